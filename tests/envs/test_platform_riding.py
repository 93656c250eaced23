"""A robot standing on the moving platform, through the real env: friction carries it along, the
readout's platform velocities agree with the riding robot's and are expressed in its (yawed) trunk
frame, and the heavy platform barely feels its weight (fast: few envs, <= 3 s).

Every test builds a `MovingPlatformEnv`, feeds its own references through
`env._next_trajectories` (so that a reset after a fall replays the same reference from t = 0),
steps with a = 0 (the robot stands under its joint PD) and reads the platform from the raw
batch state (`env.sim.qpos/qvel`) and from `env.readout`.

Measured value behind the documented bounds: the platform velocity at the policy-step ends equals
the reference at constant speed (0.5000 m/s and rad/s for a 0.5 reference).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import torch
from testkit import policy_steps as _steps
from testkit import replaying_env as _make_env

from lasmp.envs import trajectories as trj
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.envs.moving_platform.scene import PLATFORM_JOINTS
from lasmp.envs.robot import as_numpy

T_CHECK_S = 3.0  # horizon of every test
T_RAMP_S = 1.0  # smooth velocity ramp of the user-made references
T_SETTLED_S = 1.5  # checks of the constant-velocity phase start here


def _ramp_refs(n: int, pose_axis: int, rate: float, t_end_s: float = T_CHECK_S + 1.0) -> trj.PiecewisePoly:
    """Pose component `pose_axis` accelerates smoothly (smoothstep velocity) to `rate` over
    T_RAMP_S, then moves at constant `rate`; sampled every 0.05 s (not-a-knot spline)."""
    t = np.arange(0.0, t_end_s + 1e-9, 0.05)
    s = np.clip(t / T_RAMP_S, 0.0, 1.0)
    pos = np.where(t < T_RAMP_S, rate * T_RAMP_S * (s**3 - 0.5 * s**4), rate * (t - 0.5 * T_RAMP_S))
    poses = np.zeros((n, len(t), 6))
    poses[:, :, pose_axis] = pos
    return trj.from_samples(t, poses)


def _plf_dofs(env: MovingPlatformEnv) -> np.ndarray:
    return np.array([env.sim.model.joint(j).dofadr[0] for j in PLATFORM_JOINTS])


def _expected_plf_in_body(env: MovingPlatformEnv) -> tuple[np.ndarray, np.ndarray]:
    """(v_plf_b, omega_plf_b) computed independently of the readout: platform joint rates ->
    world twist (R_wp = Rz(yaw) Ry(pitch) Rx(roll)), velocity of the platform point under the
    trunk origin, rotated into the trunk frame with MuJoCo's own quaternion conversion."""
    n, root = env.num_envs, env.index.root_qpos
    dofs = _plf_dofs(env)
    qpos, qvel = env.sim.qpos.numpy(), env.sim.qvel.numpy()
    q = qpos[:, env.index.plf_qpos.numpy()]  # x, y, z, yaw, pitch, roll
    qd = qvel[:, dofs]
    yaw, pitch = q[:, 3], q[:, 4]
    ez = np.array([0.0, 0.0, 1.0])
    y_axis = np.stack([-np.sin(yaw), np.cos(yaw), np.zeros(n)], axis=1)  # Rz ey
    x_axis = np.stack([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), -np.sin(pitch)], axis=1)
    omega_w = qd[:, 3:4] * ez + qd[:, 4:5] * y_axis + qd[:, 5:6] * x_axis
    lever = qpos[:, root : root + 3] - q[:, :3]
    v_w = qd[:, :3] + np.cross(omega_w, lever)
    r_wb = np.empty((n, 9))
    for i in range(n):
        quat = qpos[i, root + 3 : root + 7]
        mujoco.mju_quat2Mat(r_wb[i], quat / np.linalg.norm(quat))
    r_wb = r_wb.reshape(n, 3, 3)
    return np.einsum("nji,nj->ni", r_wb, v_w), np.einsum("nji,nj->ni", r_wb, omega_w)


