"""A1 model checks: published numbers, names/order the envs rely on, and a 5-s stand on a floor."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from lasmp.robots import a1

DT_S = 0.005
STAND_S = 5.0
SETTLE_S = 0.5  # the PD compliance sags the trunk in the first ~0.5 s; drift is measured after


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return a1.load_model()


def build_floor_scene() -> mujoco.MjModel:
    """Floor plane (contype=0, conaffinity=1) + the A1 attached with an empty prefix."""
    spec = mujoco.MjSpec()
    spec.option.timestep = DT_S
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.worldbody.add_geom(
        name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1], contype=0, conaffinity=1
    )
    robot = mujoco.MjSpec.from_file(str(a1.MJCF_PATH))
    # An empty prefix makes MuJoCo warn "may prevent the model from being saved" (we never save);
    # a temporary handler keeps it from being written to MUJOCO_LOG.TXT in the working directory.
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: None)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            spec.attach(robot, prefix="", frame=spec.worldbody.add_frame())
            return spec.compile()
    finally:
        mujoco.set_mju_user_warning(previous)


def _set_nominal(m: mujoco.MjModel, d: mujoco.MjData, trunk_z: float) -> None:
    adr = m.joint(a1.ROOT_JOINT_NAME).qposadr[0]
    d.qpos[adr : adr + 7] = [0, 0, trunk_z, 1, 0, 0, 0]
    for name, q in zip(a1.JOINT_NAMES, a1.Q_NOMINAL_RAD, strict=True):
        d.qpos[m.joint(name).qposadr[0]] = q


def test_total_and_link_masses(model):
    total = model.body_subtreemass[model.body("trunk").id]
    print(f"total robot mass = {total:.3f} kg")
    assert 11.5 <= total <= 12.6
    assert model.body_mass[model.body("trunk").id] == pytest.approx(a1.TRUNK_MASS_KG)
    # a1.TRUNK_COM_M is the published trunk CoM rounded to 0.1 mm
    np.testing.assert_allclose(model.body_ipos[model.body("trunk").id], a1.TRUNK_COM_M, atol=2e-4)
    for leg in a1.LEG_NAMES:
        for part, mass in (("hip", 0.696), ("thigh", 1.013), ("calf", 0.166), ("foot", 0.06)):
            assert model.body_mass[model.body(f"{leg}_{part}").id] == pytest.approx(mass)


def test_kinematics(model):
    for leg in a1.LEG_NAMES:
        sx = 1.0 if leg[0] == "F" else -1.0
        sy = 1.0 if leg[1] == "L" else -1.0
        np.testing.assert_allclose(model.body(f"{leg}_hip").pos, [sx * 0.1805, sy * 0.047, 0])
        np.testing.assert_allclose(model.body(f"{leg}_thigh").pos, [0, sy * 0.0838, 0])
        assert np.linalg.norm(model.body(f"{leg}_calf").pos) == pytest.approx(0.2)
        assert np.linalg.norm(model.body(f"{leg}_foot").pos) == pytest.approx(0.2)
        np.testing.assert_allclose(model.body(f"{leg}_foot").pos, [0, 0, -0.2])
        assert model.geom_size[model.geom(f"{leg}_foot").id][0] == pytest.approx(a1.FOOT_RADIUS_M)
    np.testing.assert_allclose(model.geom_size[model.geom("trunk").id], [0.1335, 0.097, 0.057])


def test_joint_and_actuator_order_and_limits(model):
    hinge_names = [
        model.joint(i).name for i in range(model.njnt) if model.jnt_type[i] == mujoco.mjtJoint.mjJNT_HINGE
    ]
    assert tuple(hinge_names) == a1.JOINT_NAMES
    assert model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE and model.joint(0).name == "root"
    assert tuple(model.actuator(i).name for i in range(model.nu)) == a1.JOINT_NAMES
    for i, name in enumerate(a1.JOINT_NAMES):
        j = model.joint(name)
        axis = [1, 0, 0] if "hip" in name else [0, 1, 0]
        np.testing.assert_allclose(j.axis, axis)
        assert j.limited[0]
        np.testing.assert_allclose(j.range, a1.JOINT_RANGE_RAD[i])
        assert model.actuator_trnid[i, 0] == j.id
        np.testing.assert_allclose(model.actuator_ctrlrange[i], a1.JOINT_RANGE_RAD[i])
        assert model.actuator_ctrllimited[i] and model.actuator_forcelimited[i]
        np.testing.assert_allclose(model.actuator_forcerange[i], [-a1.TORQUE_LIMIT_NM, a1.TORQUE_LIMIT_NM])
        assert model.actuator_gainprm[i, 0] == a1.KP_NOMINAL_NM_PER_RAD
        np.testing.assert_allclose(
            model.actuator_biasprm[i, :3], [0, -a1.KP_NOMINAL_NM_PER_RAD, -a1.KD_NOMINAL_NM_S_PER_RAD]
        )
    lo, hi = a1.JOINT_RANGE_RAD.T
    assert np.all((a1.Q_NOMINAL_RAD > lo) & (a1.Q_NOMINAL_RAD < hi))


def test_collision_geoms_sites_sensors(model):
    names = set(a1.NON_FOOT_COLLISION_GEOMS) | set(a1.FOOT_NAMES)
    collidable = {
        model.geom(i).name for i in range(model.ngeom) if model.geom_contype[i] or model.geom_conaffinity[i]
    }
    assert collidable == names
    for n in names:
        g = model.geom(n)
        assert (g.contype[0], g.conaffinity[0]) == (1, 0)
    for f in a1.FOOT_NAMES:
        g = model.geom(f)
        assert g.type[0] == mujoco.mjtGeom.mjGEOM_SPHERE and g.condim[0] == 3 and g.friction[0] == 1.0
        assert model.site(f).bodyid[0] == model.body(f).id
    assert model.site("imu").bodyid[0] == model.body("trunk").id
    np.testing.assert_allclose(model.site("imu").pos, 0)
    assert model.sensor("imu_acc").type[0] == mujoco.mjtSensor.mjSENS_ACCELEROMETER
    assert model.sensor("imu_gyro").type[0] == mujoco.mjtSensor.mjSENS_GYRO


def test_nominal_hips_splay_outward(model):
    """q_nominal's hip signs (+ left, - right) move each foot outward relative to hips at 0."""
    d = mujoco.MjData(model)

    def feet_y(hips_zero: bool) -> np.ndarray:
        _set_nominal(model, d, 0.0)
        if hips_zero:
            for leg in a1.LEG_NAMES:
                d.qpos[model.joint(f"{leg}_hip_joint").qposadr[0]] = 0.0
        mujoco.mj_kinematics(model, d)
        return np.array([d.site_xpos[model.site(f).id][1] for f in a1.FOOT_NAMES])

    side = np.array([1.0 if leg[1] == "L" else -1.0 for leg in a1.LEG_NAMES])
    outward = side * (feet_y(False) - feet_y(True))
    assert np.all(outward > 0.02), outward  # ~0.1 rad x ~0.29 m leg


