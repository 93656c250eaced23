"""The MuJoCo Warp backend (`lasmp/envs/backends/warp.py`) on Warp's CPU device, against C MuJoCo.

Few worlds and short runs: the kernels compile once (~1 min, cached in ~/.cache/warp), then each
test takes seconds. Run with `pytest -m warp`.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
import torch

pytest.importorskip("mujoco_warp")
wp = pytest.importorskip("warp")

from lasmp.config.base import SimCfg  # noqa: E402
from lasmp.envs.backends import make_backend  # noqa: E402
from lasmp.envs.backends.cpu import CpuBatchSim  # noqa: E402
from lasmp.envs.backends.warp import WarpSim  # noqa: E402
from lasmp.envs.moving_platform.cfg import PlatformCfg  # noqa: E402
from lasmp.envs.moving_platform.scene import PLATFORM_JOINTS, build_model, platform_top_z_m  # noqa: E402
from lasmp.envs.robot import RobotIndex  # noqa: E402
from lasmp.robots import a1  # noqa: E402

pytestmark = pytest.mark.warp
wp.config.quiet = True  # no line per kernel module loaded

SIM = SimCfg()
PLATFORM = PlatformCfg()
# the step-by-step parity test compares the two solvers where both converge within their tolerance:
# MuJoCo's pyramidal cone without no-slip passes. With the default elliptic cone and no-slip passes
# the solver stops at its iteration limit, and relaxing C MuJoCo's tolerance no longer measures how
# far the backends may differ; the benchmark-level agreement (tests/envs/test_warp_env.py) covers those.
PARITY_SIM = SimCfg(cone="pyramidal", noslip_iterations=0)
POLICY_DT_S = SIM.dt_s * SIM.decimation


@pytest.fixture(scope="module")
def model():
    return build_model(PLATFORM, SIM)


@pytest.fixture(scope="module")
def ix(model):
    return RobotIndex(model)


def standing(model, ix, n: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(qpos, qvel, ctrl) of n envs: the robot level at the platform centre in its nominal stance, feet
    1 mm above the top (as the env's reset puts it), the joint servos holding that stance."""
    qpos = torch.tensor(np.tile(model.qpos0, (n, 1)))
    qpos[:, ix.root_qpos + 2] = platform_top_z_m(PLATFORM) + a1.nominal_trunk_height_m(model) + 0.001
    qpos[:, ix.root_qpos + 3 : ix.root_qpos + 7] = torch.tensor([1.0, 0.0, 0.0, 0.0])
    qpos[:, ix.joint_qpos] = torch.tensor(a1.Q_NOMINAL_RAD)
    ctrl = torch.zeros(n, model.nu, dtype=torch.float64)
    ctrl[:, ix.joint_act] = torch.tensor(a1.Q_NOMINAL_RAD)
    return qpos, torch.zeros(n, model.nv, dtype=torch.float64), ctrl


def reset_all(sim, model, ix) -> None:
    sim.reset(torch.arange(sim.num_envs), *standing(model, ix, sim.num_envs), set_const=True)


class PlatformDrive:
    """The platform's servos tracking a small sway, as the env drives them: each policy step the
    intvelocity servo's target (its `act`) is set to x_ref(t) and ramps at ctrl to x_ref(t + dt); the
    velocity servo tracks v_ref at mid-step. x_ref = amplitude * sin(2 pi f t) on z, roll and pitch."""

    AMPLITUDE = {"plf_z": 0.03, "plf_roll": 0.06, "plf_pitch": 0.04}  # m, rad
    FREQ_HZ = 1.0

    def __init__(self, model):
        self.pos_act = [model.actuator(f"{j}_pos").id for j in PLATFORM_JOINTS]
        self.vel_act = [model.actuator(f"{j}_vel").id for j in PLATFORM_JOINTS]
        self.act_adr = [int(model.actuator_actadr[a]) for a in self.pos_act]
        self.amp = [self.AMPLITUDE.get(j, 0.0) for j in PLATFORM_JOINTS]

    def _ref(self, t_s: float) -> tuple[list[float], list[float]]:
        w = 2 * math.pi * self.FREQ_HZ
        return [a * math.sin(w * t_s) for a in self.amp], [a * w * math.cos(w * t_s) for a in self.amp]

    def apply(self, sim, k: int) -> None:
        t_s = k * POLICY_DT_S
        x_now, _ = self._ref(t_s)
        x_next, _ = self._ref(t_s + POLICY_DT_S)
        _, v_mid = self._ref(t_s + 0.5 * POLICY_DT_S)
        for j in range(len(PLATFORM_JOINTS)):
            sim.act[:, self.act_adr[j]] = x_now[j]
            sim.ctrl[:, self.pos_act[j]] = (x_next[j] - x_now[j]) / POLICY_DT_S
            sim.ctrl[:, self.vel_act[j]] = v_mid[j]


