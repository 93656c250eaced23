"""LAS-MP reward terms (SPEC §10) as a registry of small pure functions; weights are data.

Each registered term returns its UNWEIGHTED value, shape (num_envs,), as a positive magnitude;
the sign lives in the weight. The paper's 12 terms are split into atomic named terms, one
weight each, the name's prefix being the paper term. Paper coefficients k0..k18 map as:

    k0        -> weight of task0_collision (-k0)
    k1, k2    -> weight of task1_center,    RewardParams.sigma_center_m
    k3, k4    -> weight of task2_alignment, RewardParams.sigma_alignment
    k5, k6    -> weight of task3_level,     RewardParams.sigma_level_rad
    k7, k8    -> weight of task4_height,    RewardParams.sigma_height_m
    k9, k10   -> reg0_torque_rate, reg0_action_rate (-k)
    k11..k13  -> reg1_torque, reg1_joint_vel, reg1_joint_acc (-k)
    k14       -> reg2_power (-k)
    k15       -> reg3_contact_force (-k)
    k16       -> reg4_air_time (-k)
    k17       -> reg5_contact_time (-k)
    k18       -> reg6_foot_slip (-k)

Our choices (SPEC §10 leaves them open):
- reg0/reg1 norms are squared, as in legged_gym.
- reg4/reg5 are clipped at 0: no term ever pays a bonus for tapping or for lingering.
- Every weighted term is multiplied by dt_s (legged_gym convention), in `RewardManager`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import torch

from lasmp.envs.moving_platform.state import StepState
from lasmp.envs.reward_registry import check_reward_weights, make_registry, squared_norm


@dataclass
class RewardParams:
    """Shape parameters of the reward terms (not weights)."""

    sigma_center_m: float = 1.2  # k2, task1 length scale, m
    sigma_alignment: float = 0.3  # k4, task2 scale of ‖u_aln‖ (mixed m/s and rad/s)
    sigma_level_rad: float = 0.2  # k6, task3 scale of trunk roll/pitch, rad
    sigma_height_m: float = 0.1  # k8, task4 height scale, m
    h_des_m: float = 0.37  # desired trunk height in the platform frame (origin at its CoM), m
    f_tol_n: float = 50.0  # contact-force tolerance per foot, N
    t_swing_des_s: float = 0.1  # desired minimal air time, s
    t_contact_des_s: float = 0.5  # desired minimal contact time, s


RewardFn = Callable[[StepState, RewardParams], torch.Tensor]
REWARD_TERMS, reward_term = make_registry()  # name -> RewardFn


_sq = squared_norm


# ---- task terms -------------------------------------------------------------------------


@reward_term
def task0_collision(s: StepState, p: RewardParams) -> torch.Tensor:
    """1 if trunk/limbs touch something or the robot fell off."""
    return s.collision.to(s.p_body_p.dtype)


@reward_term
def task1_center(s: StepState, p: RewardParams) -> torch.Tensor:
    """exp(-‖p_body_p,xy‖ / sigma): stay at the platform's centre."""
    return torch.exp(-torch.linalg.vector_norm(s.p_body_p[:, :2], dim=-1) / p.sigma_center_m)


@reward_term
def task2_alignment(s: StepState, p: RewardParams) -> torch.Tensor:
    """exp(-‖u_aln‖ / sigma): move with the platform."""
    return torch.exp(-torch.linalg.vector_norm(s.u_aln, dim=-1) / p.sigma_alignment)


@reward_term
def task3_level(s: StepState, p: RewardParams) -> torch.Tensor:
    """exp(-‖(roll, pitch)‖ / sigma): keep the trunk level in the world."""
    return torch.exp(-torch.linalg.vector_norm(s.phi_body_w[:, :2], dim=-1) / p.sigma_level_rad)


@reward_term
def task4_height(s: StepState, p: RewardParams) -> torch.Tensor:
    """exp(-|z - h_des| / sigma), z in the platform frame."""
    return torch.exp(-torch.abs(s.p_body_p[:, 2] - p.h_des_m) / p.sigma_height_m)


# ---- regularization terms ---------------------------------------------------------------


@reward_term
def reg0_torque_rate(s: StepState, p: RewardParams) -> torch.Tensor:
    """‖tau - tau_prev‖², (N·m)²."""
    return _sq(s.tau - s.tau_prev)


@reward_term
def reg0_action_rate(s: StepState, p: RewardParams) -> torch.Tensor:
    """‖a - a_prev‖²."""
    return _sq(s.action - s.action_prev)


@reward_term
def reg1_torque(s: StepState, p: RewardParams) -> torch.Tensor:
    """‖tau‖², (N·m)²."""
    return _sq(s.tau)


