"""The slide-onset protocol of bench/friction_cone.py: the tilting-platform worlds (a block, or the
standing A1), the platform's drive, the onset of sliding and the friction usage at it, and the coarse
fixed-tilt form that tests/test_friction_cone.py runs. What each measures, and why so: the docstring
of bench/friction_cone.py.
"""

from __future__ import annotations

import collections
import math
import time

import lasmp  # noqa: F401  (first: it sets the OpenMP spin that torch reads when it loads)

# isort: split
import mujoco
import numpy as np

from lasmp.config.base import SimCfg
from lasmp.envs.moving_platform import scene
from lasmp.envs.moving_platform.cfg import PlatformCfg
from lasmp.robots import a1

# name -> (cone, impratio, noslip_iterations); "pyramidal" is the cost reference
SETTINGS: dict[str, tuple[str, float, int]] = {
    "pyramidal": ("pyramidal", 1.0, 0),
    "pyramidal_noslip3": ("pyramidal", 1.0, 3),
    "elliptic": ("elliptic", 1.0, 0),
    "elliptic_noslip1": ("elliptic", 1.0, 1),
    "elliptic_noslip2": ("elliptic", 1.0, 2),
    "elliptic_noslip5": ("elliptic", 1.0, 5),
    "elliptic_impratio10": ("elliptic", 10.0, 0),
}
DIRECTIONS_DEG = (0.0, 22.5, 45.0, 67.5, 90.0)
BLOCK_MASS_KG = 12.0  # about the A1's 12.45 kg, on four feet
BLOCK_HALF_SPAN_M = 0.1  # feet at (+-0.1, +-0.1): tipping needs ~79 deg, far beyond any slide
SETTLE_S = 1.0  # at rest on the level platform before the ramp
RELAX_S = 1.5  # robot, "relaxed" stance: first this long on frictionless feet (see the docstring)
WINDOW_S = 1.0  # onset: more than onset_mm along the surface within the last WINDOW_S
ENV_WARMUP_STEPS = 10
FIXED_RAMP_S, FIXED_HOLD_S = 2.0, 2.0  # fixed-tilt protocol (the tests')
TOPPLE_TILT_RAD = 0.3  # trunk z from the platform's normal
TOPPLE_LIFTOFF_S = 0.1  # a foot out of contact this long


def sim_cfg(setting: str) -> SimCfg:
    cone, impratio, noslip = SETTINGS[setting]
    return SimCfg(cone=cone, impratio=impratio, noslip_iterations=noslip)


def tilt_matrix(theta: float, azimuth: float) -> np.ndarray:
    """Rotation by `theta` about the horizontal axis z x d, d = (cos az, sin az, 0): the surface's
    normal leans towards d, so d is downhill (also in the platform's frame)."""
    axis = np.array([-math.sin(azimuth), math.cos(azimuth), 0.0])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(theta) * k + (1.0 - math.cos(theta)) * (k @ k)


def zyx_angles(r: np.ndarray) -> np.ndarray:
    """(yaw, pitch, roll) with R = Rz(yaw) Ry(pitch) Rx(roll), the platform's joint chain."""
    return np.array([math.atan2(r[1, 0], r[0, 0]), math.asin(-r[2, 0]), math.atan2(r[2, 1], r[2, 2])])


def block_model(sim: SimCfg, mu: float) -> mujoco.MjModel:
    spec = scene.build_spec(PlatformCfg(), sim)
    for element in [*spec.sensors, *spec.actuators]:
        if not element.name.startswith("plf_"):
            spec.delete(element)
    spec.delete(spec.body(a1.TRUNK_BODY_NAME))
    top = scene.platform_top_z_m(PlatformCfg())
    body = spec.worldbody.add_body(name="block", pos=[0, 0, top + a1.FOOT_RADIUS_M])
    body.add_freejoint(name="block")
    for i, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        body.add_geom(
            name=f"block_foot{i}",
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[a1.FOOT_RADIUS_M, 0, 0],
            pos=[sx * BLOCK_HALF_SPAN_M, sy * BLOCK_HALF_SPAN_M, 0],
            mass=BLOCK_MASS_KG / 4,
            condim=3,
            friction=[mu, 0.005, 0.0001],
            priority=1,
            contype=1,
            conaffinity=0,
        )
    return spec.compile()