def randomize(sim, model, trunk_mass_kg, foot_friction, joint_kp, joint_kd) -> None:
    """Per-env robot parameters written through `expand`, as the env's intrinsics writer does (one
    value per env: trunk mass kg, foot sliding friction, joint kp N·m/rad and kd N·m·s/rad)."""

    def col(values):
        return torch.as_tensor(values, dtype=sim.dtype)[:, None]

    trunk = model.body(a1.TRUNK_BODY_NAME).id
    feet = [model.geom(f).id for f in a1.FOOT_NAMES]
    joints = [model.actuator(j).id for j in a1.JOINT_NAMES]
    sim.expand("body_mass")[:, trunk] = torch.as_tensor(trunk_mass_kg, dtype=sim.dtype)
    sim.expand("geom_friction")[:, feet, 0] = col(foot_friction)
    sim.expand("actuator_gainprm")[:, joints, 0] = col(joint_kp)
    sim.expand("actuator_biasprm")[:, joints, 1] = -col(joint_kp)
    sim.expand("actuator_biasprm")[:, joints, 2] = -col(joint_kd)


def foot_contacts(sim, ix) -> torch.Tensor:
    """(n, 4) bool: each foot's contact sensor found a contact."""
    return torch.stack([sim.sensordata[:, s][:, 0] > 0 for s in ix.foot_contact], dim=1)


def outputs(sim) -> dict[str, torch.Tensor]:
    """Copies of every array the contract hands out."""
    names = ("qpos", "qvel", "ctrl", "act", "sensordata", "site_xpos", "actuator_force")
    return {name: getattr(sim, name).clone() for name in names}


def assert_rows_equal(a: dict, b: dict, rows) -> None:
    for name in a:
        assert torch.equal(a[name][rows], b[name][rows]), f"{name} rows {rows} changed"


# -- 1. parity with C MuJoCo ---------------------------------------------------------------------


