"""Unitree A1 constants: every per-robot number the envs need, in one place.

Model: ``resources/robots/a1/a1.xml`` (authored for this project from the published A1
parameters, docs/world.md, The robot).

Frames: trunk/body frame x forward, y left, z up, origin at the trunk box centre (the ``imu``
site). The trunk's CoM is offset from that origin by ``TRUNK_COM_M``.

Joint order (actuators and joints, the order of ``q``, ``q_dot``, actions):
FR, FL, RR, RL legs, each (hip, thigh, calf) ->
``FR_hip_joint, FR_thigh_joint, FR_calf_joint, FL_hip_joint, ..., RL_calf_joint``.

Joint sign conventions (rad): zero = leg straight down. Hip = abduction about +x: a positive
hip angle swings the foot toward +y, so +q splays a *left* leg outward and -q splays a
*right* leg outward; the nominal hips (+0.1 left, -0.1 right) are therefore splayed out.
Thigh about +y: positive swings the knee backward. Calf about +y, always negative
(knee bent, foot forward of the knee).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[2]
MJCF_PATH: Path = REPO_ROOT / "resources" / "robots" / "a1" / "a1.xml"

LEG_NAMES: tuple[str, ...] = ("FR", "FL", "RR", "RL")
JOINT_NAMES: tuple[str, ...] = tuple(
    f"{leg}_{part}_joint" for leg in LEG_NAMES for part in ("hip", "thigh", "calf")
)
FOOT_NAMES: tuple[str, ...] = tuple(f"{leg}_foot" for leg in LEG_NAMES)  # geom, body and site names
TRUNK_BODY_NAME = "trunk"
ROOT_JOINT_NAME = "root"

# Nominal stance q_nominal (rad), order JOINT_NAMES: hips splayed out (+0.1 left, -0.1 right),
# thighs 0.8 front / 1.0 rear, calves -1.5 (docs/world.md, The robot).
_HIP_OUT_RAD = 0.1  # hip abduction magnitude; sign: + for left legs, - for right (= splayed out)
Q_NOMINAL_RAD: np.ndarray = np.concatenate(
    [
        [-_HIP_OUT_RAD, 0.8, -1.5],  # FR
        [+_HIP_OUT_RAD, 0.8, -1.5],  # FL
        [-_HIP_OUT_RAD, 1.0, -1.5],  # RR
        [+_HIP_OUT_RAD, 1.0, -1.5],  # RL
    ]
).astype(np.float64)
Q_NOMINAL_RAD.flags.writeable = False

# Joint limits (rad), order JOINT_NAMES.
_HIP_RANGE, _THIGH_RANGE, _CALF_RANGE = (-0.803, 0.803), (-1.047, 4.189), (-2.697, -0.916)
JOINT_RANGE_RAD: np.ndarray = np.array([_HIP_RANGE, _THIGH_RANGE, _CALF_RANGE] * 4, dtype=np.float64)
JOINT_RANGE_RAD.flags.writeable = False

TORQUE_LIMIT_NM = 33.5  # per joint, N·m
KP_NOMINAL_NM_PER_RAD = 40.0  # position-actuator stiffness
KD_NOMINAL_NM_S_PER_RAD = 1.0  # position-actuator damping (kv)

TRUNK_MASS_KG = 4.714  # as in a1.xml (nominal, before randomization)
TRUNK_COM_M: np.ndarray = np.array([0.0127, 0.002, 0.0006])  # trunk CoM in the trunk frame, m
TRUNK_COM_M.flags.writeable = False

FOOT_RADIUS_M = 0.02

# The sagittal mirror (left <-> right): each leg's mirror image, in LEG_NAMES order, and per joint in
# JOINT_NAMES order the joint whose mirror it is and the sign its angle takes (hip abduction flips;
# thigh and calf turn about the y axis, which the mirror keeps). q_nominal is mirror-symmetric.
MIRROR_LEGS: tuple[int, ...] = (1, 0, 3, 2)  # FR <-> FL, RR <-> RL
MIRROR_JOINTS: tuple[int, ...] = tuple(3 * MIRROR_LEGS[j // 3] + j % 3 for j in range(12))
MIRROR_JOINT_SIGNS: tuple[float, ...] = (-1.0, 1.0, 1.0) * 4
NON_FOOT_COLLISION_GEOMS: tuple[str, ...] = ("trunk",) + tuple(
    f"{leg}_{part}" for leg in LEG_NAMES for part in ("hip", "thigh", "calf")
)


def load_model() -> mujoco.MjModel:
    """Compile the bare robot (floating, no floor)."""
    return mujoco.MjModel.from_xml_path(str(MJCF_PATH))


def nominal_trunk_height_m(model: mujoco.MjModel | None = None) -> float:
    """Trunk-origin height (m) above a flat surface at q_nominal with the lowest foot touching.

    Forward kinematics with the trunk level at the origin: height = -(lowest foot-sphere bottom).
    ``model`` may be any model containing the A1 with the standard names (default: the bare
    robot); joints are addressed by name so attached scenes work too.
    """
    model = load_model() if model is None else model
    data = mujoco.MjData(model)
    root = model.joint(ROOT_JOINT_NAME)
    data.qpos[root.qposadr[0] : root.qposadr[0] + 7] = [0, 0, 0, 1, 0, 0, 0]
    for name, q in zip(JOINT_NAMES, Q_NOMINAL_RAD, strict=True):
        data.qpos[model.joint(name).qposadr[0]] = q
    mujoco.mj_kinematics(model, data)
    trunk_z = data.xpos[model.body(TRUNK_BODY_NAME).id][2]
    lowest = min(
        data.geom_xpos[model.geom(f).id][2] - model.geom_size[model.geom(f).id][0] for f in FOOT_NAMES
    )
    return float(trunk_z - lowest)