def robot_model(sim: SimCfg, mu: float) -> mujoco.MjModel:
    model = scene.build_model(PlatformCfg(), sim)
    for foot in a1.FOOT_NAMES:
        model.geom_friction[model.geom(foot).id, 0] = mu
    return model


def robot_stance(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    root = model.joint(a1.ROOT_JOINT_NAME).qposadr[0]
    z = scene.platform_top_z_m(PlatformCfg()) + a1.nominal_trunk_height_m(model)
    data.qpos[root : root + 7] = [0, 0, z, 1, 0, 0, 0]
    for name, q in zip(a1.JOINT_NAMES, a1.Q_NOMINAL_RAD, strict=True):
        joint = model.joint(name)
        data.qpos[joint.qposadr[0]] = q
        servo = np.flatnonzero((model.actuator_trnid[:, 0] == joint.id) & (model.actuator_trntype == 0))
        data.ctrl[servo] = q  # the joint's position servo: PD to q_nominal


class PlatformDrive:
    """Writes the platform's PD reference (its intvelocity servos' `act`, and the reference's
    velocity as their ctrl and the dampers' ctrl) for a tilt theta(t) about a fixed axis."""

    def __init__(self, model: mujoco.MjModel, azimuth: float, kinematic: bool = False):
        pos_ids, vel_ids = scene.platform_actuator_ids(model)
        self.act_adr = model.actuator_actadr[pos_ids]
        self.pos_ids, self.vel_ids = pos_ids, vel_ids
        self.azimuth = azimuth
        # kinematic: also write the joints' positions and velocities (exact tracking, for fast ramps)
        self.kinematic = kinematic
        self.qpos_adr = np.array([model.joint(j).qposadr[0] for j in scene.PLATFORM_JOINTS])
        self.dof_adr = np.array([model.joint(j).dofadr[0] for j in scene.PLATFORM_JOINTS])

    def ref(self, theta: float) -> np.ndarray:
        q = np.zeros(6)  # PLATFORM_JOINTS order: x, y, z, yaw, pitch, roll
        q[3:] = zyx_angles(tilt_matrix(theta, self.azimuth))
        return q

    def apply(self, data: mujoco.MjData, theta: float, theta_next: float, dt: float) -> None:
        q, q_next = self.ref(theta), self.ref(theta_next)
        v = (q_next - q) / dt
        data.act[self.act_adr] = q
        data.ctrl[self.pos_ids] = v
        data.ctrl[self.vel_ids] = v
        if self.kinematic:
            data.qpos[self.qpos_adr] = q
            data.qvel[self.dof_adr] = v


def tilt_scene(sim: SimCfg, what: str, mu: float):
    """(model, data, platform body, contact geoms, tracked points) of the block or the standing robot;
    the tracked points are a function of nothing that gives their world positions, (n, 3): the robot's
    feet's centres, or the block's body."""
    model = robot_model(sim, mu) if what == "robot" else block_model(sim, mu)
    data = mujoco.MjData(model)
    if what == "robot":
        robot_stance(model, data)
        geoms = [model.geom(f).id for f in a1.FOOT_NAMES]
        sites = [model.site(f).id for f in a1.FOOT_NAMES]

        def points():
            return data.site_xpos[sites]
    else:
        block = model.body("block").id
        geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == block]

        def points():
            return data.xpos[[block]]

    return model, data, model.body("platform").id, geoms, points


def _platform_frame(data: mujoco.MjData, pid: int) -> tuple[np.ndarray, np.ndarray]:
    return data.xpos[pid].copy(), data.xmat[pid].reshape(3, 3).copy()