@reward_term
def reg1_joint_vel(s: StepState, p: RewardParams) -> torch.Tensor:
    """‖q_dot‖², (rad/s)²."""
    return _sq(s.q_dot)


@reward_term
def reg1_joint_acc(s: StepState, p: RewardParams) -> torch.Tensor:
    """‖q_ddot‖², (rad/s²)²."""
    return _sq(s.q_ddot)


@reward_term
def reg2_power(s: StepState, p: RewardParams) -> torch.Tensor:
    """Σ_j max(tau_j q_dot_j, 0): positive mechanical power, W."""
    return torch.sum(torch.clamp(s.tau * s.q_dot, min=0.0), dim=-1)


@reward_term
def reg3_contact_force(s: StepState, p: RewardParams) -> torch.Tensor:
    """Σ_i max(‖f_i‖ - f_tol, 0), N."""
    f = torch.linalg.vector_norm(s.f_feet_w, dim=-1)
    return torch.sum(torch.clamp(f - p.f_tol_n, min=0.0), dim=-1)


@reward_term
def reg4_air_time(s: StepState, p: RewardParams) -> torch.Tensor:
    """Σ_i touchdown_i · max(t_air_i - t_swing_des, 0), s."""
    excess = torch.clamp(s.t_air_s - p.t_swing_des_s, min=0.0)
    return torch.sum(s.touchdown.to(excess.dtype) * excess, dim=-1)


@reward_term
def reg5_contact_time(s: StepState, p: RewardParams) -> torch.Tensor:
    """Σ_i liftoff_i · max(t_contact_des - t_contact_i, 0), s."""
    short = torch.clamp(p.t_contact_des_s - s.t_contact_s, min=0.0)
    return torch.sum(s.liftoff.to(short.dtype) * short, dim=-1)


@reward_term
def reg6_foot_slip(s: StepState, p: RewardParams) -> torch.Tensor:
    """Σ_i contact_i · ‖v_slip_p,i‖, m/s: feet in contact should not slide on the platform."""
    slip = torch.linalg.vector_norm(s.v_slip_p, dim=-1)
    return torch.sum(s.contact.to(slip.dtype) * slip, dim=-1)


# Paper coefficients k0..k18 with their signs (see the module docstring for the mapping).
DEFAULT_REWARD_WEIGHTS: dict[str, float] = {
    "task0_collision": -10.0,
    "task1_center": 3.0,
    "task2_alignment": 2.0,
    "task3_level": 1.0,
    "task4_height": 4.0,
    "reg0_torque_rate": -1e-7,
    "reg0_action_rate": -1e-4,
    "reg1_torque": -1e-4,
    "reg1_joint_vel": -1e-7,
    "reg1_joint_acc": -1e-6,
    "reg2_power": -1e-5,
    "reg3_contact_force": -0.01,
    "reg4_air_time": -2.0,
    "reg5_contact_time": -3.0,
    "reg6_foot_slip": -0.05,
}


@functools.lru_cache(maxsize=16)
def _weight_factors(weights: tuple[float, ...], dt_s: float, device: torch.device) -> torch.Tensor:
    """(K, 1) float32 factors w_k · dt_s on `device`, built once: a tensor made from host numbers every
    step would, on a GPU, wait for the device each time."""
    return torch.tensor([[w * dt_s] for w in weights], device=device)


class RewardManager:
    """Sums weighted terms each step and keeps per-env episode sums per term for logging.

    Terms with weight 0 are skipped (never computed, not logged). Episode sums hold the
    weighted, dt-scaled contributions, i.e. what the term added to the return.
    """

    def __init__(
        self,
        weights: Mapping[str, float],
        params: RewardParams,
        num_envs: int,
        device: torch.device | str = "cpu",
        registry: Mapping[str, Callable] | None = None,
    ) -> None:
        registry = REWARD_TERMS if registry is None else registry  # another task's terms
        check_reward_weights(weights, registry, "weights")
        active = [(name, float(w)) for name, w in weights.items() if float(w) != 0.0]
        self.params = params
        self.num_envs = num_envs
        self.device = torch.device(device)
        self.term_names: list[str] = [n for n, _ in active]
        self._fns = [registry[n] for n in self.term_names]
        self._weights = [w for _, w in active]
        self._episode_sums = torch.zeros(len(active), num_envs, device=self.device)

    def compute(self, state: StepState) -> torch.Tensor:
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
        if list(d["term_names"]) != self.term_names or tuple(d["episode_sums"].shape) != tuple(self._episode_sums.shape):
            raise ValueError(f"saved reward sums are for terms {list(d['term_names'])} x {tuple(d['episode_sums'].shape)}, "
                             f"this manager has {self.term_names} x {tuple(self._episode_sums.shape)}")  # fmt: skip
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
