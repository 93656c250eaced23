"""A training, as `train.py` runs it: check the config, check a resume or warm start whole, check the
machine, claim the run directory, build (`lasmp.cli.build`), restore, learn, say how it ended.

Run directories (`lasmp.io.rundir`): a training locks its directory; a new run is refused a directory
that holds a run. A resume (`resume=`) continues a run as `lasmp.cli.resume` decides.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from omegaconf import OmegaConf

from lasmp.algo import distributed as dp
from lasmp.algo.checkpoint import CheckpointError
from lasmp.algo.runner import LasmpRunner
from lasmp.algo.stopping import TrainingFaulted, TrainingInterrupted
from lasmp.cli.build import make_runner
from lasmp.cli.command_line import explicit_keys, resume_command
from lasmp.cli.preflight import training_environment_error
from lasmp.cli.resources import check_disk_space
from lasmp.cli.resume import Resume, check_run_dir
from lasmp.cli.run_directory import config_header, default_log_dir, finished_message, remove_failed_start
from lasmp.cli.train_failures import RankLost, named, quiet_writer_threads
from lasmp.cli.warm_start import WarmStart
from lasmp.config.checks import ConfigError
from lasmp.config.recipe import run_label
from lasmp.config.train import to_train_cfg
from lasmp.envs.trajectories import TrajectoryFileError
from lasmp.io.atomic import atomic_open
from lasmp.io.errors import ErrorTable, run
from lasmp.io.rundir import RunDirError, claim


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
        # the env's memory is checked before its envs' data are allocated (`lasmp.cli.build.make_env`)
        processes = dp.local_world_size() if ranks.distributed else 1
        runner = make_runner(cfg, str(log_dir) if ranks.is_main else None, ranks.rank, processes)
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
                        + OmegaConf.to_yaml(runner.full_config)  # to_plain(cfg), as the checkpoints keep it
                    )
            jobs = f" x {ranks.world_size} processes" if ranks.distributed else ""
            span = f" ({first}\u2013{last})" if cfg.runner.max_iterations else ""
            say(
                f"training {cfg.task} / {run_label(cfg)}: {cfg.env.num_envs} envs{jobs}, {cfg.runner.max_iterations} "
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
                raise named(err, runner, log_dir) from err
            except RuntimeError as err:
                if ranks.distributed and dp.is_peer_lost(err):
                    raise RankLost(
                        ranks.rank, ranks.world_size, log_dir, last, runner.current_learning_iteration
                    ) from err
                raise
            say(finished_message(log_dir), flush=True)
        except BaseException:
            if ranks.is_main and not continuing:
                remove_failed_start(log_dir, there_before)
            raise
    return runner


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