def friction_usage(model, data, geoms: list[int], mu: float, uphill: np.ndarray) -> tuple[float, float]:
    """Over the contacts of `geoms`: sum |f_t| / (mu sum f_n) (1 = every contact on an isotropic
    cone's boundary) and sum f_t . uphill / (mu sum f_n) (the share of it that holds the body up)."""
    f = np.zeros(6)
    normal = tangential = holding = 0.0
    for i, c in enumerate(data.contact[: data.ncon]):
        if c.geom1 in geoms or c.geom2 in geoms:
            mujoco.mj_contactForce(model, data, i, f)
            sign = 1.0 if c.geom2 in geoms else -1.0  # mj_contactForce: the force on geom2
            f_t = sign * (f[1] * c.frame[3:6] + f[2] * c.frame[6:9])
            normal += f[0]
            tangential += float(np.hypot(f[1], f[2]))
            holding += float(f_t @ uphill)
    return (tangential / (mu * normal), holding / (mu * normal)) if normal > 0 else (0.0, 0.0)


def slide_onset(
    setting: str,
    what: str,
    mu: float,
    azimuth_deg: float,
    rate_deg_s: float = 0.5,
    onset_mm: float = 5.0,
    stance: str = "relaxed",
    max_factor: float = 1.3,
) -> dict:
    """Ramp the tilt until the block / robot slides (or topples, or the tilt passes max_factor atan mu)."""
    robot = what == "robot"
    model, data, pid, geoms, points = tilt_scene(sim_cfg(setting), what, mu)
    if robot:
        trunk = model.body(a1.TRUNK_BODY_NAME).id
    drive = PlatformDrive(model, math.radians(azimuth_deg))
    dt = model.opt.timestep
    rate = math.radians(rate_deg_s)
    relax_s = RELAX_S if robot and stance == "relaxed" else 0.0
    if relax_s:
        model.geom_condim[geoms] = 1  # frictionless feet: the stance settles without locked-in forces
    ramp_from_s = relax_s + SETTLE_S
    window = max(1, int(round(WINDOW_S / dt)))
    trail: collections.deque = collections.deque(maxlen=window + 1)  # tracked points, platform frame
    out = {
        "setting": setting,
        "what": what,
        "mu": mu,
        "azimuth_deg": azimuth_deg,
        "atan_mu_deg": math.degrees(math.atan(mu)),
    }
    if robot:
        out["stance"] = stance
    t, airborne, creep_09, first_foot = 0.0, 0, None, None
    mujoco.mj_forward(model, data)
    wall = time.perf_counter()
    while True:
        theta = max(0.0, t - ramp_from_s) * rate
        drive.apply(data, theta, max(0.0, t + dt - ramp_from_s) * rate, dt)
        mujoco.mj_step(model, data)
        t += dt
        if relax_s and t >= relax_s:
            model.geom_condim[geoms] = 3
            relax_s = 0.0
        if t < ramp_from_s:
            continue
        x_p, r_p = _platform_frame(data, pid)
        here = points() - x_p
        here = here @ r_p  # platform frame, (n points, 3)
        trail.append(here)
        if len(trail) <= window:
            continue
        tilt = math.acos(min(1.0, r_p[2, 2]))
        # each point's displacement along the surface within the last WINDOW_S
        recent = np.linalg.norm((here - trail[0])[:, :2], axis=1)
        if creep_09 is None and tilt >= 0.9 * math.atan(mu):
            creep_09 = float(recent.max()) / WINDOW_S
        if robot:
            if first_foot is None and recent.max() > onset_mm * 1e-3:
                first_foot = math.degrees(tilt)
            touching = {g for c in data.contact[: data.ncon] for g in (c.geom1, c.geom2)} & set(geoms)
            airborne = airborne + 1 if len(touching) < 4 else 0
            lean = math.acos(min(1.0, float(data.xmat[trunk].reshape(3, 3)[:, 2] @ r_p[:, 2])))
            if airborne * dt >= TOPPLE_LIFTOFF_S or lean > TOPPLE_TILT_RAD:
                out.update(event="toppled", onset_deg=math.degrees(tilt))
                break
        if recent.min() > onset_mm * 1e-3:  # every foot (robot) / the block slides
            n = r_p[:, 2]
            down = np.array([0.0, 0.0, -1.0]) + n[2] * n  # gravity along the surface, world
            down /= np.linalg.norm(down)
            usage, holding = friction_usage(model, data, geoms, mu, -down)
            shift = (here - trail[0]).mean(axis=0) @ r_p.T  # world
            out.update(
                event="slid",
                onset_deg=math.degrees(tilt),
                friction_usage=usage,
                holding_usage=holding,
                slip_vs_downhill_deg=math.degrees(math.atan2(np.cross(down, shift) @ n, down @ shift)),
            )
            break
        if tilt > max_factor * math.atan(mu):
            out.update(event="held", onset_deg=None, max_tilt_deg=math.degrees(tilt))
            break
    out["ratio_to_atan_mu"] = None if out["onset_deg"] is None else out["onset_deg"] / out["atan_mu_deg"]
    if robot:
        out["first_foot_slip_deg"] = first_foot
    out["creep_mm_s_at_0.9_atan_mu"] = None if creep_09 is None else 1e3 * creep_09
    out["wall_s"] = time.perf_counter() - wall
    return out


