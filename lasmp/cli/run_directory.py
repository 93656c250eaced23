"""A training's run directory, as the story in `lasmp.cli.train` writes it: its default name, the
header of its config.yaml, the message a finished training ends with, and a failed start's removal
(the directory locks and checkpoints themselves: `lasmp.io.rundir`)."""

from __future__ import annotations

import contextlib
import datetime
import os
import shlex
import shutil
from pathlib import Path

from lasmp.config.recipe import run_slug
from lasmp.config.train import TrainCfg
from lasmp.io.rundir import run_checkpoints


def default_log_dir(cfg: TrainCfg) -> str:
    """logs/<task>/<recipe>[-<policy>]/<date_time> (`lasmp.config.recipe.run_slug`: lasmp_plus, lasmp_paper,
    lasmp_plus-no_alignment_command; rough_static: rs), unique per job: a Hydra multirun's job adds its number
    (`-m seed=1,2,3` starts its jobs within one second), and a name already taken (two starts in the
    same second) gets the first free suffix `-2`, `-3`, ... Two processes that pick one name at the
    same instant still meet `claim`'s lock, and the second is refused naming the first."""
    stamp = datetime.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
    job = _multirun_job()
    base = os.path.join("logs", cfg.task, run_slug(cfg), stamp + (f"_job{job}" if job is not None else ""))
    path, n = base, 1
    while os.path.lexists(path):
        n += 1
        path = f"{base}-{n}"
    return path


def _multirun_job() -> int | None:
    """The job's number in a Hydra multirun (`train.py -m ...`); None in a single run."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    if not HydraConfig.initialized():
        return None
    hydra_cfg = HydraConfig.get()
    return hydra_cfg.job.num if hydra_cfg.mode == RunMode.MULTIRUN else None


def config_header(first: int, last: int, how: str = "a resume") -> str:
    """config.yaml's first lines: which iterations the command that wrote it trained. Why: on a resume
    `runner.max_iterations` holds the iterations that command added (930 after 70), and read alone it
    looks like the run's length."""
    if first == 0:
        return ""
    return (
        f"# written by {how}: this command trained iterations {first}\u2013{last}, so the run holds "
        f"{last + 1} in all;\n# runner.max_iterations below counts the iterations it added, not the run's length\n"
    )


def finished_message(log_dir: Path) -> str:
    """What a finished training prints last: its newest checkpoint and the commands that play and
    evaluate it, as the Ctrl-C path names its checkpoint and the resume command."""
    saved = run_checkpoints(log_dir)
    if not saved:
        return f"finished: no checkpoint was saved in {log_dir}"
    n, newest = next(reversed(saved.items()))
    path = shlex.quote(str(newest))
    return (
        f"finished: the last checkpoint is {newest} (iteration {n})\n"
        f"play it:     python play.py --checkpoint {path} --video episode.mp4\n"
        f"evaluate it: python evaluate.py --checkpoint {path}"
    )


# what a failed start of a new run may have written: they are removed when it saved no checkpoint
START_FILES = ("config.yaml", "git")
EVENTS_PREFIX = "events.out.tfevents."


def remove_failed_start(log_dir: Path, there_before: set[str]) -> None:
    """A new run (or a branch) that ends in an error before its first checkpoint leaves nothing:
    it could not be resumed, and its config.yaml would make the rerun refuse the directory as one
    that holds a run. Only what this start wrote goes (config.yaml, rsl_rl's git/, TensorBoard's
    events); a failure of the removal never replaces the error that ended the run."""
    if not log_dir.is_dir() or run_checkpoints(log_dir):
        return
    for name in set(os.listdir(log_dir)) - there_before:
        if name in START_FILES or name.startswith(EVENTS_PREFIX):
            path = log_dir / name
            with contextlib.suppress(OSError):
                shutil.rmtree(path) if path.is_dir() and not path.is_symlink() else path.unlink()
