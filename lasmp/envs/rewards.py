"""Rewards as data, shared by every task: a registry of named terms, the weight check, a few terms
both tasks use, and the `RewardManager` that sums and logs them.

A term is a small pure function `term(state, cfg) -> (num_envs,)` of a task's step state and its
rewards config (the config entry that holds the weights and the terms' shape parameters: each
parameter is declared there once and read by name). It returns its UNWEIGHTED value; the sign
lives in the weight; every weighted term is multiplied by dt_s in the manager (legged_gym's
convention). Weights are checked against a task's registered terms by `check_reward_weights`: a
task's rewards config declares it (`NAMED`, read by `lasmp.config.checks.check_config`), and the
manager checks the weights it is given the same way.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import torch

from lasmp.config.checks import Bound, check_named

RewardFn = Callable[[Any, Any], torch.Tensor]  # (a task's step state, its rewards config) -> (n,)


def make_registry() -> tuple[dict[str, RewardFn], Callable]:
    """(terms, register): `@register` adds a function to `terms` under its name, once;
    `register(fn, name)` adds a shared term under the task's own name for it."""
    terms: dict[str, RewardFn] = {}

    def register(fn: RewardFn, name: str | None = None) -> RewardFn:
        name = fn.__name__ if name is None else name
        if name in terms:
            raise ValueError(f"reward term {name!r} registered twice")
        terms[name] = fn
        return fn

    return terms, register


def check_reward_weights(weights: Mapping[str, float], terms: Mapping[str, RewardFn], where: str) -> None:
    """Refuse a weight for a term that is not registered in `terms` (listing the valid names) or a
    weight outside `WEIGHT`; `where` names the weights in the message (e.g. `env.rewards.weights`)."""
    check_named(where, weights, terms, WEIGHT, REWARD_TERM)


# a term's weight: rsl_rl's PPO (its value loss, its clip) expects rewards of order 1 per step; at 1000 a
# single term swamps every other and the value function's error swamps the policy gradient
WEIGHT = Bound(-1000, 1000, "per step, before dt_s: rewards of order 1 keep PPO's value loss in scale")
REWARD_TERM = "reward term"  # what a key of a rewards config's `weights` is, in messages


def weights_of(terms: Mapping[str, RewardFn]) -> dict:
    """A rewards config's NAMED entry (`lasmp.config.checks.check_config`): its `weights` name terms of
    `terms`, each within WEIGHT."""
    return {"weights": (terms, WEIGHT, REWARD_TERM)}


def squared_norm(x: torch.Tensor) -> torch.Tensor:
    """Sum of squares over the last dimension."""
    return torch.sum(torch.square(x), dim=-1)


# ---- terms both tasks register (each under its own name) --------------------------------------
# They read fields every task's step state has: tau (n, 12) N·m, q_ddot (n, 12) rad/s², action and
# action_prev (n, 12).


def torque_sq(s, cfg) -> torch.Tensor:
    """‖tau‖², (N·m)²."""
    return squared_norm(s.tau)


def joint_acc_sq(s, cfg) -> torch.Tensor:
    """‖q_ddot‖², (rad/s²)²."""
    return squared_norm(s.q_ddot)


def action_rate_sq(s, cfg) -> torch.Tensor:
    """‖a - a_prev‖²."""
    return squared_norm(s.action - s.action_prev)


@functools.lru_cache(maxsize=16)
def _weight_factors(weights: tuple[float, ...], dt_s: float, device: torch.device) -> torch.Tensor:
    """(K, 1) float32 factors w_k · dt_s on `device`, built once: a tensor made from host numbers every
    step would, on a GPU, wait for the device each time."""
    return torch.tensor([[w * dt_s] for w in weights], device=device)


class RewardManager:
    """Sums a task's weighted terms each step and keeps per-env episode sums per term for logging.

    `terms` is the task's registry, `weights` its config's weights (checked against it), `params`
    what every term gets as its second argument (the task's rewards config). Terms with weight 0
    are skipped (never computed, not logged). Episode sums hold the weighted, dt-scaled
    contributions, i.e. what the term added to the return.
    """

    def __init__(
        self,
        terms: Mapping[str, RewardFn],
        weights: Mapping[str, float],
        params: Any,
        num_envs: int,
        device: torch.device | str = "cpu",
    ) -> None:
        check_reward_weights(weights, terms, "weights")
        active = [(name, float(w)) for name, w in weights.items() if float(w) != 0.0]
        self.params = params
        self.num_envs = num_envs
        self.device = torch.device(device)
        self.term_names: list[str] = [n for n, _ in active]
        self._fns = [terms[n] for n in self.term_names]
        self._weights = [w for _, w in active]
        self._episode_sums = torch.zeros(len(active), num_envs, device=self.device)

    def compute(self, state) -> torch.Tensor:
        """Total reward Σ_k w_k · term_k · dt_s, shape (num_envs,)."""
        if not self._fns:
            return torch.zeros(self.num_envs, device=self.device)
        # all terms as one (K, n) stack: three array operations for the weighting, the episode sums
        # and the total instead of three per term, with the same values (w_k · dt_s is rounded to
        # float32 as a scalar factor was; checked bit for bit on a seeded 400-step rollout)
        factors = _weight_factors(tuple(self._weights), state.dt_s, self.device)
        weighted = torch.stack([fn(state, self.params) for fn in self._fns]) * factors
        self._episode_sums += weighted
        return weighted.sum(dim=0)

    def state_dict(self) -> dict:
        """The running episode sums per term (a resume continues them)."""
        return {"term_names": list(self.term_names), "episode_sums": self._episode_sums}

    def load_state_dict(self, d: dict) -> None:
        if list(d["term_names"]) != self.term_names or tuple(d["episode_sums"].shape) != tuple(
            self._episode_sums.shape
        ):
            raise ValueError(
                f"saved reward sums are for terms {list(d['term_names'])} x {tuple(d['episode_sums'].shape)}, "
                f"this manager has {self.term_names} x {tuple(self._episode_sums.shape)}"
            )
        self._episode_sums = d["episode_sums"].to(self.device).clone()

    def reset(self, env_ids: torch.Tensor | Sequence[int] | None = None) -> dict[str, float]:
        """Mean episode sum per term over `env_ids` (all envs if None), then zero them."""
        if env_ids is None:
            env_ids = torch.arange(self.num_envs, device=self.device)
        elif not isinstance(env_ids, torch.Tensor):
            env_ids = torch.as_tensor(env_ids, dtype=torch.long, device=self.device)
        if env_ids.numel() == 0 or not self.term_names:
            return {}
        sums = self._episode_sums[:, env_ids]
        means = sums.mean(dim=1).tolist()  # one device sync for all terms
        self._episode_sums[:, env_ids] = 0.0
        return dict(zip(self.term_names, means, strict=True))
