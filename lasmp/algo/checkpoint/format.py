"""The checkpoint file's format: writing it atomically, reading it safely and checked, its
compatibility with an env, the random state it carries (the package's docstring says what a
checkpoint holds)."""

from __future__ import annotations

import contextlib
import os
import pickle
import re
import stat
import zipfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import torch

from lasmp.io.atomic import OutputExistsError, atomic_open, claim_output
from lasmp.io.inputs import InputError, check_out_file
from lasmp.io.rundir import CHECKPOINT_NAME, FULL, POLICY, run_checkpoints

CHECKPOINT_VERSION = 1


CHECKPOINT_FORMAT = f"lasmp-checkpoint-v{CHECKPOINT_VERSION}"


CHECKPOINT_SUFFIXES = (".pt", ".pth")  # what the checkpoint tool writes


REQUIRED_KEYS = ("actor_state_dict", "critic_state_dict", "config", "obs_layout", "num_actions", "iter")


# the envs' running-state format (BaseEnv.RUN_STATE_FORMAT) that stores it as plain data: what
# `convert_trusted` writes (a test holds it equal to the env's)
PLAIN_RUN_STATE_FORMAT = 3


# The envs' running state names the class of each dataclass it holds (`lasmp.io.plainstate.pack`), and
# `unpack` restores one only into a live value of that class with the same fields. A checkpoint
# that names a class or a field otherwise reads back through this table, kept here so that the
# envs' classes carry one name each: task -> attribute -> rules (class in the file, class now,
# {field in the file: field now}, fields the class now lacks: dropped). `rename_run_state` applies
# them to every checkpoint read (`read_checkpoint`) and converted (`convert_trusted`).
RunStateRule = tuple[str, str, dict[str, str], tuple[str, ...]]


RENAMED_RUN_STATE: dict[str, dict[str, tuple[RunStateRule, ...]]] = {
    "moving_platform": {"readout": (("Readout", "SceneReadout", {}, ()),)},
    "rough_static": {
        "last_state": (
            ("RoughStepState", "StepState", {"body_contact": "collision"}, ()),
            ("StepState", "StepState", {"body_contact": "collision"}, ()),
        ),
        # robots held with the moving platform's gain factors, which the R-S baseline never reads
        "intrinsics": (("Intrinsics", "RobotIntrinsics", {}, ("platform_kp_factor", "platform_kd_factor")),),
    },
}


class CheckpointError(ValueError):
    """A checkpoint is missing, unreadable or does not fit this run; the message says why."""


def obs_layout(obs) -> dict[str, list[int]]:
    """Per-group shapes of one env's observation (batch dimension dropped)."""
    return {key: list(value.shape[1:]) for key, value in obs.items()}


def latest_checkpoint(run_dir: str | Path, full_only: bool = False) -> Path:
    """The checkpoint of `run_dir` with the largest N (numerically: 10 after 9), full or policy only
    (`full_only`: the newest `model_<N>.pt`, the one a resume needs)."""
    found = run_checkpoints(run_dir, full_only)
    if not found:
        if full_only and run_checkpoints(run_dir):
            raise CheckpointError(
                f"no full checkpoint model_<N>.pt in {run_dir}, only policy checkpoints (policy_<N>.pt), "
                "which hold no training state: they play and evaluate, but cannot resume training"
            )
        raise CheckpointError(f"no checkpoint model_<N>.pt or policy_<N>.pt in {run_dir}")
    return found[max(found)]


def _converted(path: Path) -> str:
    """For a missing `model_<N>.pt` whose `policy_<N>.pt` exists: what became of it."""
    m = CHECKPOINT_NAME.fullmatch(path.name)
    policy = path.with_name(f"{POLICY}_{m.group(2)}.pt") if m and m.group(1) == FULL else None
    if policy is None or not policy.exists():
        return ""
    return (
        f" (runner.keep_full kept it as the policy checkpoint {policy.name}, which plays and "
        "evaluates but cannot resume training)"
    )