def test_nominal_trunk_height(model):
    h = a1.nominal_trunk_height_m(model)
    print(f"nominal trunk height above surface = {h:.4f} m (the paper's desired 0.27 m)")
    assert 0.27 <= h <= 0.33


def test_stands_still_on_floor():
    m = build_floor_scene()
    assert m.opt.timestep == DT_S and m.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    d = mujoco.MjData(m)
    h0 = a1.nominal_trunk_height_m(m) + 1e-3  # feet 1 mm above the floor, never inside it
    _set_nominal(m, d, h0)
    d.ctrl[:] = a1.Q_NOMINAL_RAD
    trunk = m.body("trunk").id
    floor = m.geom("floor").id
    foot_ids = {m.geom(f).id for f in a1.FOOT_NAMES}
    non_foot = {m.geom(n).id for n in a1.NON_FOOT_COLLISION_GEOMS}
    settled = None
    for step in range(int(STAND_S / DT_S)):
        mujoco.mj_step(m, d)
        assert np.all(np.isfinite(d.qpos))
        touching = {g for c in d.contact[: d.ncon] for g in (c.geom1, c.geom2) if g != floor}
        assert not touching & non_foot, "non-foot geom touches the floor"
        if step + 1 == int(SETTLE_S / DT_S):
            settled = d.xpos[trunk].copy()
    end = d.xpos[trunk].copy()
    touching = {g for c in d.contact[: d.ncon] for g in (c.geom1, c.geom2) if g != floor}
    sag = h0 - end[2]
    drift_z = abs(end[2] - settled[2])
    drift_xy = np.linalg.norm(end[:2])
    print(
        f"stand 5 s: start z={h0:.4f}, z@{SETTLE_S}s={settled[2]:.4f}, end z={end[2]:.4f}, "
        f"sag={sag * 100:.2f} cm, z drift after settle={drift_z * 1000:.2f} mm, "
        f"xy drift={drift_xy * 1000:.1f} mm"
    )
    assert touching == foot_ids
    assert drift_z < 0.02
    assert sag < 0.04  # static PD compliance at Kp=40 under 12.45 kg
    assert drift_xy < 0.02
    assert np.abs(d.qvel).max() < 0.01  # at rest
    up = d.xmat[trunk].reshape(3, 3)[:, 2]
    assert up[2] > np.cos(0.05)  # trunk stays level within ~3°


