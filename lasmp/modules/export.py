"""The exported LAS-MP policy (docs/deploy.md): the ONNX file of the network (`LasmpDeployPolicy`,
in `policy.py`) and the metadata that travels with it, what a robot runtime needs besides."""

from __future__ import annotations

import json
import logging
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

from lasmp.io.atomic import atomic_open, atomic_write_with
from lasmp.io.inputs import file_sha256
from lasmp.robots import a1

if TYPE_CHECKING:
    from lasmp.modules.policy import LasmpActor


# ---------------------------------------------------------------------------------------------
# Deployment metadata: what a robot runtime needs to run the exported policy without this repo
# ---------------------------------------------------------------------------------------------
METADATA_VERSION = 1  # bump when a key changes meaning or disappears (docs/deploy.md lists them)
SIDECAR_HASH_KEY = "onnx_sha256"  # policy.json only: the sha256 of the policy.onnx it describes
BODY_FRAME = "trunk (body) frame at the IMU/trunk origin: x forward, y left, z up"

# o_t, slot by slot, as `lasmp.envs.robot.proprioception` builds it (tests/modules/test_export.py holds the
# two together); `components` name each column, `start` is the first column of the slot in o_t
_OBS_SLOTS: tuple[tuple[str, tuple[str, ...], str, str, str], ...] = (
    (
        "accelerometer",
        ("x", "y", "z"),
        "m/s^2",
        BODY_FRAME,
        "IMU specific force (what an accelerometer reads: +9.81 on z when standing still and level)",
    ),
    ("gyro", ("x", "y", "z"), "rad/s", BODY_FRAME, "IMU angular velocity of the trunk"),
    (
        "roll_pitch",
        ("roll", "pitch"),
        "rad",
        "trunk attitude w.r.t. gravity",
        "ZYX Euler angles of the trunk, R_world_body = Rz(yaw) Ry(pitch) Rx(roll); yaw is not observed",
    ),
    (
        "joint_pos",
        (),
        "rad",
        "joint space, order joint_names",
        "joint angle relative to the default pose: q - default_joint_pos_rad",
    ),
    ("joint_vel", (), "rad/s", "joint space, order joint_names", "joint angular velocity q_dot"),
    (
        "last_action",
        (),
        "1 (raw policy output)",
        "joint space, order joint_names",
        "the previous step's action after the clip to +-action_clip, before scaling; 0 at the first step",
    ),
)


def observation_layout(joint_names: tuple[str, ...] | list[str]) -> list[dict]:
    """The slots of o_t in order: name, start column, size, unit, frame, description, components."""
    slots, start = [], 0
    for name, components, unit, frame, description in _OBS_SLOTS:
        components = components or tuple(joint_names)
        slots.append(
            {
                "name": name,
                "start": start,
                "size": len(components),
                "unit": unit,
                "frame": frame,
                "description": description,
                "components": list(components),
            }
        )
        start += len(components)
    return slots


def _normalization(actor: LasmpActor) -> dict:
    """How the observations are normalized: inside the graph (the actor's EmpiricalNormalization,
    o-part, for reference) or not at all; either way the runtime feeds raw observations."""
    if not actor.obs_normalization:
        return {"folded_into_graph": False, "feed": "raw observations", "formula": "none"}
    norm = actor.obs_normalizer
    return {
        "folded_into_graph": True,
        "feed": "raw observations (do not normalize them again)",
        "formula": "(o - mean) / (std + eps), per column of o_t, for every o in the window",
        "mean": norm.mean[: actor.num_obs].tolist(),
        "std": norm.std[: actor.num_obs].tolist(),
        "eps": float(norm.eps),
    }


def _lasmp_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("lasmp")
    except PackageNotFoundError:  # a source tree that was never installed
        return "unknown"


def deploy_metadata(actor: LasmpActor, cfg, iteration: int, checkpoint_file: str) -> dict:
    """Everything a robot runtime needs besides the network, as JSON-ready values (docs/deploy.md).

    `cfg` is the checkpoint's TrainCfg (its env config fixes the timing, the action scale and H);
    the robot's constants come from `lasmp.robots.a1`, the normalization from `actor`.
    """
    env = cfg.env
    n_joints, h = len(a1.JOINT_NAMES), actor.history_len
    ranges = env.domain_rand.train if env.domain_rand.enabled else None
    kp_range = list(ranges.joint_kp) if ranges else [a1.KP_NOMINAL_NM_PER_RAD] * 2
    kd_range = list(ranges.joint_kd) if ranges else [a1.KD_NOMINAL_NM_S_PER_RAD] * 2
    return {
        "metadata_version": METADATA_VERSION,
        "lasmp_version": _lasmp_version(),
        "task": cfg.task,
        "policy_name": cfg.policy.name,
        "checkpoint_iteration": int(iteration),
        "checkpoint_file": checkpoint_file,
        "robot": "unitree_a1",
        "joint_names": list(a1.JOINT_NAMES),
        "default_joint_pos_rad": a1.Q_NOMINAL_RAD.tolist(),
        "joint_pos_limits_rad": a1.JOINT_RANGE_RAD.tolist(),
        "kp_nm_per_rad": [a1.KP_NOMINAL_NM_PER_RAD] * n_joints,
        "kd_nm_s_per_rad": [a1.KD_NOMINAL_NM_S_PER_RAD] * n_joints,
        "kp_training_range_nm_per_rad": [float(x) for x in kp_range],
        "kd_training_range_nm_s_per_rad": [float(x) for x in kd_range],
        "torque_limit_nm": [a1.TORQUE_LIMIT_NM] * n_joints,
        "action_scale": float(env.control.action_scale),
        "action_clip": float(env.control.action_clip),
        "action_to_target": "q_target = default_joint_pos_rad + action_scale * clip(a, -action_clip, "
        "action_clip), then clipped to joint_pos_limits_rad; held for one control period",
        "pd_law": "tau = clip(kp * (q_target - q) - kd * q_dot, -torque_limit_nm, torque_limit_nm), "
        "every physics step",
        "control_dt_s": float(env.sim.dt_s * env.sim.decimation),
        "physics_dt_s": float(env.sim.dt_s),
        "decimation": int(env.sim.decimation),
        "history_length": int(h),
        "obs_dim": int(actor.num_obs),
        "obs_layout": observation_layout(a1.JOINT_NAMES),
        "joint_pos_convention": "relative: joint_pos = q - default_joint_pos_rad",
        "obs_clip": float(env.observations.clip),
        "obs_normalization": _normalization(actor),
        "input_name": "obs_window",
        "input_shape": [1, h + 1, int(actor.num_obs)],
        "input_order": "newest_first: obs_window[0, k] = o_{t-k}, k = 0..history_length; at start "
        "(and after any reset) every row is the first o",
        "output_name": "actions",
        "output_shape": [1, n_joints],
    }


