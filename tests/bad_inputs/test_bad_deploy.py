"""Deployment inputs a robot runtime meets, through the loader and the control loop that
docs/deploy.md gives (its one Python block, run as written in a directory holding `deploy/`).

X12: nothing tied policy.json to its policy.onnx, so an edited `action_scale` of 2.5 gave targets
ten times too far; now the sidecar carries the ONNX file's sha256 and must equal the metadata inside
it, and values no robot should run with are refused. X06 and X07: a NaN or Inf in the newest
observation gave NaN actions, which `np.clip` passed on as NaN targets; now the loop holds the last
safe target (the nominal stance before the first good step). One float64 or one 43-value observation
entered the window, and every later, correct call raised; now an observation of the wrong shape or
dtype is refused (ValueError, expected and got) before anything changes, and float64 is cast to float32."""

from __future__ import annotations

import hashlib
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from lasmp.deploy import load_policy
from lasmp.modules.export import SIDECAR_HASH_KEY, deploy_metadata, export_policy

onnx = pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "deploy.md"
SHIPPED = ROOT / "resources" / "policies" / "lasmp_a1.pt"


def documented_loop() -> dict:
    """The namespace of docs/deploy.md's Python block after running it in the working directory
    (it loads `deploy/`); whatever it raises escapes."""
    (code,) = re.findall(r"^```python\n(.*?)^```", DOC.read_text(), re.S | re.M)
    namespace = {"__name__": "deploy_md"}
    exec(compile(code, str(DOC), "exec"), namespace)
    return namespace


def refused_by_loader(*patterns: str) -> str:
    """The documented loader refuses `deploy/` with its ExportError, whose message holds each pattern."""
    with pytest.raises(Exception) as caught:
        documented_loop()
    assert type(caught.value).__name__ == "ExportError", repr(caught.value)
    message = str(caught.value)
    assert "\n" not in message
    for pattern in patterns:
        assert re.search(pattern, message), f"{pattern!r} not in {message!r}"
    return message


@pytest.fixture(scope="module")
def export(tmp_path_factory) -> Path:
    """The shipped checkpoint's policy exported once (policy.onnx and policy.json)."""
    deployed = load_policy(SHIPPED)
    meta = deploy_metadata(deployed.policy, deployed.cfg, deployed.checkpoint["iter"], SHIPPED.name)
    out = tmp_path_factory.mktemp("export") / "deploy"
    export_policy(deployed.policy, out, meta)
    return out


@pytest.fixture
def deploy(export) -> Path:
    """A copy of the export as `deploy/` in this test's working directory (where the doc loads it)."""
    return Path(shutil.copytree(export, "deploy"))


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def edit(deploy: Path, onnx_values: dict | None = None, sidecar_values: dict | None = None, rehash=False):
    """Change metadata values inside policy.onnx and/or in policy.json (as a hand or a tool would);
    `rehash`: also write the changed ONNX's sha256 into the sidecar (an edit made to look whole)."""
    onnx_file, json_file = deploy / "policy.onnx", deploy / "policy.json"
    if onnx_values:
        model = onnx.load(str(onnx_file))
        props = {p.key: p.value for p in model.metadata_props}
        props.update({key: json.dumps(value) for key, value in onnx_values.items()})
        del model.metadata_props[:]
        onnx.helper.set_model_props(model, props)
        onnx.save(model, str(onnx_file))
    sidecar = json.loads(json_file.read_text())
    sidecar.update(sidecar_values or {})
    if rehash:
        sidecar[SIDECAR_HASH_KEY] = sha256(onnx_file)
    json_file.write_text(json.dumps(sidecar))


# ---------------------------------------------------------------------------------------------
# X12: the sidecar and its ONNX
# ---------------------------------------------------------------------------------------------
def test_the_sidecar_holds_the_sha256_of_the_onnx_file_and_the_documented_loader_accepts_the_pair(deploy):
    sidecar = json.loads((deploy / "policy.json").read_text())
    assert sidecar[SIDECAR_HASH_KEY] == sha256(deploy / "policy.onnx")
    ns = documented_loop()
    assert SIDECAR_HASH_KEY not in ns["meta"] and ns["meta"]["action_scale"] == 0.25


@pytest.mark.parametrize("missing", ["policy.json", "policy.onnx"])
def test_an_export_missing_one_of_its_two_files_is_refused_naming_it(deploy, missing):
    (deploy / missing).unlink()
    refused_by_loader(rf"deploy/{re.escape(missing)} is missing", "both files")


def test_an_action_scale_edited_in_the_sidecar_is_refused_as_differing_from_the_onnx(deploy):
    edit(deploy, sidecar_values={"action_scale": 2.5})
    refused_by_loader(
        r"deploy/policy\.json differs from deploy/policy\.onnx", r"\['action_scale'\]", "export"
    )