def _quat_yaw(q: np.ndarray) -> np.ndarray:
    """Yaw (ZYX) of (n, 4) MuJoCo quaternions (w, x, y, z)."""
    w, x, y, z = q.T
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


# --------------------------------------------------------------------------------------------
# 1. The robot is carried along by friction
# --------------------------------------------------------------------------------------------
def test_standing_robot_is_carried_along_x():
    n, v = 4, 0.5
    env = _make_env(n, _ramp_refs(n, 0, v), domain_rand={"enabled": False})
    root, root_v = env.index.root_qpos, env.index.root_qvel
    x_dof = _plf_dofs(env)[0]
    a = torch.zeros(n, 12)
    k0, k1 = _steps(env, T_SETTLED_S), _steps(env, T_CHECK_S)
    trunk, plf, v_trunk, p_rel = [], [], [], []
    for k in range(1, k1 + 1):
        _, _, done, _ = env.step(a)
        assert not done.any(), f"robot fell/reset at t = {k * env.dt_s:.2f} s while standing"
        if k >= k0:
            trunk.append(env.sim.qpos[:, root : root + 3].numpy().copy())
            plf.append(env.sim.qpos[:, env.index.plf_qpos[:3]].numpy().copy())
            v_trunk.append(env.sim.qvel[:, root_v : root_v + 3].numpy().copy())  # world frame
            p_rel.append(env.readout.p_body_p.numpy().copy())
    trunk, plf, v_trunk, p_rel = map(np.array, (trunk, plf, v_trunk, p_rel))
    dur = (k1 - k0) * env.dt_s
    v_trunk_fd = (trunk[-1] - trunk[0]) / dur
    v_plf_fd = (plf[-1] - plf[0]) / dur
    ratio = v_trunk_fd[:, 0] / v_plf_fd[:, 0]
    msg = (
        f"trunk/platform velocity ratio {np.round(ratio, 4)} (platform {np.round(v_plf_fd[:, 0], 4)} m/s), "
        f"per-step trunk vx in [{v_trunk[:, :, 0].min():.4f}, {v_trunk[:, :, 0].max():.4f}], "
        f"max |vy| {np.abs(v_trunk[:, :, 1]).max():.4f}, platform qvel x at step ends "
        f"{env.sim.qvel[0, x_dof].item():.4f}"
    )
    print(msg)
    np.testing.assert_allclose(v_plf_fd[:, 0], v, rtol=0.01, err_msg=msg)  # the platform itself moves at v
    assert np.all(np.abs(ratio - 1.0) < 0.05), msg
    assert np.all(np.abs(v_trunk[:, :, 0] / v - 1.0) < 0.05), f"per-step trunk velocity off by > 5 %: {msg}"
    assert np.abs(v_trunk[:, :, 1]).max() < 0.05 * v, msg
    slip = np.abs(p_rel[-1, :, :2] - p_rel[0, :, :2]).max()
    assert slip < 0.02, f"trunk moved {slip * 1e3:.1f} mm relative to the platform: {msg}"