# Published link inertials of Unitree's A1 description (unitree_ros, robots/a1_description,
# xacro/const.xacro of 2020, commits 5346d55 / 6dbbff9; the same leg values are in later
# urdf/a1.urdf): mass (kg), CoM (m) and inertia about the CoM (kg m^2) as
# (ixx, iyy, izz, ixy, ixz, iyz), given for the front-left leg. The trunk is 4.713 kg; the model
# lumps the description's 0.001 kg imu_link (at the trunk origin) into it.
PUBLISHED_TRUNK = (
    4.713,
    (0.012731, 0.002186, 0.000515),
    (0.01683993, 0.056579028, 0.064713601, 8.3902e-05, 0.000597679, 2.5134e-05),
)
PUBLISHED_IMU_LINK_KG = 0.001
PUBLISHED_LEG = {
    "hip": (
        0.696,
        (-0.003311, 0.000635, 3.1e-05),
        (0.000469246, 0.00080749, 0.000552929, -9.409e-06, -3.42e-07, -4.66e-07),
    ),
    "thigh": (
        1.013,
        (-0.003237, -0.022327, -0.027326),
        (0.005529065, 0.005139339, 0.001367788, 4.825e-06, 0.000343869, 2.2448e-05),
    ),
    "calf": (
        0.166,
        (0.006435, 0.0, -0.107388),
        (0.002997972, 0.003014022, 3.2426e-05, 0.0, -0.000141163, 0.0),
    ),
    "foot": (0.06, (0.0, 0.0, 0.0), (9.6e-06, 9.6e-06, 9.6e-06, 0.0, 0.0, 0.0)),
}
PUBLISHED_WHOLE_BODY_INERTIA = (
    0.158,
    0.400,
    0.428,
)  # kg m^2 about the CoM, trunk frame, q_nominal (docs/world.md, The robot)
PUBLISHED_TOTAL_MASS_KG = 12.45
PUBLISHED_JOINT_FRICTION_NM = 0.2  # urdf/a1.urdf <dynamics friction="0.2" damping="0.01"/>
PUBLISHED_JOINT_DAMPING = 0.01


def _mirrored(leg: str, part: str):
    """The description's mirroring: CoM x of the hip and its ixz flip front/rear (front_hind);
    CoM y of hip and thigh and their iyz flip left/right (mirror); ixy of the hip flips with both,
    of the thigh with left/right; calf and foot are not mirrored."""
    mass, (cx, cy, cz), (ixx, iyy, izz, ixy, ixz, iyz) = PUBLISHED_LEG[part]
    m = 1.0 if leg[1] == "L" else -1.0
    f = 1.0 if leg[0] == "F" else -1.0
    if part == "hip":
        return mass, (cx * f, cy * m, cz), (ixx, iyy, izz, ixy * m * f, ixz * f, iyz * m)
    if part == "thigh":
        return mass, (cx, cy * m, cz), (ixx, iyy, izz, ixy * m, ixz, iyz * m)
    return PUBLISHED_LEG[part]


def _tensor(ixx, iyy, izz, ixy, ixz, iyz) -> np.ndarray:
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def _body_tensor(model: mujoco.MjModel, body: int) -> np.ndarray:
    """The compiled inertia tensor about the body's CoM, in the body frame."""
    r = np.zeros(9)
    mujoco.mju_quat2Mat(r, model.body_iquat[body])
    r = r.reshape(3, 3)
    return r @ np.diag(model.body_inertia[body]) @ r.T


