"""Training runner: rsl_rl's `OnPolicyRunner` with complete, atomic, checked checkpoints (see
`lasmp.algo.checkpoint`), a fault guard and safe interruption.

- Divergence: the learner's update raises `FloatingPointError` on a non-finite loss or parameter
  (`PPOROA`'s guard), and `save` refuses to write a non-finite checkpoint, so the last good one stays.
- Faults: each iteration counts the env-steps whose physics faulted (the env's `fault_count`; the
  progress line shows them); more than `max_fault_fraction` of an iteration's env-steps raises
  `TrainingFaulted` during its rollout, before its update, naming the cause.
- Interruption: SIGINT (Ctrl-C) or SIGTERM during `learn` stops it within one env-step and raises
  `TrainingInterrupted` (the caller prints the resume command). Signalled during an update (or in a
  torchrun job, whose ranks can only agree at an iteration's end), the iteration finishes and
  `model_<it>.pt` is written: its resume is exact. Signalled during a rollout, the rollout is
  abandoned (no update has used it) and the state of the last completed iteration `it - 1` is kept:
  where `model_<it-1>.pt` is in the run directory already, it is the checkpoint (exact, nothing is
  written); otherwise `model_<it-1>.pt` is written with the networks and optimizers of iteration
  `it - 1` and the envs' state of the moment the rollout stopped, marked `abandoned_rollout`: the
  resume says that it is not exact (the envs had run some steps of iteration `it`, and the observation
  normalizers, if any, had seen them). Before any iteration completed nothing is saved. A second
  signal ends the process at once with 128 + signal (130 / 143) and one line, without a checkpoint
  (`_exit_now`). A rank of
  a torchrun job that leaves `learn` on an exception ignores both signals from then on: the process
  is ending, and its report must not be cut by torchrun's agent terminating the ranks left.
- Where the fault guard and the interruption fire: inside rsl_rl's `OnPolicyRunner.learn`, from
  its logger (`OneLineLogger`).
  The loop calls `logger.process_env_step` after every env-step of a rollout (then `_check_faults`)
  and `logger.log` after every update (then `_after_iteration`, which saves and raises on a signal,
  before rsl_rl's own save of that iteration). These are the loop's only calls, per step and per
  iteration, into an object the runner chooses; rsl_rl offers no hook, and overriding `learn`
  would copy its loop.
- Validation (ours): after every `validation_interval`-th iteration (its number + 1 a multiple), a
  validator (built by the caller: `lasmp.eval.validation.Validator`) scores the current actor on the
  validation benchmark. The runner logs `Val/*` (TensorBoard and a console line), rewrites the run's
  `validation.json` (every score with its env-steps and wall-clock seconds, and the best) and keeps
  `policy_best.pt`, the policy checkpoint of the best score (the lowest collision rate, the height
  violation the tie-break), rewritten only on an improvement. The scores and the best travel in every
  checkpoint, so a resume goes on from the best so far.
- Disk: after each save into the run directory the newest `keep_full` full checkpoints stay, older
  ones become policy checkpoints (`keep_newest_full`), and a line names them.
- Console (`lasmp.algo.console`): one line per network instead of rsl_rl's printout of every layer,
  then one progress line per iteration.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np
import torch

from lasmp.algo import distributed as dp
from lasmp.algo.checkpoint import (
    CHECKPOINT_FORMAT,
    CheckpointError,
    atomic_torch_save,
    check_compatible,
    check_finite,
    keep_newest_full,
    not_fitting,
    obs_layout,
    policy_only,
    read_checkpoint,
    refuse_policy_only,
    rng_state,
    set_rng_state,
)
from lasmp.algo.console import OneLineLogger, network_line, without_network_printout
from lasmp.atomic import atomic_open
from lasmp.rsl_compat import OnPolicyRunnerCompat

INTERRUPT_SIGNALS = (signal.SIGINT, signal.SIGTERM)
BEST_POLICY = "policy_best.pt"  # the run's policy of the best validation score
VALIDATION_FILE = "validation.json"  # the run's validation curve


def _array_bytes(obj, seen: set[int] | None = None) -> int:
    """The bytes of the tensors and numpy arrays in a nested structure of dicts, lists and tuples;
    a tensor storage shared by several entries counts once, as torch.save writes it once."""
    seen = set() if seen is None else seen
    if isinstance(obj, torch.Tensor):
        storage = obj.untyped_storage()
        if storage.data_ptr() in seen:
            return 0
        seen.add(storage.data_ptr())
        return storage.nbytes()
    if isinstance(obj, np.ndarray):
        return obj.nbytes
    if isinstance(obj, dict):
        return sum(_array_bytes(v, seen) for v in obj.values())
    if isinstance(obj, (list, tuple)):
        return sum(_array_bytes(v, seen) for v in obj)
    return 0


class TrainingInterrupted(Exception):
    """Training stopped on a signal after iteration `iteration` (-1: none completed), saved to
    `checkpoint` (None: nothing saved); `how` replaces the default account of what was kept."""

    def __init__(self, signum: int, iteration: int, checkpoint: str | None, how: str | None = None):
        self.signum, self.iteration, self.checkpoint = signum, iteration, checkpoint
        name = signal.Signals(signum).name
        default = f", saved {checkpoint}" if checkpoint else " (no log_dir: nothing saved)"
        super().__init__(f"{name} received: stopped after iteration {iteration}" + (how or default))


class _RolloutAbandoned(Exception):
    """Raised from the rollout loop (after an env-step) when a stop was asked for: caught by `learn`."""


class TrainingFaulted(RuntimeError):
    """Too many of an iteration's env-steps faulted (the physics diverged); the message says how many."""