# --------------------------------------------------------------------------------------------
# 2. Yawing platform: the readout's platform quantities agree with the riding robot's
# --------------------------------------------------------------------------------------------
def test_yawing_platform_readout_consistent_with_riding_robot():
    n, rate = 4, 0.5
    env = _make_env(n, _ramp_refs(n, 5, rate), domain_rand={"enabled": False})  # pose 5 = yaw
    a = torch.zeros(n, 12)
    k0, k1 = _steps(env, T_SETTLED_S), _steps(env, T_CHECK_S)
    u, w_plf, dv, dw, r_xy = [], [], [], [], []
    for k in range(1, k1 + 1):
        obs, _, done, _ = env.step(a)
        assert not done.any(), f"robot fell/reset at t = {k * env.dt_s:.2f} s while standing"
        r = as_numpy(env.readout)
        np.testing.assert_allclose(obs["alignment"].numpy(), r.u_aln, atol=1e-5)  # obs = readout
        v_exp, w_exp = _expected_plf_in_body(env)  # incl. omega x lever arm (~5 mm/s here)
        np.testing.assert_allclose(r.v_plf_b, v_exp, atol=1e-6, err_msg=f"t = {k * env.dt_s:.2f} s")
        np.testing.assert_allclose(r.omega_plf_b, w_exp, atol=1e-6, err_msg=f"t = {k * env.dt_s:.2f} s")
        if k >= k0:
            u.append(r.u_aln.copy())
            w_plf.append(r.omega_plf_b[:, 2].copy())
            dv.append(np.linalg.norm(r.v_plf_b - r.v_body_b, axis=1))
            dw.append(np.linalg.norm(r.omega_plf_b - r.omega_body_b, axis=1))
            r_xy.append(np.linalg.norm(r.p_body_p[:, :2], axis=1))
    u, w_plf, dv, dw, r_xy = map(np.array, (u, w_plf, dv, dw, r_xy))
    u_max = np.abs(u).max(axis=(0, 1))
    msg = (
        f"max |u_aln| = {np.round(u_max, 4)} (vx, vy m/s, wz rad/s); omega_plf_b,z in "
        f"[{w_plf.min():.4f}, {w_plf.max():.4f}] for rate {rate}; max |v_plf_b - v_body_b| "
        f"{dv.max():.4f} m/s, max |omega_plf_b - omega_body_b| {dw.max():.4f} rad/s; "
        f"trunk within {r_xy.max() * 1e3:.1f} mm of the centre"
    )
    print(msg)
    assert r_xy.max() < 0.1, msg  # the robot still stands near the centre
    assert np.all(u_max[:2] < 0.03), msg
    assert u_max[2] < 0.025, msg  # 5 % of the yaw rate
    assert dv.max() < 0.03 and dw.max() < 0.05, msg
    assert np.all(np.abs(w_plf / rate - 1.0) < 0.03), msg


# --------------------------------------------------------------------------------------------
# 3. The platform is heavy: a standing robot barely disturbs it
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "cfg",
    [
        pytest.param({"domain_rand": {"enabled": False}}, id="nominal"),
        pytest.param({"domain_rand": {"enabled": False}, "platform": {}}, id="calibrated-default"),
        pytest.param(  # the softest test-range platform under the heaviest test-range trunk
            {
                "domain_rand": {
                    "split": "test",
                    "test": {
                        "platform_kp_factor": [0.5, 0.5],
                        "platform_kd_factor": [0.01, 0.01],
                        "trunk_mass_kg": [5.5, 5.5],
                    },
                }
            },
            id="test-soft-heavy",
        ),
    ],
)
def test_static_platform_barely_disturbed_by_robot(cfg):
    n = 4
    env = _make_env(n, trj.from_samples(np.array([0.0, 1.0]), np.zeros((n, 2, 6))), seed=1, **cfg)
    a = torch.zeros(n, 12)
    err = np.zeros(6)
    for k in range(1, _steps(env, 8.0) + 1):  # the 1 rad/s default settles (2 %) in ~6 s
        _, _, done, _ = env.step(a)
        assert not done.any(), f"robot fell/reset at t = {k * env.dt_s:.2f} s on a static platform"
        err = np.maximum(err, np.abs(env.sim.qpos[:, env.index.plf_qpos].numpy()).max(axis=0))
    sag = -env.sim.qpos[:, env.index.plf_qpos[2]].numpy()
    # static sag = robot weight / kp_z (the platform is gravity-compensated)
    m = env.sim.model
    robot_mass = env.sim.expand("body_mass").numpy()[:, 1:].sum(axis=1) - env.cfg.platform.mass_kg
    kp_z = env.sim.expand("actuator_gainprm").numpy()[:, int(env.plf_act_pos[2]), 0]
    sag_expected = robot_mass * -m.opt.gravity[2] / kp_z
    msg = (
        f"max |x,y,z| = {np.round(err[:3] * 1e3, 4)} mm, max |yaw,pitch,roll| = "
        f"{np.round(err[3:] * 1e3, 4)} mrad; final sag {np.round(sag * 1e3, 4)} mm "
        f"(weight/kp_z {np.round(sag_expected * 1e3, 4)} mm)"
    )
    print(msg)
    assert err[:2].max() < 1e-3, msg
    assert err[2] < max(1e-3, 1.1 * sag_expected.max()), msg  # z: no more than its static sag
    assert err[3:].max() < 1e-3, msg  # 1 mrad = 1 mm at the platform's edge
    np.testing.assert_allclose(sag, sag_expected, rtol=0.1, err_msg=msg)


