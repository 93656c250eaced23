"""Checkpoint files: writing, reading, compatibility checks, the latest one of a run.

A checkpoint (format "lasmp-checkpoint-v1") is a dict saved with `torch.save` that holds only tensors,
numbers, strings and plain containers, and is read with `torch.load(weights_only=True)`: loading a
file from elsewhere never runs code (the env's running state is stored by `lasmp.io.plainstate`):
- the learner's state (`LasmpRunner.save`: all networks with their normalizers, both optimizers);
- `iter`: the last *completed* iteration (a resume continues at iter + 1);
- `config`: the resolved TrainCfg as a plain dict (`lasmp.config.checkpoint` rebuilds it); `obs_layout`
  and `num_actions`;
- `env_state`: the env's own state: the curriculum's level and window, and under "run" every env's
  running state (physics, per-env model fields, buffers, trajectories, intrinsics), so that a
  resume continues bit for bit (older checkpoints lack "run": their envs restart their episodes);
- `rng_state`: torch's and the env's numpy random states at the save, so that a resume continues
  the random streams instead of replaying them from the seed (optional: older checkpoints lack it).
A *policy checkpoint* (`policy_checkpoint`, `kind` = "policy") is the same file without the
optimizers' states and the envs' running state: a few MB that play.py and evaluate.py load, and
train.py refuses to resume.
In a run directory a full checkpoint is `model_<N>.pt` and a policy checkpoint `policy_<N>.pt`, N the
iteration saved; training keeps the newest `runner.keep_full` full ones and turns older ones into
policy ones (`keep_newest_full`). A run directory given to play or evaluate means its newest
checkpoint of either kind, given to a resume its newest full one (`latest_checkpoint`).
It is written to a temporary file in the same directory and renamed over the target
(`atomic_torch_save`), so an interrupted save never leaves a truncated checkpoint behind.
Every command reads one through `read_checkpoint`: only a regular file (a FIFO would hang it), and
only one that begins as a PyTorch checkpoint (an ONNX model, a text or .npz file is named for what
it is); a checkpoint of a newer format than CHECKPOINT_VERSION says to update lasmp. Running state
that names a class or a field otherwise than the envs do reads back renamed (`RENAMED_RUN_STATE`).

The package: format.py (the file: written, read, checked), forms.py (full and policy checkpoints, a run
directory's full ones), cli.py (`python -m lasmp.algo.checkpoint`); it re-exports what its users read.
"""

from lasmp.algo.checkpoint.cli import main
from lasmp.algo.checkpoint.format import (
    CHECKPOINT_FORMAT,
    CHECKPOINT_SUFFIXES,
    CHECKPOINT_VERSION,
    OPTIMIZER_KEYS,
    PLAIN_RUN_STATE_FORMAT,
    RENAMED_RUN_STATE,
    REQUIRED_KEYS,
    CheckpointError,
    atomic_torch_save,
    check_compatible,
    check_finite,
    checkpoint_file,
    convert_trusted,
    is_policy_only,
    latest_checkpoint,
    not_fitting,
    obs_layout,
    read_checkpoint,
    rename_run_state,
    rng_state,
    set_rng_state,
)
from lasmp.algo.checkpoint.forms import (
    keep_newest_full,
    learning_rates,
    policy_checkpoint,
    policy_only,
    refuse_policy_only,
)

__all__ = [
    "CHECKPOINT_FORMAT",
    "CHECKPOINT_SUFFIXES",
    "CHECKPOINT_VERSION",
    "CheckpointError",
    "OPTIMIZER_KEYS",
    "PLAIN_RUN_STATE_FORMAT",
    "RENAMED_RUN_STATE",
    "REQUIRED_KEYS",
    "atomic_torch_save",
    "check_compatible",
    "check_finite",
    "checkpoint_file",
    "convert_trusted",
    "is_policy_only",
    "keep_newest_full",
    "latest_checkpoint",
    "learning_rates",
    "main",
    "not_fitting",
    "obs_layout",
    "policy_checkpoint",
    "policy_only",
    "read_checkpoint",
    "refuse_policy_only",
    "rename_run_state",
    "rng_state",
    "set_rng_state",
]