class LasmpRunner(OnPolicyRunnerCompat):
    """`OnPolicyRunner` + checkpoints with config, layout, env and random state; fault guard;
    checkpoint on SIGINT / SIGTERM."""

    def __init__(
        self,
        env,
        train_cfg: dict,
        log_dir: str | None,
        device: str = "cpu",
        full_config: dict | None = None,
        max_fault_fraction: float = 0.5,
        keep_full: int = 2,
        validator=None,
        validation_interval: int = 0,
    ):
        """`validator(iteration, actor_state_dict, obs_layout, num_actions)` -> a score with `key()`
        (lower is better) and plain fields; called every `validation_interval` iterations (0: never)."""
        with without_network_printout(lambda: getattr(self, "alg", None)):
            super().__init__(env, train_cfg, log_dir=log_dir, device=device)
        if self.gpu_global_rank == 0:
            obs = env.get_observations()
            print(network_line("actor", self.alg.get_policy(), obs), flush=True)
            print(network_line("critic", self.alg.critic, obs), flush=True)
        self.full_config = full_config or {}
        self.max_fault_fraction = max_fault_fraction
        self.keep_full = keep_full
        self._faults_before = 0  # env.fault_count when the iteration under way began
        self.logger = OneLineLogger(
            log_dir=log_dir,
            cfg=self.cfg,
            env_cfg=env.cfg,
            num_envs=env.num_envs,
            is_distributed=self.is_distributed,
            gpu_world_size=self.gpu_world_size,
            gpu_global_rank=self.gpu_global_rank,
            device=self.device,
        )
        self._final_iteration = -1  # the last iteration of the current learn()
        self._other_ranks: list | None = None  # rank 0: the other ranks' running state for the next save
        self.logger.step_done = self._check_faults
        self.logger.iteration_done = self._after_iteration
        self._signal: int | None = None
        self._under_way = 0  # the iteration whose rollout or update is under way
        self._rollout_steps = 0  # the env-steps of its rollout so far
        self._abandoned: dict | None = None  # while saving at a rollout's stop: which rollout, how far
        self.validator = validator
        self.validation_interval = validation_interval if validator is not None else 0
        self.validation_history: list[dict] = []  # every score of the run, resumes included
        self.validation_best: dict | None = None  # the best score so far (its record)
        self._wall_before_s = 0.0  # the run's training seconds before this command (from its checkpoint)
        self._learn_start_s: float | None = None

    # -- data-parallel training (lasmp.algo.distributed) -------------------------------------------
    def configure_ranks(self) -> None:
        """rsl_rl's multi-GPU setup without its NCCL-and-CUDA assumption: gloo on a CPU, NCCL on CUDA."""
        ranks = dp.ranks_from_env()
        self.gpu_world_size, self.gpu_global_rank, self.gpu_local_rank = (
            ranks.world_size,
            ranks.rank,
            ranks.local_rank,
        )
        self.is_distributed = ranks.distributed
        self.cfg["multi_gpu"] = (
            {"global_rank": ranks.rank, "local_rank": ranks.local_rank, "world_size": ranks.world_size}
            if ranks.distributed
            else None
        )
        if ranks.distributed:
            self.device = dp.rank_device(self.device, ranks)
            dp.setup(ranks, self.device)

    def _share_iteration_end(self, it: int) -> int | None:
        """Every rank at the end of iteration `it`: one curriculum, one decision to stop (returned: the
        signal, or None), and, before a save, the other ranks' running state on rank 0."""
        if hasattr(getattr(self.env, "curriculum", None), "sync"):
            self.env.curriculum.sync()
        stop = self._agreed_signal()
        saving = stop is not None or it == self._final_iteration or it % self.cfg["save_interval"] == 0
        if saving:
            mine = {"run": self.env.state_dict()["run"], "rng_state": rng_state(self.env.rng)}
            gathered = dp.gather_to_main(mine)
            self._other_ranks = gathered[1:] if gathered is not None else None
        return stop

    def _agreed_signal(self) -> int | None:
        """The signal any rank has received, the same answer on every rank. The handler's own record
        is only read, never overwritten: a signal that lands while this rank waits in the collective
        (after it has given 0) is counted at the next iteration's end, by every rank at once, instead
        of being lost (torchrun would then kill the job without a checkpoint 30 s later)."""
        return dp.any_rank(self._signal or 0, self.device) or None

    def _this_ranks_state(self, data: dict, run: bool) -> dict:
        """A resume in a job of K ranks: rank k's envs' running state and random state from the
        checkpoint (rank 0's are its own; the others' are under `other_ranks`)."""
        others = data.get("other_ranks") or []
        if not run:
            return data
        if len(others) != self.gpu_world_size - 1:
            raise CheckpointError(
                f"{data.get('path', 'the checkpoint')} holds the running state of {len(others) + 1} process(es), "
                f"this job has {self.gpu_world_size}: give resume_drop_env_state=true to start every env's "
                "episode anew (the resume is then not exact)"
            )
        if self.gpu_global_rank == 0:
            return data
        mine = others[self.gpu_global_rank - 1]
        return {
            **data,
            "env_state": {**data["env_state"], "run": mine["run"]},
            "rng_state": mine["rng_state"],
            "episode_log_state": None,
        }

    # -- fault guard ------------------------------------------------------------------------------
    def _check_faults(self) -> None:
        """After each env-step of a rollout: count the iteration's faulted env-steps so far for the
        progress line; stop as soon as they pass the threshold (the count only grows in a rollout).
        A stop asked for (a signal) abandons the rollout here, alone (a torchrun job's ranks stop
        together at the iteration's end)."""
        self._rollout_steps += 1
        if self._signal is not None and not self.is_distributed:
            raise _RolloutAbandoned()
        count = getattr(self.env, "fault_count", None)
        if count is None:
            return
        faults = count - self._faults_before
        self.logger.iteration_faults = faults
        steps = self.cfg["num_steps_per_env"] * self.env.num_envs
        if faults > self.max_fault_fraction * steps:
            raise TrainingFaulted(
                f"physics faults: {faults:,} of the {steps:,} env-steps of iteration {self.alg.iteration} "
                f"faulted ({faults / steps:.0%}, more than runner.max_fault_fraction={self.max_fault_fraction}). The "
                "simulation diverges (MuJoCo errors or warnings, non-finite state, runaway joints): check "
                "env.sim.dt_s, env.control.action_scale, the trajectory file and the robots' parameters "
                "(runner.max_fault_fraction=1 trains on regardless). Stopped before this iteration's update; "
                "the last saved checkpoint is intact."
            )

    # -- interruption ------------------------------------------------------------------------------
    # in a torchrun job, a signal this soon after the first is its echo (torchrun forwards SIGTERM twice,
    # and a Ctrl-C reaches a rank from the terminal and from the agent); alone, every second one counts
    REPEAT_WINDOW_S = 2.0

    def _on_signal(self, signum, _frame) -> None:
        if self._signal is not None:
            if self.is_distributed and time.monotonic() - self._signal_time_s < self.REPEAT_WINDOW_S:
                return  # torchrun's echo of the first signal to every rank, not a second one
            # a second signal: stop now, without a checkpoint
            print(
                f"\n{signal.Signals(signum).name} again: stopped at once, without a checkpoint (the last "
                "saved one is intact)",
                file=sys.stderr,
                flush=True,
            )
            self._exit_now(128 + signum)
        self._signal, self._signal_time_s = signum, time.monotonic()
        print(
            f"\n{signal.Signals(signum).name}: stopping, then saving a checkpoint (send it again to abort at once)",
            flush=True,
        )

    @staticmethod
    def _exit_now(code: int) -> None:
        """End the process with `code` at once: `os._exit`, after flushing the console. Why not an
        exception (SystemExit, KeyboardInterrupt): the handler runs wherever the main thread is, and
        the most likely place for a second signal is inside torch.save of a large checkpoint, whose
        zip writer turns any exception of its Python file's write into `RuntimeError` (a traceback,
        exit 1); an `except` on the way could also catch it or add to it. `os._exit` runs no
        handler, so nothing can print after the handler's line. A checkpoint being written is left
        as its hidden temporary file (`.model_<it>.pt.*.tmp`), never under its final name (the
        write renames only a complete file); the next command that holds the run directory removes
        it (`lasmp.atomic.remove_stale_temporaries`, when `lasmp.rundir` claims the directory)."""
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # a closed or broken console must not keep the process alive
                pass
        os._exit(code)

    # -- validation -------------------------------------------------------------------------------
    def wall_s(self) -> float:
        """The run's training seconds so far: its earlier commands' (from the checkpoint) and this one's."""
        now = 0.0 if self._learn_start_s is None else time.perf_counter() - self._learn_start_s
        return self._wall_before_s + now

    def _validate_if_due(self, it: int) -> None:
        """Score the policy of iteration `it` when due; log it, record it, keep the best policy."""
        interval = self.validation_interval
        if interval <= 0 or (it + 1) % interval:
            return
        score = self.validator(
            it, self.alg.actor.state_dict(), obs_layout(self.env.get_observations()), self.env.num_actions
        )
        env_steps = (it + 1) * self.cfg["num_steps_per_env"] * self.env.num_envs * self.gpu_world_size
        record = {**dataclasses.asdict(score), "env_steps": env_steps, "wall_s": round(self.wall_s(), 3)}
        improved = self.validation_best is None or score.key() < tuple(
            self.validation_best[k] for k in ("collision_rate", "height_violation_rate")
        )
        self.validation_history.append(record)
        if improved:
            self.validation_best = record
        run_dir = self.logger.log_dir
        if run_dir is not None:
            if improved:
                data = self.checkpoint_data(None, str(Path(run_dir) / BEST_POLICY), run_state=False)
                source = f"iteration {it}, the best validation score so far"
                atomic_torch_save(policy_only(data, source), Path(run_dir) / BEST_POLICY)
            with atomic_open(Path(run_dir) / VALIDATION_FILE, "w") as f:
                json.dump({"best": self.validation_best, "history": self.validation_history}, f, indent=1)
        writer = self.logger.writer
        if writer is not None:
            for name in ("collision_rate", "height_violation_rate", "world_tilt_rad"):
                writer.add_scalar(f"Val/{name}", record[name], it)
        best = self.validation_best
        print(
            f"validation it {it}: collision {score.collision_rate:.3f} | height {score.height_violation_rate:.3f}"
            f" | tilt {score.world_tilt_rad:.3f} rad | "
            + (
                f"new best, {BEST_POLICY}"
                if improved
                else f"best {best['collision_rate']:.3f} (it {best['iteration']})"
            )
            + f" | {score.seconds:.1f} s",
            flush=True,
        )

    def _after_iteration(self, it: int) -> None:
        self._under_way, self._rollout_steps = it + 1, 0
        self._faults_before = getattr(self.env, "fault_count", 0)  # the next rollout's faults count from here
        if self._signal is None:  # a stop asked for saves at once, without a validation first
            self._validate_if_due(it)
        stop = self._share_iteration_end(it) if self.is_distributed else self._signal
        if stop is None:
            return
        path = None
        if self.logger.log_dir is not None:
            path = str(Path(self.logger.log_dir) / f"model_{it}.pt")
            self.save(path)
            self.logger.stop_logging_writer()
        raise TrainingInterrupted(stop, it, path)

    def learn(self, num_learning_iterations: int, init_at_random_ep_len: bool = False) -> None:
        """rsl_rl's loop; SIGINT / SIGTERM (main thread only) end it after the current iteration with a
        checkpoint and `TrainingInterrupted`."""
        previous = {}
        if threading.current_thread() is threading.main_thread():
            previous = {s: signal.signal(s, self._on_signal) for s in INTERRUPT_SIGNALS}
        self._signal = None
        self._under_way, self._rollout_steps = self.current_learning_iteration, 0
        self._learn_start_s = time.perf_counter()
        self._final_iteration = self.current_learning_iteration + num_learning_iterations - 1
        self._faults_before = getattr(self.env, "fault_count", 0)
        try:
            try:
                super().learn(num_learning_iterations, init_at_random_ep_len)
            except _RolloutAbandoned:
                self._stop_in_rollout()
        except BaseException:
            if self.is_distributed and previous:
                # this rank ends (stopped, or a peer lost): torchrun's agent, seeing a rank gone,
                # sends the others SIGTERM within a fraction of a second; ignored from here, so that
                # the rank's one-line report (train.main) is said whole and it exits with its own code
                previous = dict.fromkeys(previous, signal.SIG_IGN)
            raise
        finally:
            for s, handler in previous.items():
                signal.signal(s, handler)
            self._wall_before_s, self._learn_start_s = self.wall_s(), None

    def _stop_in_rollout(self) -> None:
        """A signal during the rollout of iteration `self._under_way`: keep the state of the last
        completed one (see the module's docstring) and raise `TrainingInterrupted`."""
        it, done = self._under_way, self._under_way - 1
        during = f" (during iteration {it}'s rollout, {self._rollout_steps} env-steps in, abandoned)"
        run_dir = self.logger.log_dir
        if done < 0 or run_dir is None:
            how = "; no iteration completed: nothing saved" if done < 0 else " (no log_dir: nothing saved)"
            raise TrainingInterrupted(self._signal, done, None, during + how)
        path = Path(run_dir) / f"model_{done}.pt"
        if path.is_file():  # iteration done's own checkpoint: its resume is exact
            self.logger.stop_logging_writer()
            raise TrainingInterrupted(self._signal, done, str(path), f"{during}; its checkpoint is {path}")
        self.current_learning_iteration = done
        self._abandoned = {"iteration": it, "env_steps": self._rollout_steps}
        try:
            self.save(str(path))
        finally:
            self._abandoned = None
        self.logger.stop_logging_writer()
        how = f"{during}; saved {path} (iteration {done}, with the envs' state of the stop: not an exact resume)"
        raise TrainingInterrupted(self._signal, done, str(path), how)

    # -- checkpoints -------------------------------------------------------------------------------
    def save(self, path: str, infos: dict | None = None) -> None:
        """Write the checkpoint to `path` (atomically); any failure of the write is an AtomicWriteError
        naming `path` (`atomic_torch_save`)."""
        atomic_torch_save(self.checkpoint_data(infos, path), path)
        run_dir = self.logger.log_dir
        if run_dir is not None and Path(path).parent.resolve() == Path(run_dir).resolve():
            self._keep_newest_full(run_dir)

    def checkpoint_size(self) -> int:
        """A lower bound of the bytes of a checkpoint of this run: the arrays it would hold now
        (tensors, each storage once, and numpy arrays: almost all of the file). Before the
        optimizers' first step their moments do not exist yet, so the first checkpoint's file is
        larger (by up to two copies of the trained parameters). Counted, not serialized: cheap, and
        independent of the writer."""
        return _array_bytes(self.checkpoint_data(None, None))

    def checkpoint_data(self, infos: dict | None, path: str | None, run_state: bool = True) -> dict:
        """What a checkpoint holds; a non-finite network or optimizer state is refused (FloatingPointError
        naming `path`, where given), so that the last good checkpoint stays. Without `run_state` the
        envs' running state is left out (a policy checkpoint drops it anyway)."""
        data = self.alg.save()
        if path is not None:
            check_finite(data, f"refusing to save {path}")
        data.update(
            format=CHECKPOINT_FORMAT,
            iter=self.current_learning_iteration,
            infos=infos,
            config=self.full_config,
            obs_layout=obs_layout(self.env.get_observations()),
            num_actions=self.env.num_actions,
            env_state=self.env.state_dict(run=run_state),
            rng_state=rng_state(self.env.rng),
            episode_log_state=self.logger.episode_log_state(),
            validation={
                "history": self.validation_history,
                "best": self.validation_best,
                "wall_s": self.wall_s(),
            },
        )
        if self._abandoned:  # saved at a rollout's stop: a resume says it is not exact
            data["abandoned_rollout"] = dict(self._abandoned)
        if self.is_distributed:  # every rank's envs, so that a resume of the job continues each of them
            data["other_ranks"] = self._other_ranks
            data["world_size"] = self.gpu_world_size
        return data

    def _keep_newest_full(self, run_dir: str) -> None:
        """The newest `keep_full` full checkpoints of the run stay; older ones become policy
        checkpoints, named in one line (never silently)."""
        converted, left = keep_newest_full(run_dir, self.keep_full)
        if converted or left:
            said = [f"kept as policy checkpoints: {', '.join(converted)}"] if converted else []
            said += [f"left as they were: {'; '.join(left)}"] if left else []
            print(f"checkpoints (runner.keep_full={self.keep_full}): {'; '.join(said)}", flush=True)

    def load(
        self,
        path: str | dict,
        load_cfg: dict | None = None,
        strict: bool = True,
        map_location: str | None = None,
    ):
        """Load a checkpoint: a path, or a `read_checkpoint` result (a tool reads its file once)."""
        data = path if isinstance(path, dict) else read_checkpoint(path, map_location or self.device)
        check_compatible(data, self.env)
        if load_cfg is None or load_cfg.get("optimizer", True):
            refuse_policy_only(data)
        run_wanted = load_cfg is None or load_cfg.get("env_run_state", True)
        if self.is_distributed or data.get("other_ranks"):
            data = self._this_ranks_state(data, run_wanted and bool((data.get("env_state") or {}).get("run")))
        where = data.get("path", "the checkpoint")
        # a file that passed read_checkpoint may still not fit: its errors as CheckpointError, naming it
        with not_fitting(f"{where} does not fit this policy and learner"):
            iteration = self.alg.load(data, load_cfg, strict)  # the learner goes on from the checkpoint's too
        if iteration:
            self.current_learning_iteration = int(data["iter"]) + 1  # the saved iteration is complete
        if data.get("env_state"):  # the running state only to resume training in an env of the same size
            run = load_cfg is None or load_cfg.get("env_run_state", True)
            with not_fitting(f"{where}: the envs' running state does not fit this env"):
                restored = self.env.load_state_dict(data["env_state"], run=run)
                if restored and data.get("episode_log_state"):
                    self.logger.load_episode_log_state(data["episode_log_state"])
        if data.get("validation"):  # older checkpoints lack it: the scores start afresh
            saved = data["validation"]
            self.validation_history = list(saved["history"])
            self.validation_best = saved["best"]
            self._wall_before_s = float(saved["wall_s"])
        if data.get("rng_state"):  # older checkpoints lack it: the streams then restart from the seed
            with not_fitting(f"{where}: its random state cannot be restored"):
                set_rng_state(data["rng_state"], self.env.rng)
        return data.get("infos")
