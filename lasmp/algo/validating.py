"""The runner's validation during training (its step after each iteration: lasmp/algo/runner.py).

- Validation (ours): after every `validation_interval`-th iteration (its number + 1 a multiple), a
  validator (built by the caller: `lasmp.eval.validation.Validator`) scores the current actor on the
  validation benchmark. The runner logs `Val/*` (TensorBoard and a console line), rewrites the run's
  `validation.json` (every score with its env-steps and wall-clock seconds, and the best) and keeps
  `policy_best.pt`, the policy checkpoint of the best score (the lowest collision rate, the height
  violation the tie-break), rewritten only on an improvement. The scores and the best travel in every
  checkpoint, so a resume goes on from the best so far.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

from lasmp.algo.checkpoint import (
    atomic_torch_save,
    obs_layout,
    policy_only,
)
from lasmp.io.atomic import atomic_open

BEST_POLICY = "policy_best.pt"  # the run's policy of the best validation score
VALIDATION_FILE = "validation.json"  # the run's validation curve


class ValidatingMixin:
    """LasmpRunner's validation: the runner's state it reads is its own."""

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
