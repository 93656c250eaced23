"""The benchmark sets and their draw: Xi_eval (docs/method.md, Evaluation), the test set, and the
validation set (ours), fixed trajectories and fixed robots. Their file: lasmp/eval/benchmark_file.py;
the command line and `load_or_make`: lasmp/eval/benchmark.py.

Definition
    * ``trajectories``: M (default 10,000) platform trajectories drawn by
      :func:`lasmp.envs.trajectories.sample` with the *testing* ranges
      (``ranges_for_split("test")``: N uniform in 4..16, T = 10 s), from
      ``np.random.default_rng([seed, 0])``.
    * ``robots``: R (default 1,024) intrinsic-parameter draws
      (:func:`lasmp.envs.moving_platform.domain_rand.sample_intrinsics`) from the *testing* ranges
      of Table B (``DomainRandCfg().test``: trunk mass, CoM shift, foot friction, joint Kp/Kd and
      the platform PD gain factors), from ``np.random.default_rng([seed, 1])``.
      The two streams are independent: changing M does not change the robots. Changing M does
      change the trajectories (``sample`` draws all N first, then all waypoints), so for quick runs
      take the first K rows of the full set (:meth:`Benchmark.subset`), not a set drawn with M = K.
    * Pairing (fixed, method-independent): episode k replays trajectory k with robot k % R
      (:meth:`Benchmark.pairing`). Every method meets exactly the same (trajectory, robot) pairs.
    * Initial pose (ours): episode k starts at the heading (and offset) of its own draws,
      ``np.random.default_rng([seed, 2, k])`` (:meth:`Benchmark.initial_pose_draws`), so it starts
      the same whatever the controller, the number of envs or the order in which envs reset. Not
      stored: it follows from the seed.

The validation benchmark (ours, docs/evaluation.md#validation-and-test): 2,000 episodes drawn exactly
as Xi_eval is (this generator, the testing ranges, the same robots' count) from a seed of its own,
`VALIDATION.seed`. Every choice (a candidate, a budget, a checkpoint, the shipped seed) is made on it;
Xi_eval is read only for a final row. A validation file whose seed is Xi_eval's is refused
(`check_validation`): `load` already holds every array to what its seed draws, so a file with another
seed cannot hold Xi_eval's motions or robots.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from lasmp.config.base import DomainRandCfg
from lasmp.envs import trajectories as T
from lasmp.envs.moving_platform.domain_rand import Intrinsics, sample_intrinsics

DEFAULT_NUM_TRAJECTORIES = 10_000
DEFAULT_NUM_ROBOTS = 1_024
DEFAULT_PATH = os.path.join("benchmarks", "xi_eval.npz")
MAX_TRAJECTORIES = 100_000  # 10x the paper's set; more would take gigabytes (generate's bound)
MAX_ROBOTS = 100_000


@dataclass(frozen=True)
class BenchmarkSet:
    """A named benchmark: where its file lives by default and what draws it."""

    name: str
    path: str
    seed: int
    num_trajectories: int
    num_robots: int = DEFAULT_NUM_ROBOTS


# the test set (the paper's Xi_eval: read only for a final row) and the validation set (ours: every
# choice is made on it), drawn by the same generator from different seeds
XI_EVAL = BenchmarkSet("xi_eval", DEFAULT_PATH, 0, DEFAULT_NUM_TRAJECTORIES)
VALIDATION = BenchmarkSet("validation", os.path.join("benchmarks", "validation.npz"), 1, 2_000)
SETS = {s.name: s for s in (XI_EVAL, VALIDATION)}


@dataclass
class Benchmark:
    """Xi_eval: M trajectories (testing ranges), R robots (testing intrinsics), the seed."""

    trajectories: T.PiecewisePoly
    robots: Intrinsics
    seed: int

    @property
    def num_trajectories(self) -> int:
        return len(self.trajectories)

    @property
    def num_episodes(self) -> int:
        """Episodes the set defines (episode k plays trajectory k)."""
        return len(self.trajectories)

    @property
    def num_robots(self) -> int:
        return int(self.robots.trunk_mass_kg.shape[0])

    def pairing(self, episodes) -> tuple[np.ndarray, np.ndarray]:
        """(trajectory rows, robot rows) of episodes k: trajectory k, robot k % R.

        Fixed and method-independent, so every method is scored on the same pairs.
        """
        k = np.asarray(episodes, dtype=np.int64)
        if k.size and (k.min() < 0 or k.max() >= self.num_trajectories):
            raise IndexError(f"episode indices must be in 0..{self.num_trajectories - 1}")
        return k.copy(), k % self.num_robots

    def initial_pose_draws(self, episodes) -> np.ndarray:
        """(n, 3) uniforms in [0, 1) from which episodes k start (the env maps them to a heading and
        an offset): stream [seed, 2, k] of each episode."""
        k = np.asarray(episodes, dtype=np.int64)
        return episode_draws([[self.seed, 2, int(e)] for e in k.ravel()])

    def subset(self, num_trajectories: int) -> Benchmark:
        """The first ``num_trajectories`` trajectories with the same robots (quick runs)."""
        if not 1 <= num_trajectories <= self.num_trajectories:
            raise ValueError(f"subset: need 1..{self.num_trajectories} trajectories, got {num_trajectories}")
        return Benchmark(self.trajectories.subset(np.arange(num_trajectories)), self.robots, self.seed)


def episode_draws(keys) -> np.ndarray:
    """(len(keys), 3) uniforms in [0, 1): row i from `np.random.default_rng(keys[i])`, a generator of
    the episode's own (its key: a list of non-negative ints). An episode's start then depends on
    nothing but its key."""
    return np.array([np.random.default_rng(key).random(3) for key in keys]).reshape(-1, 3)


def generate(
    num_trajectories: int = DEFAULT_NUM_TRAJECTORIES, num_robots: int = DEFAULT_NUM_ROBOTS, seed: int = 0
) -> Benchmark:
    """Draw Xi_eval (module docstring): trajectories from stream [seed, 0], robots from [seed, 1]."""
    if num_trajectories < 1 or num_robots < 1:
        raise ValueError(f"generate: need >= 1 trajectories and robots, got {num_trajectories}, {num_robots}")
    traj = T.sample(num_trajectories, T.ranges_for_split("test"), np.random.default_rng([seed, 0]))
    robots = sample_intrinsics(num_robots, DomainRandCfg().test, np.random.default_rng([seed, 1]))
    return Benchmark(traj, robots, int(seed))


def generate_set(which: BenchmarkSet) -> Benchmark:
    """The benchmark `which` names, drawn from its seed and sizes."""
    return generate(which.num_trajectories, which.num_robots, which.seed)
