"""A sweep's (`train.py -m ...`) jobs and how each ended: a failed job is said when it ends and again,
with every other failed job, when the sweep ends; an interrupted job stops the sweep, naming the jobs
that did not run (docs/usage.md)."""

from __future__ import annotations

import sys
import traceback
from collections.abc import Callable


class Sweep:
    """A sweep's (`train.py -m ...`) jobs and how each ended. A job that fails (bad input, exit 2; a
    run that could not go on, exit 1; an unexpected exception, its traceback and exit 1) is said when it
    ends, and the sweep goes on with the next job; `report` then lists every failed job. A job stopped
    by Ctrl-C or SIGTERM (exit 128 + the signal) stops the sweep, naming the jobs that did not run."""

    def __init__(self, jobs: list[list[str]] | None):
        self.jobs = jobs  # None: not expanded here (the labels are then the job numbers alone)
        self.failed: dict[int, int] = {}  # job number -> exit code
        self.ran = 0

    def label(self, num: int) -> str:
        """Job #num with the overrides that tell it from the sweep's other jobs."""
        if not self.jobs or num >= len(self.jobs):
            return f"#{num}"
        own = self.jobs[num]
        varying = [o for o in own if not all(o in job for job in self.jobs)] or own
        return f"#{num} ({' '.join(varying)})"

    def run_job(self, num: int, job: Callable[[], int]) -> None:
        """Run job #num and keep its exit code; SystemExit if it was interrupted."""
        try:
            code = job()
        except Exception:  # a bug, not a user's mistake: its traceback, and the other jobs still run
            traceback.print_exc()
            code = 1
        self.ran += 1
        if code >= 128:  # Ctrl-C or SIGTERM: the user wants the sweep to stop, not to skip one job
            rest = self.jobs[num + 1 :] if self.jobs is not None else None
            if rest is None:
                not_run = f"the jobs after #{num} did not run"
            elif rest:
                not_run = f"did not run: {', '.join(self.label(n) for n in range(num + 1, len(self.jobs)))}"
            else:
                not_run = "it was the last job"
            failed = f"; failed before: {self._listed()}" if self.failed else ""
            print(
                f"the sweep stopped at job {self.label(num)}: {not_run}{failed}", file=sys.stderr, flush=True
            )
            raise SystemExit(code)
        if code:
            self.failed[num] = code
            print(
                f"sweep: job {self.label(num)} failed (exit {code}); going on with the next job",
                file=sys.stderr,
                flush=True,
            )

    def _listed(self) -> str:
        return ", ".join(f"{self.label(n)} exit {code}" for n, code in self.failed.items())

    def report(self) -> int:
        """After the sweep: the failed jobs in one line (their own errors were said as each ended); the
        exit code, the first failed job's (0 if none failed)."""
        if not self.failed:
            return 0
        total = len(self.jobs) if self.jobs is not None else self.ran
        print(
            f"error: {len(self.failed)} of {total} jobs of the sweep failed: {self._listed()} (each job's error "
            "is above); the other jobs ran to their end",
            file=sys.stderr,
            flush=True,
        )
        return next(iter(self.failed.values()))