def checkpoint_file(path: str | Path, full_only: bool = False) -> Path:
    """The file a checkpoint argument names (a run directory: its latest checkpoint), checked to be a
    regular file (a symlink to one included). Why: a FIFO waits for a writer for ever and /dev/zero
    never ends, so torch.load would hang; a directory or a device is never a checkpoint."""
    path = Path(path)
    if path.is_dir():
        path = latest_checkpoint(path, full_only)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise CheckpointError(f"checkpoint {path} does not exist{_converted(path)}") from None
    except OSError as err:  # a symlink loop, no permission
        raise CheckpointError(f"checkpoint {path} cannot be read: {err.strerror or err}") from None
    if not stat.S_ISREG(mode):
        what = next((w for test, w in _NOT_REGULAR if test(mode)), "not a regular file")
        if path.is_symlink():
            what += f" (it links to {os.path.realpath(path)})"
        raise CheckpointError(
            f"checkpoint {path} is {what}, not a regular file: give a checkpoint file "
            f"({FULL}_<N>.pt or {POLICY}_<N>.pt) or its run directory"
        )
    return path


_NOT_REGULAR = (
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISDIR, "a directory"),
)


# how torch.save's older (pre-1.6, non-zip) files begin: a pickled magic number
_TORCH_LEGACY_MAGIC = b"\x80\x02\x8a\x0a\x6c\xfc\x9c\x46\xf9\x20\x6a\xa8\x50\x19"


def _not_torch(path: Path) -> str | None:
    """What a regular file is when it cannot be a PyTorch checkpoint, from its first bytes (None where
    it may be one). Why: torch.load of such a file fails with a message about pickles or zip
    internals; of an ONNX model with the advice to `convert --trust` it, which then fails too."""
    with open(path, "rb") as f:
        head = f.read(512)
    if not head:
        return "an empty file, 0 bytes: an interrupted copy or save?"
    if head.startswith(b"PK"):  # a zip archive, as torch.save writes
        try:
            with zipfile.ZipFile(path) as z:
                names = z.namelist()
        except (zipfile.BadZipFile, OSError, ValueError):
            return None  # a truncated checkpoint: torch.load says so
        if any(n == "data.pkl" or n.endswith("/data.pkl") for n in names):
            return None
        if names and all(n.endswith(".npy") for n in names):
            return "a NumPy .npz archive: a trajectory or benchmark file?"
        return "a zip archive without the data.pkl that torch.save writes"
    if head.startswith(_TORCH_LEGACY_MAGIC):
        return None
    if path.suffix.lower() == ".onnx" or (head[0] == 0x08 and head[2:3] == b"\x12"):
        return "an ONNX model? Play and evaluate take the .pt checkpoint it was exported from"
    if head.startswith(b"\x93NUMPY"):
        return "a NumPy .npy array"
    if head[0] == 0x80:
        return "a Python pickle that torch.save did not write"
    if all(32 <= b < 127 or b in b"\t\n\r" for b in head):
        return "a text file"
    return "its content is neither a zip archive, as torch.save writes, nor an older torch file"


def read_checkpoint(path: str | Path, map_location: str = "cpu", full_only: bool = False) -> dict:
    """Load and sanity-check a checkpoint file (a run directory means its latest checkpoint, the
    latest full one with `full_only`). The one loader of every command (train's resume, play,
    evaluate, the checkpoint tool): only a regular file that looks like a PyTorch checkpoint reaches
    torch.load, and a checkpoint of a newer format is told apart from a file that is none."""
    path = checkpoint_file(path, full_only)
    why = _not_torch(path)
    if why is not None:
        raise CheckpointError(
            f"{path} is not a PyTorch checkpoint ({why}): unreadable as one. Give a lasmp checkpoint "
            f"({FULL}_<N>.pt or {POLICY}_<N>.pt) or its run directory"
        )
    try:
        data = torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as err:
        if "weights only" not in str(err).lower():  # a pickle stream that is not a checkpoint
            raise CheckpointError(f"checkpoint {path} is unreadable (not a checkpoint): {err}") from err
        raise CheckpointError(
            f"checkpoint {path} holds pickled Python objects, and unpickling them could run any code: "
            "refused. Checkpoints of lasmp before plain running state (format 3) are like this. If you "
            f"trust this file, convert it once with: python -m lasmp.algo.checkpoint convert --trust {path} OUT"
        ) from None
    except Exception as err:  # truncated zip, not a torch file, ...
        raise CheckpointError(
            f"checkpoint {path} is unreadable (truncated or not a checkpoint): {err}"
        ) from err
    _check_format(data, path)
    for key in REQUIRED_KEYS:
        if key not in data:
            raise CheckpointError(f"checkpoint {path} lacks '{key}'")
    if type(data["iter"]) is not int or data["iter"] < 0:
        raise CheckpointError(f"checkpoint {path}: 'iter' must be an iteration >= 0, got {data['iter']!r}")
    rename_run_state(data)
    data["path"] = str(path)
    return data