def test_an_action_scale_edited_inside_the_onnx_no_longer_matches_the_sidecars_hash(deploy):
    edit(deploy, onnx_values={"action_scale": 2.5})
    refused_by_loader(r"deploy/policy\.json does not hold the sha256 of deploy/policy\.onnx", "export")


def test_a_sidecar_of_another_export_is_refused(deploy):
    edit(deploy, sidecar_values={SIDECAR_HASH_KEY: hashlib.sha256(b"another policy.onnx").hexdigest()})
    refused_by_loader(r"does not hold the sha256 of deploy/policy\.onnx")


def test_a_sidecar_without_a_hash_is_refused(deploy):
    sidecar = json.loads((deploy / "policy.json").read_text())
    del sidecar[SIDECAR_HASH_KEY]
    (deploy / "policy.json").write_text(json.dumps(sidecar))
    refused_by_loader(r"does not hold the sha256")


def test_a_sidecar_that_is_not_json_is_refused(deploy):
    (deploy / "policy.json").write_text('{"action_scale": 0.25,')
    refused_by_loader(r"deploy/policy\.json is not JSON")


@pytest.mark.parametrize(
    ("key", "value", "pattern"),
    [
        ("action_scale", 0.0, r"action_scale = 0\.0, not 1 positive finite number"),
        ("action_scale", -0.25, r"action_scale = -0\.25"),
        ("action_scale", float("nan"), r"action_scale = nan"),
        ("action_scale", float("inf"), r"action_scale = inf"),
        ("action_clip", 0.0, r"action_clip = 0\.0"),
        ("kp_nm_per_rad", [40.0] * 11 + [0.0], r"kp_nm_per_rad = .*not 12 positive finite number"),
        ("kd_nm_s_per_rad", [-1.0] * 12, r"kd_nm_s_per_rad"),
        ("kp_nm_per_rad", [40.0] * 6, r"kp_nm_per_rad = .*not 12"),
        ("torque_limit_nm", [float("inf")] * 12, r"torque_limit_nm"),
        ("control_dt_s", 0.0, r"control_dt_s = 0\.0"),
        ("physics_dt_s", -0.005, r"physics_dt_s"),
        ("decimation", 0, r"decimation = 0"),
        ("control_dt_s", 0.05, r"control_dt_s is not physics_dt_s \* decimation"),
        ("default_joint_pos_rad", [9.0] * 12, r"default_joint_pos_rad is not within joint_pos_limits_rad"),
        ("joint_pos_limits_rad", [[0.0, 1.0]] * 11, r"malformed metadata"),
        ("action_scale", "0.25", r"action_scale = '0\.25', not 1 positive finite number"),
        ("metadata_version", 2, r"metadata_version is 2, not 1"),
    ],
)
def test_values_no_robot_should_run_with_are_refused_even_in_a_consistent_export(deploy, key, value, pattern):
    # the same value inside the ONNX and in the sidecar, with the sidecar rehashed: only the range check is left
    edit(deploy, onnx_values={key: value}, sidecar_values={key: value}, rehash=True)
    refused_by_loader(r"^deploy/policy\.json: ", pattern)


# ---------------------------------------------------------------------------------------------
# X06 and X07: a non-finite observation
# ---------------------------------------------------------------------------------------------
def standing_observation(ns: dict, k: int) -> np.ndarray:
    """A plausible o_t (level, nearly still, near the default stance), different for each k."""
    wobble = 0.02 * np.sin(np.arange(12) + k)
    return ns["observe"]([0.0, 0.0, 9.81], [0.01 * k, 0.0, 0.0], 0.0, 0.01, ns["q0"] + wobble, wobble)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_non_finite_observation_holds_the_last_target_and_leaves_no_trace(deploy, bad):
    ns = documented_loop()
    targets = [ns["control_step"](standing_observation(ns, k)) for k in range(3)]
    held, window, last_action = targets[-1].copy(), ns["window"].copy(), ns["last_action"].copy()
    for column in (0, 10, 25, 43):  # accelerometer, joint_pos, joint_vel, last_action
        o = standing_observation(ns, 3)
        o[column] = bad
        sent = ns["control_step"](o)
        assert np.all(np.isfinite(sent))
        np.testing.assert_array_equal(sent, held)
    np.testing.assert_array_equal(ns["window"], window)  # the bad o never entered the window
    np.testing.assert_array_equal(ns["last_action"], last_action)
    after = ns["control_step"](standing_observation(ns, 3))
    # the same target as a loop that never saw the bad observations
    clean = documented_loop()
    for k in range(4):
        expected = clean["control_step"](standing_observation(clean, k))
    np.testing.assert_array_equal(after, expected)
    assert np.all(np.isfinite(after)) and not np.array_equal(after, held)