def test_parity_with_cpu_backend(model, ix):
    """Same model, state, per-env randomization and controls through both backends: 100 policy steps
    (2 s) of a robot standing on a swaying platform agree, env by env.

    Tolerances (per env, max over the run): MuJoCo Warp runs in float32 and stops its solver at
    tolerance 1e-6 where C MuJoCo (float64) goes on to 1e-8. So an env agrees to
    - a float32 floor: 1e-5 m (rad) in positions and site positions, 5e-4 m/s (rad/s) in velocities
      and velocity sensors. Measured: 6e-7 and 2e-5; the stance is servo- and contact-damped, so
      rounding errors of ~3e-8 per substep don't grow;
    - plus what the solver tolerance itself is worth in that env, measured here as how far C MuJoCo
      moves when its own tolerance is relaxed to 1e-6. With the joints' friction losses (the
      published A1's) the solver converges slowly in every env; env 1 also slips (foot friction 0.5
      below the platform's 1.0 on the swaying platform).
    Foot-contact flags agree exactly: the feet stay planted, far from a make/break threshold."""
    n = 3
    loose = build_model(PLATFORM, PARITY_SIM)
    loose.opt.tolerance = 1e-6  # MuJoCo Warp's floor (put_model raises smaller tolerances to it)
    model = build_model(PLATFORM, PARITY_SIM)
    warp_sim = WarpSim(model, n, PARITY_SIM, "cpu")
    cpu_sim, cpu_loose = CpuBatchSim(model, n, num_threads=1), CpuBatchSim(loose, n, num_threads=1)
    sims = (warp_sim, cpu_sim, cpu_loose)
    drive = PlatformDrive(model)
    for sim in sims:
        # env 0 nominal; 1 heavy, slipping, soft servos; 2 light, foot friction below the platform's
        # (the feet's contact priority decides), stiff servos
        randomize(sim, model, [4.714, 6.0, 3.8], [1.0, 0.5, 0.7], [40.0, 30.0, 50.0], [1.0, 0.7, 1.3])
        reset_all(sim, model, ix)
    vel_sensors = slice(model.sensor("imu_gyro").adr[0], model.sensor("FR_foot_contact").adr[0])

    def per_env_error(a, b) -> dict[str, torch.Tensor]:
        """Max abs differences per env: positions (qpos, site_xpos), velocities (qvel, velocity sensors)."""
        pos = torch.cat(
            [(a.qpos.double() - b.qpos).abs(), (a.site_xpos.double() - b.site_xpos).abs().flatten(1)], 1
        )
        vel = torch.cat(
            [(a.qvel.double() - b.qvel).abs(), (a.sensordata.double() - b.sensordata)[:, vel_sensors].abs()],
            1,
        )
        return {"pos": pos.max(dim=1).values, "vel": vel.max(dim=1).values}

    err = {"pos": torch.zeros(n, dtype=torch.float64), "vel": torch.zeros(n, dtype=torch.float64)}
    slack = {"pos": torch.zeros(n, dtype=torch.float64), "vel": torch.zeros(n, dtype=torch.float64)}
    for k in range(100):
        for sim in sims:
            drive.apply(sim, k)
            assert not sim.step(SIM.decimation).any()
        for key, value in per_env_error(warp_sim, cpu_sim).items():
            err[key] = torch.maximum(err[key], value)
        for key, value in per_env_error(cpu_loose, cpu_sim).items():
            slack[key] = torch.maximum(slack[key], value)
        assert torch.equal(foot_contacts(warp_sim, ix), foot_contacts(cpu_sim, ix)), f"step {k}"
    print(f"warp vs C per env: {err}; C tolerance 1e-6 vs 1e-8: {slack}")
    assert (err["pos"] <= 1e-5 + slack["pos"]).all(), (err, slack)
    assert (err["vel"] <= 5e-4 + slack["vel"]).all(), (err, slack)
    plf = [model.joint(j).qposadr[0] for j in PLATFORM_JOINTS]
    assert cpu_sim.qpos[:, plf].abs().max() > 0.01  # the platform did move
    assert foot_contacts(cpu_sim, ix).all()


# -- 2. per-env randomization --------------------------------------------------------------------


def test_randomization_matters(model, ix):
    """Worlds with equal parameters stay bit-equal; a heavier trunk sags further on its servos."""
    sim = WarpSim(model, 3, SIM, "cpu")
    heavy_kg = a1.TRUNK_MASS_KG + 1.5
    randomize(sim, model, [a1.TRUNK_MASS_KG, a1.TRUNK_MASS_KG, heavy_kg], [1.0] * 3, [40.0] * 3, [1.0] * 3)
    reset_all(sim, model, ix)
    # set_const refreshed the constants of world 2 alone (the subtree mass of the robot's root body)
    root = model.body(a1.TRUNK_BODY_NAME).rootid[0]
    subtree = sim._m.body_subtreemass.numpy()[:, root]
    assert subtree[2] - subtree[0] == pytest.approx(1.5, abs=1e-5) and subtree[0] == subtree[1]
    for _ in range(25):
        assert not sim.step(SIM.decimation).any()
    assert torch.equal(sim.qpos[0], sim.qpos[1]) and torch.equal(sim.qvel[0], sim.qvel[1])
    z = sim.qpos[:, ix.root_qpos + 2]
    assert z[0] - z[2] > 1e-3, f"trunk heights {z.tolist()}"