def rename_run_state(data: dict) -> dict:
    """`data`, a checkpoint, with its envs' running state in the classes and fields the envs hold
    (`RENAMED_RUN_STATE`, by the checkpoint's task), changed in place; one without running state (a
    policy checkpoint) stays as it is."""
    env_state = data.get("env_state")
    run = env_state.get("run") if isinstance(env_state, dict) else None
    attrs = run.get("attrs") if isinstance(run, dict) else None
    if not isinstance(attrs, dict):
        return data
    config = data.get("config")
    task = config.get("task", "moving_platform") if isinstance(config, dict) else None  # TrainCfg's default
    for name, rules in RENAMED_RUN_STATE.get(task, {}).items():
        saved = attrs.get(name)
        for former, now, fields, dropped in rules:
            if (
                isinstance(saved, dict)
                and saved.get("class") == former
                and isinstance(saved.get("fields"), dict)
            ):
                kept = {fields.get(k, k): v for k, v in saved["fields"].items() if k not in dropped}
                saved = attrs[name] = {**saved, "class": now, "fields": kept}
    return data


def _check_format(data, path) -> None:
    """Refuse what is not a lasmp checkpoint, and a newer one as newer (update lasmp), not as none."""
    fmt = data.get("format") if isinstance(data, dict) else None
    if fmt == CHECKPOINT_FORMAT:
        return
    m = re.fullmatch(r"lasmp-checkpoint-v(\d+)", fmt) if isinstance(fmt, str) else None
    if m and int(m.group(1)) > CHECKPOINT_VERSION:
        raise CheckpointError(
            f"checkpoint {path} is of format '{fmt}', newer than this code, which reads "
            f"'{CHECKPOINT_FORMAT}': update lasmp (git pull, or pip install -U) to read it"
        )
    got = f"format {fmt!r}" if fmt is not None else "no format"
    raise CheckpointError(f"{path} is not a lasmp checkpoint ({got}; this code reads '{CHECKPOINT_FORMAT}')")


def convert_trusted(src: str | Path, dst: str | Path, force: bool = False) -> Path:
    """Rewrite a checkpoint of an older lasmp (pickled running state) in today's plain format. This
    UNPICKLES `src`, which runs whatever code it holds: only for a file the user trusts (the CLI
    asks for --trust). `dst` is checked (extension, a writable directory) and claimed (`claim_output`:
    an existing file only with `force`) before `src` is read."""
    from lasmp.io.plainstate import PlainStateError, pack

    src = checkpoint_file(src)
    why = _not_torch(src)
    if why is not None:
        raise CheckpointError(f"{src} is not a PyTorch checkpoint ({why}): there is nothing to convert")
    if src.resolve() == Path(dst).resolve():
        raise CheckpointError(f"convert writes a new file: OUT must differ from IN ({src})")
    dst = _out_file(dst)
    with _claim(dst, force, src):
        try:
            data = torch.load(src, map_location="cpu", weights_only=False)
        except Exception as err:
            raise CheckpointError(f"checkpoint {src} is unreadable: {err}") from err
        _check_format(data, src)
        run = (data.get("env_state") or {}).get("run")
        if run is not None and run.get("format") != PLAIN_RUN_STATE_FORMAT:  # plain already: kept as it is
            try:
                run.update(format=PLAIN_RUN_STATE_FORMAT, sim=pack(run["sim"]), attrs=pack(run["attrs"]))
            except (PlainStateError, KeyError, TypeError) as err:
                raise CheckpointError(
                    f"checkpoint {src}: its running state cannot be converted: {err}"
                ) from None
        rename_run_state(data)
        data.pop("path", None)
        atomic_torch_save(data, dst)
    read_checkpoint(dst)  # the result must load safely
    return dst


def _out_file(dst: str | Path) -> Path:
    """`dst` as a checkpoint file the tool may write (lasmp.io.inputs.check_out_file: its extension, not a
    directory, a writable directory), as CheckpointError. A file already there is `_claim`'s to refuse."""
    try:
        return check_out_file(dst, suffixes=CHECKPOINT_SUFFIXES, force=True, option="OUT")
    except InputError as err:
        raise CheckpointError(str(err)) from None


