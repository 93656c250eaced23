"""Build the env, the runner and train: the logic behind `train.py`.

Run directories (`lasmp.io.rundir`): a training locks its directory; a new run is refused a directory
that holds a run. A resume (`resume=`) continues a run as `lasmp.cli.resume` decides.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import os
import shlex
import shutil
import threading
from pathlib import Path

import torch
from omegaconf import OmegaConf

from lasmp.algo import distributed as dp
from lasmp.algo.checkpoint import CheckpointError
from lasmp.algo.runner import LasmpRunner
from lasmp.algo.stopping import TrainingFaulted, TrainingInterrupted
from lasmp.cli.command_line import explicit_keys, resume_command
from lasmp.cli.preflight import training_environment_error
from lasmp.cli.resources import check_disk_space, check_memory
from lasmp.cli.resume import Resume, check_run_dir
from lasmp.cli.warm_start import WarmStart
from lasmp.compat.rsl_rl import raised_storing_code_state
from lasmp.compat.tensorboard import events_file, is_writer_thread, raised_in_tensorboard, writer_thread_error
from lasmp.config.base import ConfigError
from lasmp.config.recipe import run_label, run_slug
from lasmp.config.train import TrainCfg, rsl_rl_cfg, to_plain, to_train_cfg
from lasmp.envs import registry
from lasmp.envs.trajectories import TrajectoryFileError
from lasmp.io.atomic import AtomicWriteError, atomic_open
from lasmp.io.errors import ErrorTable, run
from lasmp.io.inputs import SEED_MAX
from lasmp.io.rundir import RunDirError, claim, run_checkpoints


def seed_everything(seed: int) -> None:
    torch.manual_seed(seed)


def make_env(cfg: TrainCfg):
    """The task's env (`lasmp.envs.registry`), its tensors where its physics runs (cpu backend: the CPU,
    even with the learner on a GPU; warp: `cfg.device`)."""
    return registry.make_env(cfg.task, cfg.env, cfg.device)


def make_runner(cfg: TrainCfg, log_dir: str | None, rank: int = 0) -> LasmpRunner:
    """The env and the runner of `cfg`; in a data-parallel job, rank k's envs and torch streams are
    seeded with seed + k (its own physics, trajectories and curriculum draws); the saved config keeps
    the job's seed."""
    if cfg.device.startswith("cuda") and not torch.cuda.is_available():
        raise ConfigError(
            f"device={cfg.device} but torch sees no CUDA device (install a CUDA build of torch)"
        )
    if cfg.torch_threads > 0:
        torch.set_num_threads(cfg.torch_threads)
    seed = (cfg.seed + rank) % (SEED_MAX + 1)  # a seed near 2**32 - 1 stays a valid seed on every rank
    seed_everything(seed)
    env = make_env(
        cfg if rank == 0 else dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, seed=seed))
    )
    full_config = to_plain(cfg)
    return LasmpRunner(
        env,
        rsl_rl_cfg(cfg),
        log_dir=log_dir,
        device=cfg.device,
        full_config=full_config,
        max_fault_fraction=cfg.runner.max_fault_fraction,
        keep_full=cfg.runner.keep_full,
        validator=make_validator(cfg, full_config) if rank == 0 else None,
        validation_interval=cfg.runner.validation_interval,
    )


def make_validator(cfg: TrainCfg, full_config: dict):
    """The in-training validator of a moving-platform run (None when validation is off, or for another
    task: the validation benchmark is the moving platform's)."""
    if cfg.runner.validation_interval == 0 or cfg.task != "moving_platform":
        return None
    from lasmp.eval.validation import Validator

    return Validator(full_config, cfg.runner.validation_episodes)


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


def train(cfg, explicit: set[str] | None = None) -> LasmpRunner:
    """Train as `cfg` says: build, resume (`lasmp.cli.resume`), learn. `explicit`: on resume, the keys
    the command line set (None: every key of `cfg`)."""
    cfg = to_train_cfg(cfg)
    # a resume or a warm start, checked whole: it fails before anything is built
    start = WarmStart.check(cfg, explicit) if cfg.warm_start else None
    resume = Resume.check(cfg, explicit) if cfg.resume and not start else None
    cfg = resume.cfg if resume else start.cfg if start else cfg
    # what this machine must bring (a W&B login, MuJoCo Warp), checked before any env is built
    missing = training_environment_error(cfg)
    if missing:
        raise ConfigError(missing)
    ranks = dp.ranks_from_env()  # torchrun: rank 0 alone holds the run directory, logs and saves
    # an env.num_envs that cannot fit, refused before any allocation
    check_memory(cfg, dp.local_world_size() if ranks.distributed else 1)
    if ranks.distributed:
        cfg.device = dp.rank_device(cfg.device, ranks)
        dp.setup(ranks, cfg.device)
    data = resume.data if resume else None
    log_dir = Path(cfg.runner.log_dir or (Path(data["path"]).parent if data else default_log_dir(cfg)))
    if ranks.distributed:  # every rank knows rank 0's run directory: the one that outlives the other says it
        log_dir = Path(dp.broadcast_from_main(str(log_dir)))
    continuing = data is not None and Path(data["path"]).parent.resolve() == log_dir.resolve()
    owner = claim(log_dir, check_run_dir(log_dir, data)) if ranks.is_main else contextlib.nullcontext()
    say = print if ranks.is_main else (lambda *a, **k: None)
    with owner:
        runner = make_runner(cfg, str(log_dir) if ranks.is_main else None, ranks.rank)
        for restoring in (resume, start):
            if restoring:
                restoring.restore(runner, say)
        first = runner.current_learning_iteration
        last = first + cfg.runner.max_iterations - 1  # the iteration this command ends at
        if ranks.is_main:  # the first checkpoint must fit on the disk before anything is written
            check_disk_space(runner, log_dir)
        there_before = set(os.listdir(log_dir)) if ranks.is_main else set()
        try:
            if ranks.is_main:  # only now, with everything checked, the run directory's config
                with atomic_open(log_dir / "config.yaml", "w") as f:
                    f.write(
                        config_header(first, last, "a warm start" if start else "a resume")
                        + OmegaConf.to_yaml(to_plain(cfg))
                    )
            processes = f" x {ranks.world_size} processes" if ranks.distributed else ""
            span = f" ({first}\u2013{last})" if cfg.runner.max_iterations else ""
            say(
                f"training {cfg.task} / {run_label(cfg)}: {cfg.env.num_envs} envs{processes}, {cfg.runner.max_iterations} "
                f"iterations{span}, logs in {log_dir}",
                flush=True,
            )
            try:
                runner.learn(cfg.runner.max_iterations)
            except TrainingInterrupted as stop:
                if stop.checkpoint:
                    # on a resume, runner.max_iterations counts the iterations still to run: those left
                    left = last - stop.iteration
                    print(
                        f"{stop}\nresume with:\n  {resume_command(stop.checkpoint, str(log_dir), left)}",
                        flush=True,
                    )
                else:  # stopped before any iteration completed (the reason is in the message)
                    say(str(stop), flush=True)
                raise
            except OSError as err:
                raise _named(err, runner, log_dir) from err
            except RuntimeError as err:
                if ranks.distributed and dp.is_peer_lost(err):
                    raise RankLost(
                        ranks.rank, ranks.world_size, log_dir, last, runner.current_learning_iteration
                    ) from err
                raise
            say(finished_message(log_dir), flush=True)
        except BaseException:
            if ranks.is_main and not continuing:
                _remove_failed_start(log_dir, there_before)
            raise
    return runner


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