def test_a_non_finite_first_observation_holds_the_nominal_stance(deploy):
    ns = documented_loop()
    o = standing_observation(ns, 0)
    o[:3] = np.nan
    sent = ns["control_step"](o)
    lo, hi = np.asarray(ns["meta"]["joint_pos_limits_rad"]).T
    np.testing.assert_array_equal(sent, np.clip(ns["meta"]["default_joint_pos_rad"], lo, hi))
    assert ns["window"] is None  # the window starts with the first finite observation
    assert np.all(np.isfinite(ns["control_step"](standing_observation(ns, 0))))


def test_a_non_finite_action_is_never_sent_and_the_last_target_is_held(deploy):
    ns = documented_loop()
    held = ns["control_step"](standing_observation(ns, 0))

    class BrokenSession:  # a model that gives NaN (what a corrupted graph or a bad runtime could)
        def run(self, names, feeds):
            return [np.full((1, 12), np.nan, dtype=np.float32)]

    ns["sess"] = BrokenSession()
    sent = ns["control_step"](standing_observation(ns, 1))
    np.testing.assert_array_equal(sent, held)
    assert np.all(np.isfinite(sent))


def test_a_huge_finite_observation_is_clipped_as_in_training(deploy):
    ns = documented_loop()
    o = standing_observation(ns, 0)
    o[20] = 1e30  # a joint velocity far beyond obs_clip
    assert np.all(np.isfinite(ns["control_step"](o)))
    assert ns["window"][0, 0, 20] == ns["meta"]["obs_clip"]


def test_export_refuses_metadata_that_already_holds_the_hash_key_before_any_work(tmp_path):
    with pytest.raises(ValueError, match=SIDECAR_HASH_KEY):
        export_policy(None, tmp_path / "out", {SIDECAR_HASH_KEY: "0" * 64})
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------------------------------
# An observation of the wrong length or dtype
# ---------------------------------------------------------------------------------------------
def loop_state(ns: dict) -> tuple:
    """What control_step keeps between calls: the window, the last action and the held target."""
    return tuple(None if ns[k] is None else ns[k].copy() for k in ("window", "last_action", "q_target"))


BAD_OBSERVATIONS = {
    "43 values": (lambda o: o[:43], r"expected shape \(44,\) .*got shape \(43,\)"),
    "45 values": (lambda o: np.append(o, np.float32(0.0)), r"expected shape \(44,\) .*got shape \(45,\)"),
    "a (1, 44) row": (lambda o: o[None], r"expected shape \(44,\) .*got shape \(1, 44\)"),
    "integers": (lambda o: np.round(o).astype(np.int64), r"expected dtype float32 .*got int64"),
    "booleans": (lambda o: o > 0, r"expected dtype float32 .*got bool"),
}


@pytest.mark.parametrize("bad", list(BAD_OBSERVATIONS))
def test_an_observation_of_the_wrong_length_or_dtype_is_refused_and_the_next_calls_act_as_without_it(
    deploy, bad
):
    change, message = BAD_OBSERVATIONS[bad]
    clean = documented_loop()
    expected = [clean["control_step"](standing_observation(clean, k)) for k in range(6)]
    ns = documented_loop()
    sent = [ns["control_step"](standing_observation(ns, k)) for k in range(3)]
    before = loop_state(ns)
    with pytest.raises(ValueError, match=message):
        ns["control_step"](change(standing_observation(ns, 3)))
    for kept, now in zip(before, loop_state(ns), strict=True):  # nothing changed
        np.testing.assert_array_equal(now, kept)
    sent += [ns["control_step"](standing_observation(ns, k)) for k in range(3, 6)]
    np.testing.assert_array_equal(np.array(sent), np.array(expected))


@pytest.mark.parametrize("bad", ["43 values", "integers"])
def test_a_refused_first_observation_leaves_no_window_and_the_loop_starts_with_the_next(deploy, bad):
    change, message = BAD_OBSERVATIONS[bad]
    clean = documented_loop()
    expected = [clean["control_step"](standing_observation(clean, k)) for k in range(3)]
    ns = documented_loop()
    with pytest.raises(ValueError, match=message):
        ns["control_step"](change(standing_observation(ns, 0)))
    assert ns["window"] is None
    sent = [ns["control_step"](standing_observation(ns, k)) for k in range(3)]
    np.testing.assert_array_equal(np.array(sent), np.array(expected))


def test_a_float64_observation_is_cast_to_float32_and_acts_as_its_float32_values(deploy):
    as_float32 = documented_loop()
    expected = [as_float32["control_step"](standing_observation(as_float32, k)) for k in range(4)]
    ns = documented_loop()
    sent = [ns["control_step"](standing_observation(ns, k).astype(np.float64)) for k in range(4)]
    np.testing.assert_array_equal(np.array(sent), np.array(expected))
    assert ns["window"].dtype == np.float32
    np.testing.assert_array_equal(ns["window"], as_float32["window"])
