"""How a training stops before its end: on a signal, or on physics that diverged (the runner's
steps in its loop: lasmp/algo/runner.py).

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
"""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

INTERRUPT_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class TrainingInterrupted(Exception):
    """Training stopped on a signal after iteration `iteration` (-1: none completed), saved to
    `checkpoint` (None: nothing saved); `how` replaces the default account of what was kept."""

    def __init__(self, signum: int, iteration: int, checkpoint: str | None, how: str | None = None):
        self.signum, self.iteration, self.checkpoint = signum, iteration, checkpoint
        name = signal.Signals(signum).name
        default = f", saved {checkpoint}" if checkpoint else " (no log_dir: nothing saved)"
        super().__init__(f"{name} received: stopped after iteration {iteration}" + (how or default))


class RolloutAbandoned(Exception):
    """Raised from the rollout loop (after an env-step) when a stop was asked for: caught by `learn`."""


class TrainingFaulted(RuntimeError):
    """Too many of an iteration's env-steps faulted (the physics diverged); the message says how many."""


class StoppingMixin:
    """LasmpRunner's fault guard and interruption: the runner's state they read is its own."""

    # -- fault guard ------------------------------------------------------------------------------
    def _after_env_step(self) -> None:
        """After each env-step of a rollout: count the iteration's faulted env-steps so far for the
        progress line; stop as soon as they pass the threshold (the count only grows in a rollout).
        A stop asked for (a signal) abandons the rollout here, alone (a torchrun job's ranks stop
        together at the iteration's end)."""
        self._rollout_steps += 1
        if self._signal is not None and not self.is_distributed:
            raise RolloutAbandoned()
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
        it (`lasmp.io.atomic.remove_stale_temporaries`, when `lasmp.io.rundir` claims the directory)."""
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # a closed or broken console must not keep the process alive
                pass
        os._exit(code)

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