def fixed_tilt_slip(
    sim: SimCfg,
    what: str,
    mu: float,
    azimuth_deg: float,
    tilt_deg: float,
    ramp_s: float = FIXED_RAMP_S,
    hold_s: float = FIXED_HOLD_S,
) -> dict:
    """The coarse protocol of tests/test_friction_cone.py: settle on the level platform (robot: relaxed
    stance), tilt to `tilt_deg` along a half-cosine over `ramp_s` (the platform's joints written
    exactly, its PD being too slow for a fast ramp), hold `hold_s` (>= 1 s). Returns each tracked
    point's slip along the surface (m; block: its body, robot: its four feet) over the hold and over
    its last second, and the feet's friction usage as the hold starts (see `friction_usage`)."""
    robot = what == "robot"
    model, data, pid, geoms, points = tilt_scene(sim, what, mu)
    drive = PlatformDrive(model, math.radians(azimuth_deg), kinematic=True)
    dt, theta = model.opt.timestep, math.radians(tilt_deg)
    mujoco.mj_forward(model, data)

    def run(seconds, profile=lambda t: 0.0):
        for k in range(int(round(seconds / dt))):
            drive.apply(data, profile(k * dt), profile((k + 1) * dt), dt)
            mujoco.mj_step(model, data)

    def tracked():
        x_p, r_p = _platform_frame(data, pid)
        return (points() - x_p) @ r_p

    if robot:
        model.geom_condim[geoms] = 1
        run(RELAX_S)
        model.geom_condim[geoms] = 3
    run(SETTLE_S)
    run(ramp_s, lambda t: theta * (0.5 - 0.5 * math.cos(math.pi * min(t, ramp_s) / ramp_s)))
    n = data.xmat[pid].reshape(3, 3)[:, 2]
    down = np.array([0.0, 0.0, -1.0]) + n[2] * n
    usage, holding = friction_usage(model, data, geoms, mu, -down / np.linalg.norm(down))
    start = tracked()
    run(hold_s - 1.0, lambda t: theta)
    last = tracked()
    run(1.0, lambda t: theta)
    end = tracked()
    return {
        "slip_m": np.linalg.norm((end - start)[:, :2], axis=1),  # over the hold
        "last_s_slip_m": np.linalg.norm((end - last)[:, :2], axis=1),  # over its last second
        # at the hold's start
        "friction_usage": usage,
        "holding_usage": holding,
    }