def _claim(dst: Path, force: bool, src: Path | None = None) -> contextlib.ExitStack:
    """`with _claim(dst, force, src): <read src, write dst atomically>`: `dst` claimed for this run
    before the work (`lasmp.io.atomic.claim_output`, create-exclusive), so an existing file, or one
    another run claimed meanwhile, is refused without `force`: a CheckpointError saying what the file
    is (`src` itself, a full or a policy checkpoint), naming OUT and --force. The claim is removed
    when the block fails before writing."""
    claims = contextlib.ExitStack()
    try:
        claims.enter_context(claim_output(dst, force=force, option="OUT"))
    except OutputExistsError:
        if src is not None and dst.resolve() == src.resolve():
            what = (
                "is the checkpoint it is made from: writing over it would drop its optimizers' states "
                "and running state, so that the run could no longer be resumed"
            )
        else:
            what = f"already exists ({_kind_of(dst)})"
        raise CheckpointError(f"{dst} {what}: choose another OUT, or pass --force to overwrite it") from None
    return claims


def atomic_torch_save(obj, path: str | Path) -> None:
    """torch.save to `path` atomically; a full disk is an AtomicWriteError naming `path` (lasmp.io.atomic
    finds the OSError behind torch's RuntimeError)."""
    with atomic_open(path) as f:
        torch.save(obj, f)


def check_compatible(data: dict, env) -> None:
    """Refuse a checkpoint whose observation layout or action size differs from the env's."""
    have = obs_layout(env.get_observations())
    want = data["obs_layout"]
    for group in sorted(set(have) | set(want)):
        if have.get(group) != want.get(group):
            raise CheckpointError(
                f"checkpoint {data.get('path', '')} was trained with observation group '{group}' of shape "
                f"{want.get(group)}, but this env gives {have.get(group)}"
            )
    if int(data["num_actions"]) != env.num_actions:
        raise CheckpointError(f"checkpoint has {data['num_actions']} actions, the env {env.num_actions}")


@contextmanager
def not_fitting(what: str):
    """Errors of restoring a checkpoint that passed `read_checkpoint` but does not fit (a shape, a key,
    a value) as one CheckpointError naming `what`."""
    try:
        yield
    except CheckpointError:
        raise
    except (RuntimeError, ValueError, KeyError, TypeError, IndexError) as err:
        raise CheckpointError(f"checkpoint {what}: {err}") from err


def check_finite(state_dicts: dict, where: str) -> None:
    """Raise if any floating tensor in the (nested) state dicts is non-finite, naming the first one."""

    def walk(obj, name):
        if isinstance(obj, torch.Tensor):
            if obj.is_floating_point() and not torch.isfinite(obj).all():
                raise FloatingPointError(f"{where}: non-finite values in {name}")
        elif isinstance(obj, dict):
            for key, value in obj.items():
                walk(value, f"{name}.{key}" if name else str(key))
        elif isinstance(obj, (list, tuple)):
            for i, value in enumerate(obj):
                walk(value, f"{name}[{i}]")

    walk(state_dicts, "")


def rng_state(env_rng: np.random.Generator) -> dict:
    """torch's CPU (and CUDA, if any) and the env's numpy random states."""
    state = {"torch": torch.get_rng_state(), "numpy_env": env_rng.bit_generator.state}
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        state["torch_cuda"] = torch.cuda.get_rng_state_all()
    return state


def set_rng_state(state: dict, env_rng: np.random.Generator) -> None:
    """Restore `rng_state` output (torch CPU, CUDA where saved and present, the env's numpy stream)."""
    torch.set_rng_state(state["torch"])
    if "torch_cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["torch_cuda"])
    env_rng.bit_generator.state = state["numpy_env"]


OPTIMIZER_KEYS = ("optimizer_state_dict", "estimator_optimizer_state_dict", "rnd_optimizer_state_dict")


def is_policy_only(data: dict) -> bool:
    """True for a policy checkpoint: networks without optimizer states (cannot resume training)."""
    return data.get("kind") == "policy" or "optimizer_state_dict" not in data


def _kind_of(path: Path) -> str:
    """What an existing file is, in a few words, for a refusal to overwrite it."""
    if path.is_dir():
        return "a directory"
    try:
        return "a policy checkpoint" if is_policy_only(read_checkpoint(path)) else "a full checkpoint"
    except CheckpointError:
        return "not a lasmp checkpoint"