def metadata_props(meta: dict) -> dict[str, str]:
    """The ONNX `metadata_props` of `meta`: every value JSON-encoded (json.loads gives it back)."""
    return {key: json.dumps(value) for key, value in meta.items()}


def read_onnx_metadata(path: str | Path) -> dict:
    """The deployment metadata of an exported ONNX file, decoded (the inverse of `metadata_props`)."""
    import onnx

    model = onnx.load(str(path), load_external_data=False)
    return {p.key: json.loads(p.value) for p in model.metadata_props}


# torch's exporter, not ours: its op registry logs a warning for each torchvision op it skips when
# torchvision is absent (a policy uses none), and its pytree code warns that it uses a deprecated
# class of its own (torch 2.13). Both are silenced for the export call alone.
_TORCH_ONNX_REGISTRY_LOGGER = "torch.onnx._internal.exporter._registration"
_TORCH_PYTREE_WARNING = r"`isinstance\(treespec, LeafSpec\)` is deprecated"


def write_onnx(module, path: str | Path) -> None:
    """`module` (a policy's `as_onnx()`, in eval mode) as one self-contained ONNX file at `path`,
    opset 18, without torch's exporter noise."""
    import torch

    registry = logging.getLogger(_TORCH_ONNX_REGISTRY_LOGGER)
    level = registry.level
    registry.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=_TORCH_PYTREE_WARNING, category=FutureWarning)
            torch.onnx.export(
                module,
                module.get_dummy_inputs(),
                str(path),
                export_params=True,
                opset_version=18,
                input_names=module.input_names,
                output_names=module.output_names,
                external_data=False,  # one self-contained file (a temp name must not leak into it)
                verbose=False,
            )
    finally:
        registry.setLevel(level)


def sidecar_text(metadata: dict, onnx_sha256: str) -> str:
    """`policy.json`: `onnx_sha256` first, then the metadata, one key a line and each value compact
    (JSON that reads like the list in docs/deploy.md)."""
    items = {SIDECAR_HASH_KEY: onnx_sha256, **metadata}
    lines = [f"  {json.dumps(key)}: {json.dumps(value)}" for key, value in items.items()]
    return "{\n" + ",\n".join(lines) + "\n}\n"


def export_policy(policy, out_dir: str | Path, metadata: dict | None = None) -> Path:
    """Write the deployable policy (input obs_window (1, H+1, D), output actions) as ONNX.

    With `metadata` (`lasmp.modules.export.deploy_metadata`), the file carries it in its
    `metadata_props` (each value JSON-encoded) and `policy.json` is written beside it, with the
    sha256 of the ONNX file's bytes (`onnx_sha256`): what ties the two, so that a runtime refuses a
    sidecar that came from another export or was edited (docs/deploy.md's loader).

    Both are written atomically. The hash is taken of the finished temporary file, the very bytes
    that are renamed into place; the sidecar is renamed after the ONNX, so a failure between the two
    leaves an ONNX whose sidecar's hash does not match, which the loader refuses, rather than a
    pair that looks whole. `play.py` stages both files and renames them together (`export_into`).
    """
    if metadata is not None and SIDECAR_HASH_KEY in metadata:
        raise ValueError(f"the metadata must not hold {SIDECAR_HASH_KEY!r}: export_policy adds it")
    out_dir = Path(out_dir)
    module = policy.as_onnx(False).eval()
    path = out_dir / "policy.onnx"
    written: dict[str, str] = {}

    def write(tmp: str) -> None:
        write_onnx(module, tmp)
        if metadata is not None:
            import onnx

            model = onnx.load(tmp)
            onnx.helper.set_model_props(model, metadata_props(metadata))
            onnx.save(model, tmp)
        written["sha256"] = file_sha256(tmp)

    if metadata is None:
        atomic_write_with(path, write)
        return path
    with atomic_open(out_dir / "policy.json", "w") as f:  # renamed when the ONNX is in place
        atomic_write_with(path, write)
        f.write(sidecar_text(metadata, written["sha256"]))
    return path