# --------------------------------------------------------------------------------------------
# 4. v_plf_b is expressed in the (yawed) trunk frame
# --------------------------------------------------------------------------------------------
def test_platform_velocity_in_yawed_body_frame():
    n, v = 8, 0.5
    env = _make_env(n, _ramp_refs(n, 0, v), seed=0, domain_rand={"enabled": False})
    root = env.index.root_qpos
    dofs = _plf_dofs(env)
    yaw0 = _quat_yaw(env.sim.qpos[:, root + 3 : root + 7].numpy().copy())
    quadrants = np.unique(np.floor((yaw0 + np.pi) / (np.pi / 2)).astype(int))
    assert len(quadrants) == 4, f"the seed must give start yaws in all four quadrants, got {yaw0}"
    a = torch.zeros(n, 12)
    k0, k1 = _steps(env, T_SETTLED_S), _steps(env, T_CHECK_S)
    err_yaw, err_full = 0.0, 0.0
    for k in range(1, k1 + 1):
        _, _, done, _ = env.step(a)
        assert not done.any(), f"robot fell/reset at t = {k * env.dt_s:.2f} s while standing"
        if k < k0:
            continue
        v_plf_b = env.readout.v_plf_b.numpy()
        quat = env.sim.qpos[:, root + 3 : root + 7].numpy().copy()
        yaw = _quat_yaw(quat)
        vx = env.sim.qvel[:, dofs[0]].numpy()  # the platform's own x velocity (world x)
        # yaw-only frame: R_wb^T [v, 0, 0] = [v cos(yaw), -v sin(yaw), 0] for a level trunk
        expect = np.stack([vx * np.cos(yaw), -vx * np.sin(yaw)], axis=1)
        err_yaw = max(err_yaw, float(np.abs(v_plf_b[:, :2] - expect).max()))
        # signs, explicitly, where the component is clearly nonzero
        for comp, ref in ((0, np.cos(yaw)), (1, -np.sin(yaw))):
            sel = np.abs(ref) > 0.3
            assert np.all(np.sign(v_plf_b[sel, comp]) == np.sign(ref[sel])), (
                f"v_plf_b[:, {comp}] = {v_plf_b[sel, comp]} has the wrong sign for yaw {yaw[sel]}"
            )
        # full trunk orientation from the quaternion (MuJoCo's own conversion), all 3 components
        v_exp, _ = _expected_plf_in_body(env)
        err_full = max(err_full, float(np.abs(v_plf_b - v_exp).max()))
        np.testing.assert_allclose(vx, v, rtol=0.03)  # the platform moves along +x at ~v
    msg = (
        f"start yaws {np.round(yaw0, 3)}; max |v_plf_b,xy - Rz(yaw)^T [v,0,0]| = {err_yaw:.5f} m/s, "
        f"max |v_plf_b - R_wb^T v_w| = {err_full:.2e} m/s"
    )
    print(msg)
    assert err_yaw < 0.01, msg  # roll/pitch of the standing trunk are small
    assert err_full < 1e-6, msg