# -- 3. per-env reset and partial steps ----------------------------------------------------------


def test_reset_and_partial_step_touch_only_their_envs(model, ix):
    n = 3
    sim, twin = WarpSim(model, n, SIM, "cpu"), WarpSim(model, n, SIM, "cpu")
    drive = PlatformDrive(model)
    for s in (sim, twin):
        reset_all(s, model, ix)
    start = outputs(sim)
    for k in range(10):
        for s in (sim, twin):
            drive.apply(s, k)
            s.step(SIM.decimation)
    before = outputs(sim)
    assert not torch.equal(before["qpos"], start["qpos"])

    # a reset of env 1 gives it the start state again, and leaves envs 0 and 2 as they were
    one = torch.tensor([1])
    qpos, qvel, ctrl = standing(model, ix, 1)
    sim.reset(one, qpos, qvel, ctrl, set_const=True)
    after = outputs(sim)
    assert_rows_equal(before, after, [0, 2])
    assert_rows_equal(start, after, [1])

    # a step of envs 0 and 2 leaves env 1 exactly as it was and counts 2 env-steps; nothing of the
    # step computed (and discarded) for env 1 leaks into it: its next full step is the one its twin
    # takes from the same state
    twin.reset(one, qpos, qvel, ctrl, set_const=True)
    steps = sim.env_steps
    drive.apply(sim, 10)
    driven = outputs(sim)
    sim.step(SIM.decimation, torch.tensor([0, 2]))
    assert sim.env_steps == steps + 2
    partial = outputs(sim)
    assert_rows_equal(driven, partial, [1])
    for rows in ([0], [2]):
        assert not torch.equal(driven["qpos"][rows], partial["qpos"][rows])
    for s in (sim, twin):
        drive.apply(s, 11)
        s.step(SIM.decimation)
    assert_rows_equal(outputs(twin), outputs(sim), [1])

    # a push written into env 2's state shows in its velocity sensors after forward(ids); the others
    # keep their outputs (acceleration sensors included: they still describe their last substep)
    pushed = outputs(sim)
    sim.qvel[2, ix.root_qvel] += 0.5
    sim.forward(torch.tensor([2]))
    after_push = outputs(sim)
    assert_rows_equal(pushed, after_push, [0, 1])
    gyro_to_contacts = slice(model.sensor("imu_gyro").adr[0], model.sensor("FR_foot_contact").adr[0])
    assert not torch.equal(
        pushed["sensordata"][2, gyro_to_contacts], after_push["sensordata"][2, gyro_to_contacts]
    )


# -- 4. faults -----------------------------------------------------------------------------------


def test_nan_faults_only_its_env(model, ix):
    n = 3
    sim, clean = WarpSim(model, n, SIM, "cpu"), WarpSim(model, n, SIM, "cpu")
    for s in (sim, clean):
        reset_all(s, model, ix)
        s.step(SIM.decimation)
    sim.qvel[1, ix.root_qvel] = float("nan")
    faulted = sim.step(SIM.decimation)
    clean.step(SIM.decimation)
    assert faulted.tolist() == [False, True, False]
    assert_rows_equal(outputs(clean), outputs(sim), [0, 2])  # the others never saw it

    sim.reset(torch.tensor([1]), *standing(model, ix, 1), set_const=False)
    for _ in range(3):
        assert not sim.step(SIM.decimation).any()
    for x in outputs(sim).values():
        assert torch.isfinite(x).all()


def test_contact_overflow_faults(model, ix):
    """Contacts beyond the pool MuJoCo Warp preallocates are dropped: every env is faulted (the pool is
    shared, so the overflow is flagged in all of them)."""
    sim = WarpSim(model, 2, SimCfg(warp_contacts_per_env=1), "cpu")  # 2 slots for 8 feet on the platform
    reset_all(sim, model, ix)
    assert sim.step(SIM.decimation).tolist() == [True, True]
    roomy = WarpSim(model, 2, SIM, "cpu")
    reset_all(roomy, model, ix)
    assert roomy.step(SIM.decimation).tolist() == [False, False]


