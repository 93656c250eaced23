"""In-training validation (ours): the current policy on a fixed subset of the validation benchmark.

Every `runner.validation_interval` iterations the runner hands the validator its actor's weights.
The validator plays them as `evaluate.py --benchmark validation --num-trajectories N` plays a saved
checkpoint: the actor rebuilt from the run's config in deployment mode (the estimators replace the
privileged inputs, the action is the mean), in an env of the run's config under the benchmark's
overrides, on the validation benchmark's first N episodes (`runner.validation_episodes`), all at once.
The subset is the same at every validation and in every run, so the curves of two runs compare.

It draws nothing from the training's random streams: torch's global state is forked
around it and its env is its own (built once, its random state put back before every validation), so
a run's training curve is the same with or without validation, and the figure of a policy is the same
whenever it is measured.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass

import torch

from lasmp.config.checkpoint import checkpoint_cfg
from lasmp.deploy import build_policy
from lasmp.eval import benchmark as bm
from lasmp.eval.build import policy_eval_env
from lasmp.eval.metrics import summarize
from lasmp.eval.run import run_benchmark

# what a validation reports: the metric's name in the curves and TensorBoard (Val/<name>) -> its column
VAL_METRICS = {
    "collision_rate": "collision_rate",
    "height_violation_rate": "height_violation_rate",
    "world_tilt_rad": "rotation_deviation_rad",  # the trunk's tilt change in the world (docs/evaluation.md)
}
EVAL_SEED = 0  # evaluate.py's default --seed: a validation figure is what evaluate gives the checkpoint


@dataclass(frozen=True)
class Score:
    """One validation: the policy of `iteration`, its metrics, and what it cost (s)."""

    iteration: int
    collision_rate: float
    height_violation_rate: float
    world_tilt_rad: float
    seconds: float

    def key(self) -> tuple[float, float]:
        """Lower is better: the collision rate, the height violation the tie-break."""
        return (self.collision_rate, self.height_violation_rate)


class Validator:
    """Plays a policy of the run's config on the validation benchmark's first `num_episodes` episodes."""

    def __init__(self, config: dict, num_episodes: int, bench: bm.Benchmark | None = None):
        """`config`: the run's resolved config (a plain dict, as a checkpoint stores it); `bench`: the
        validation benchmark (default: benchmarks/validation.npz, read, or made, at the first validation)."""
        self.config = config
        self._bench = bench
        self.num_episodes = num_episodes
        self._env = None
        self._env_rng = None  # the env's random state as built, put back before every validation
        self._cfg = None

    def __call__(self, iteration: int, actor_state_dict: dict, obs_layout: dict, num_actions: int) -> Score:
        data = {
            "path": f"the policy of iteration {iteration}",
            "config": self.config,
            "actor_state_dict": actor_state_dict,
            "obs_layout": obs_layout,
            "num_actions": num_actions,
        }
        start = time.perf_counter()
        with _own_random_streams():
            torch.manual_seed(EVAL_SEED)  # as evaluate's load_policy leaves it
            if self._env is None:
                self._bench = (self._bench or bm.load_or_make(bm.VALIDATION)).subset(self.num_episodes)
                self._cfg = checkpoint_cfg(data, self.num_episodes, EVAL_SEED)
                self._env = policy_eval_env(self._cfg, self.num_episodes, EVAL_SEED)
                self._env_rng = self._env.rng.bit_generator.state
            self._env.rng.bit_generator.state = self._env_rng
            policy = build_policy(data, self._cfg)
            run = run_benchmark(self._env, policy, self._bench, self.num_episodes, progress=False)
        means = summarize(run["episodes"], num_batches=1, columns=tuple(VAL_METRICS.values()))
        values = {name: means[column]["mean"] for name, column in VAL_METRICS.items()}
        return Score(iteration, **values, seconds=time.perf_counter() - start)


@contextlib.contextmanager
def _own_random_streams():
    """torch's CPU random state as it was, whatever runs inside (numpy's global state is never used:
    every draw of the project is from a generator of its own)."""
    with torch.random.fork_rng(devices=[]):
        yield