class RankLost(RuntimeError):
    """A rank of a torchrun job lost the others (one was killed, ran out of memory or crashed): the
    message says so, names the run's newest checkpoint and the command that resumes from it."""

    def __init__(self, rank: int, world_size: int, log_dir: Path, last: int, iteration: int):
        saved = run_checkpoints(log_dir, full_only=True) if log_dir.is_dir() else {}
        head = (
            f"rank {rank} of the torchrun job lost the connection to the other processes (one of them ended: "
            "killed, out of memory or crashed, see its own output); this one stops too"
        )
        if saved:
            n, newest = next(reversed(saved.items()))
            command = resume_command(str(newest), str(log_dir), last - n).replace(
                "python train.py", f"torchrun --nproc_per_node={world_size} train.py", 1
            )
            tail = f". The newest checkpoint is {newest} (iteration {n}); resume with:\n  {command}"
        else:
            tail = f". No checkpoint was saved in {log_dir} (iteration {iteration} was under way): start the run anew"
        super().__init__(head + tail)


def _named(err: OSError, runner: LasmpRunner, log_dir: Path) -> OSError:
    """A write error of training as one that names its file. The saves name theirs
    (`AtomicWriteError`); rsl_rl's git diff and TensorBoard's events file raise a bare OSError,
    without a file name, from their writes, or (TensorBoard reopens its events file for each append)
    one that names the events file in bytes."""
    writer = runner.logger.writer
    events = events_file(writer)
    if err.filename is not None:
        named_events = events is not None and os.fsdecode(err.filename) == os.fsdecode(events)
        return AtomicWriteError(Path(os.fsdecode(events)), err) if named_events else err
    if raised_storing_code_state(err):
        where = log_dir / "git"  # rsl_rl's record of the code's state: git/<repository>.diff
    elif events is not None and (err is writer_thread_error(writer) or raised_in_tensorboard(err)):
        where = Path(events)
    else:
        where = log_dir
    return AtomicWriteError(where, err)


# what a failed start of a new run may have written: they are removed when it saved no checkpoint
START_FILES = ("config.yaml", "git")
EVENTS_PREFIX = "events.out.tfevents."


def _remove_failed_start(log_dir: Path, there_before: set[str]) -> None:
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


# what a user can meet, each said in one line (`lasmp.io.errors`)
ERRORS = ErrorTable(
    bad_input=(CheckpointError, ConfigError, RunDirError, TrajectoryFileError),
    cannot_go_on=(TrainingFaulted, FloatingPointError, OSError, RankLost),
    stopped=(TrainingInterrupted,),  # its checkpoint and the resume command are said
    interrupted="interrupted before training started: nothing saved",  # later, the runner saves and says so
)


def main(cfg, overrides: list[str] | None = None) -> int:
    """Train `cfg`, composed from `overrides` (the command line's, `lasmp.cli.command_line`); return the
    exit code (`ERRORS`). A resume or warm start takes the keys `overrides` set on top of its checkpoint's."""

    def work() -> None:
        starting_from = getattr(cfg, "resume", None) or getattr(cfg, "warm_start", None)
        explicit = explicit_keys(overrides) if starting_from and overrides is not None else None
        with quiet_writer_threads():
            train(cfg, explicit)

    return run(work, ERRORS, on_exit=dp.teardown)  # after a lost rank the teardown may fail: said never


@contextlib.contextmanager
def quiet_writer_threads():
    """TensorBoard writes its events file from a thread; on a full or read-only disk that thread dies
    printing a traceback, and the main thread raises the same error at its next write, where train()
    names the file (`_named`). Its traceback is left out; any other thread's is printed as usual."""
    previous = threading.excepthook

    def hook(args):
        if not (issubclass(args.exc_type, OSError) and is_writer_thread(args.thread)):
            previous(args)

    threading.excepthook = hook
    try:
        yield
    finally:
        threading.excepthook = previous