# -- 5. install hint -----------------------------------------------------------------------------


def test_missing_mujoco_warp_names_the_gpu_extra(model, monkeypatch):
    monkeypatch.setitem(sys.modules, "mujoco_warp", None)  # `import mujoco_warp` now raises ImportError
    with pytest.raises(ImportError, match=r'pip install -e "\.\[gpu\]"'):
        make_backend("warp", model, 2, SIM, "cpu")


# -- 6. the rough-terrain scene ------------------------------------------------------------------


def test_rough_terrain_steps():
    from lasmp.envs.rough_static.cfg import TerrainCfg
    from lasmp.envs.rough_static.scene import build_model as build_terrain

    model, field = build_terrain(TerrainCfg(), SIM)
    tix = RobotIndex(model)
    n = 2
    xy = np.array([[0.0, 0.0], [1.3, -0.7]])  # a spot per env
    # the highest ground within 0.5 m of each spot (the grid's rows are y, its columns x)
    cells = np.round((xy + [field.half_x_m, field.half_y_m]) / field.resolution_m).astype(int)
    k = int(round(0.5 / field.resolution_m))
    ground_m = np.array([field.heights_m[r - k : r + k + 1, c - k : c + k + 1].max() for c, r in cells])
    qpos = torch.tensor(np.tile(model.qpos0, (n, 1)))
    qpos[:, tix.root_qpos : tix.root_qpos + 2] = torch.tensor(xy)
    qpos[:, tix.root_qpos + 2] = torch.tensor(ground_m) + a1.nominal_trunk_height_m(model) + 0.01
    qpos[:, tix.root_qpos + 3 : tix.root_qpos + 7] = torch.tensor([1.0, 0.0, 0.0, 0.0])
    qpos[:, tix.joint_qpos] = torch.tensor(a1.Q_NOMINAL_RAD)
    ctrl = torch.zeros(n, model.nu, dtype=torch.float64)
    ctrl[:, tix.joint_act] = torch.tensor(a1.Q_NOMINAL_RAD)
    sim = WarpSim(model, n, SIM, "cpu")
    sim.reset(torch.arange(n), qpos, torch.zeros(n, model.nv, dtype=torch.float64), ctrl, set_const=True)
    for _ in range(25):  # 0.5 s: the robot drops 1 cm and settles on the heightfield
        assert not sim.step(SIM.decimation).any()
    z = sim.qpos[:, tix.root_qpos + 2].double().numpy()
    assert (z > ground_m + 0.5 * a1.nominal_trunk_height_m(model)).all(), f"fell through: {z} over {ground_m}"
    print(f"trunk z {z}, ground {ground_m}, feet in contact {foot_contacts(sim, tix).tolist()}")
    assert foot_contacts(sim, tix).sum() >= 6  # standing on its feet, not floating


# -- get_state / set_state -----------------------------------------------------------------------


def test_state_round_trip_resumes_exactly(model, ix):
    n = 2
    sim, other = WarpSim(model, n, SIM, "cpu"), WarpSim(model, n, SIM, "cpu")
    drive = PlatformDrive(model)
    randomize(sim, model, [4.714, 6.0], [1.0, 0.6], [40.0, 30.0], [1.0, 0.7])
    reset_all(sim, model, ix)
    for k in range(5):
        drive.apply(sim, k)
        sim.step(SIM.decimation)
    saved = sim.get_state()
    reset_all(other, model, ix)  # nominal parameters and another state, until set_state
    other.set_state(saved)
    for k in range(5, 10):
        for s in (sim, other):
            drive.apply(s, k)
            s.step(SIM.decimation)
    a, b = outputs(sim), outputs(other)
    for name in ("qpos", "qvel", "act", "site_xpos"):
        assert torch.equal(a[name], b[name]), name