def _whole_body_inertia(model: mujoco.MjModel) -> tuple[float, np.ndarray]:
    """Total mass and inertia tensor about the whole-body CoM, trunk frame, at q_nominal."""
    d = mujoco.MjData(model)
    _set_nominal(model, d, 0.0)
    mujoco.mj_forward(model, d)
    trunk = model.body("trunk").id
    com = d.subtree_com[trunk]
    inertia = np.zeros((3, 3))
    for b in range(1, model.nbody):
        r = d.ximat[b].reshape(3, 3)
        arm = d.xipos[b] - com
        inertia += r @ np.diag(model.body_inertia[b]) @ r.T
        inertia += model.body_mass[b] * (arm @ arm * np.eye(3) - np.outer(arm, arm))
    rt = d.xmat[trunk].reshape(3, 3)
    return float(model.body_subtreemass[trunk]), rt.T @ inertia @ rt


def test_the_whole_body_inertia_at_the_nominal_stance_is_within_3_percent_of_the_published_values(model):
    _, inertia = _whole_body_inertia(model)
    diag = np.diag(inertia)
    print(f"whole-body inertia about the CoM at q_nominal (trunk frame) = {np.round(diag, 4)} kg m^2")
    np.testing.assert_allclose(diag, PUBLISHED_WHOLE_BODY_INERTIA, rtol=0.03)


def test_the_total_mass_is_the_published_12_45_kg(model):
    total, _ = _whole_body_inertia(model)
    published = PUBLISHED_TRUNK[0] + PUBLISHED_IMU_LINK_KG + 4 * sum(v[0] for v in PUBLISHED_LEG.values())
    assert published == pytest.approx(12.454)
    assert total == pytest.approx(published, abs=1e-9)
    assert total == pytest.approx(PUBLISHED_TOTAL_MASS_KG, abs=0.01)


def test_each_joint_has_the_published_friction_and_damping(model):
    for name in a1.JOINT_NAMES:
        dof = model.joint(name).dofadr[0]
        assert model.dof_frictionloss[dof] == pytest.approx(PUBLISHED_JOINT_FRICTION_NM)
        assert model.dof_damping[dof] == pytest.approx(PUBLISHED_JOINT_DAMPING)
    assert model.dof_frictionloss[model.joint(a1.ROOT_JOINT_NAME).dofadr[0]] == 0  # the free joint has none


def test_each_link_has_the_published_mass_com_and_full_inertia_tensor_mirrored_per_leg(model):
    trunk = model.body("trunk").id
    mass, com, tensor = PUBLISHED_TRUNK
    lumped = mass + PUBLISHED_IMU_LINK_KG
    assert model.body_mass[trunk] == pytest.approx(lumped)
    np.testing.assert_allclose(model.body_ipos[trunk], np.array(com) * mass / lumped, atol=1e-6)
    np.testing.assert_allclose(_body_tensor(model, trunk), _tensor(*tensor), rtol=1e-6, atol=1e-9)
    for leg in a1.LEG_NAMES:
        for part in PUBLISHED_LEG:
            b = model.body(f"{leg}_{part}").id
            mass, com, tensor = _mirrored(leg, part)
            assert model.body_mass[b] == pytest.approx(mass)
            np.testing.assert_allclose(model.body_ipos[b], com, atol=1e-9, err_msg=f"{leg}_{part}")
            got = _body_tensor(model, b)
            np.testing.assert_allclose(got, _tensor(*tensor), rtol=1e-6, atol=1e-11, err_msg=f"{leg}_{part}")
            # physically valid: positive definite, principal moments obey the triangle inequality
            eig = np.linalg.eigvalsh(got)
            assert np.all(eig > 0) and 2 * eig.max() <= eig.sum() + 1e-12
    # two legs spelled out as in the description's expanded urdf/a1.urdf (guards the mirror rule)
    rr_hip = _tensor(0.000469246, 0.00080749, 0.000552929, -9.409e-06, 3.42e-07, 4.66e-07)
    np.testing.assert_allclose(_body_tensor(model, model.body("RR_hip").id), rr_hip, rtol=1e-6, atol=1e-11)
    np.testing.assert_allclose(model.body_ipos[model.body("RR_hip").id], [0.003311, -0.000635, 3.1e-05])
    fr_thigh = _tensor(0.005529065, 0.005139339, 0.001367788, -4.825e-06, 0.000343869, -2.2448e-05)
    np.testing.assert_allclose(
        _body_tensor(model, model.body("FR_thigh").id), fr_thigh, rtol=1e-6, atol=1e-11
    )
    np.testing.assert_allclose(model.body_ipos[model.body("FR_thigh").id], [-0.003237, 0.022327, -0.027326])
