"""LAS-MP reward terms (docs/method.md#rewards-lasmpenvsmoving_platformrewardspy) as a registry of
small pure functions, and their config entry `RewardsCfg` (the weights and the terms' shape
parameters, declared once: the terms read it).

Each registered term returns its UNWEIGHTED value, shape (num_envs,), as a positive magnitude;
the sign lives in the weight (`lasmp.envs.rewards` sums them). The paper's 12 terms are split
into atomic named terms, one weight each, the name's prefix being the paper term. Paper
coefficients k0..k18 map as:

    k0        -> weight of task0_collision (-k0)
    k1, k2    -> weight of task1_center,    RewardsCfg.sigma_center_m
    k3, k4    -> weight of task2_alignment, RewardsCfg.sigma_alignment
    k5, k6    -> weight of task3_level,     RewardsCfg.sigma_level_rad
    k7, k8    -> weight of task4_height,    RewardsCfg.sigma_height_m
    k9, k10   -> reg0_torque_rate, reg0_action_rate (-k)
    k11..k13  -> reg1_torque, reg1_joint_vel, reg1_joint_acc (-k)
    k14       -> reg2_power (-k)
    k15       -> reg3_contact_force (-k)
    k16       -> reg4_air_time (-k)
    k17       -> reg5_contact_time (-k)
    k18       -> reg6_foot_slip (-k)

Our choices (the paper leaves them open):
- reg0/reg1 norms are squared, as in legged_gym.
- reg4/reg5 are clipped at 0: no term ever pays a bonus for tapping or for lingering.
- reg4's charge (`RewardsCfg.air_time_charge`): the paper charges a swing at touchdown, so a foot held
  up until the episode ends costs nothing (the three-foot stance, docs/method.md). "accrue" (ours)
  charges the same total, the air time beyond t_swing_des, step by step as it accrues; "timeout"
  (ours) keeps the touchdown charge and also charges a swing still open at the time limit.
- Every weighted term is multiplied by dt_s (legged_gym convention), in `RewardManager`.

Terms of our own carry the prefix `ours_` and weigh 0 by default (the paper's recipe):
- `ours_support_margin`: how far inside the feet's support polygon the centre of pressure lies.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import torch

from lasmp.config.checks import Bound
from lasmp.envs import rewards as shared
from lasmp.envs.moving_platform.state import StepState
from lasmp.robots.a1 import LEG_NAMES

REWARD_TERMS, reward_term = shared.make_registry()  # name -> fn(StepState, RewardsCfg)


# ---- task terms -------------------------------------------------------------------------


@reward_term
def task0_collision(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """1 if trunk/limbs touch something or the robot fell off."""
    return s.collision.to(s.p_body_p.dtype)


@reward_term
def task1_center(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """exp(-‖p_body_p,xy‖ / sigma): stay at the platform's centre."""
    return torch.exp(-torch.linalg.vector_norm(s.p_body_p[:, :2], dim=-1) / c.sigma_center_m)


@reward_term
def task2_alignment(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """exp(-‖u_aln‖ / sigma): move with the platform."""
    return torch.exp(-torch.linalg.vector_norm(s.u_aln, dim=-1) / c.sigma_alignment)


@reward_term
def task3_level(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """exp(-‖(roll, pitch)‖ / sigma): keep the trunk level in the world."""
    return torch.exp(-torch.linalg.vector_norm(s.phi_body_w[:, :2], dim=-1) / c.sigma_level_rad)


@reward_term
def task4_height(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """exp(-|z - h_des| / sigma), z in the platform frame; h_des too: the terms get the config
    `in_platform_frame` (h_des measured from the frame's origin)."""
    return torch.exp(-torch.abs(s.p_body_p[:, 2] - c.h_des_m) / c.sigma_height_m)


# ---- regularization terms ---------------------------------------------------------------


@reward_term
def reg0_torque_rate(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """‖tau - tau_prev‖², (N·m)²."""
    return shared.squared_norm(s.tau - s.tau_prev)


reg0_action_rate = reward_term(shared.action_rate_sq, "reg0_action_rate")
reg1_torque = reward_term(shared.torque_sq, "reg1_torque")


@reward_term
def reg1_joint_vel(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """‖q_dot‖², (rad/s)²."""
    return shared.squared_norm(s.q_dot)


reg1_joint_acc = reward_term(shared.joint_acc_sq, "reg1_joint_acc")


@reward_term
def reg2_power(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """Σ_j max(tau_j q_dot_j, 0): positive mechanical power, W."""
    return torch.sum(torch.clamp(s.tau * s.q_dot, min=0.0), dim=-1)


@reward_term
def reg3_contact_force(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """Σ_i max(‖f_i‖ - f_tol, 0), N."""
    f = torch.linalg.vector_norm(s.f_feet_w, dim=-1)
    return torch.sum(torch.clamp(f - c.f_tol_n, min=0.0), dim=-1)


@reward_term
def reg4_air_time(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """The air time beyond t_swing_des charged this step, s, summed over the feet:
    - "touchdown" (the paper): Σ_i touchdown_i · max(t_air_i - t_swing_des, 0);
    - "accrue": Σ_i the part of this step's air time beyond t_swing_des (a swing's steps add up to the
      touchdown charge; one held up to the end pays for every step of it);
    - "timeout": the touchdown charge, plus at the time limit the excess of every swing still open."""
    if c.air_time_charge == "accrue":
        # the running air time passed t_swing_des by at most one step's worth this step
        this_step = torch.clamp(s.t_air_running_s - c.t_swing_des_s, min=0.0, max=s.dt_s)
        return torch.sum(this_step, dim=-1)
    excess = torch.clamp(s.t_air_s - c.t_swing_des_s, min=0.0)
    charged = torch.sum(s.touchdown.to(excess.dtype) * excess, dim=-1)
    if c.air_time_charge == "timeout":
        open_excess = torch.clamp(s.t_air_running_s - c.t_swing_des_s, min=0.0).sum(dim=-1)
        charged = charged + s.at_time_limit.to(excess.dtype) * open_excess
    return charged


@reward_term
def reg5_contact_time(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """Σ_i liftoff_i · max(t_contact_des - t_contact_i, 0), s."""
    short = torch.clamp(c.t_contact_des_s - s.t_contact_s, min=0.0)
    return torch.sum(s.liftoff.to(short.dtype) * short, dim=-1)


@reward_term
def reg6_foot_slip(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """Σ_i contact_i · ‖v_slip_p,i‖, m/s: feet in contact should not slide on the platform."""
    slip = torch.linalg.vector_norm(s.v_slip_p, dim=-1)
    return torch.sum(s.contact.to(slip.dtype) * slip, dim=-1)


# ---- terms of our own (weight 0 by default) ------------------------------------------------

# the feet counter-clockwise seen from above (x forward, y left), as indices into LEG_NAMES
FEET_CCW = tuple(LEG_NAMES.index(leg) for leg in ("FR", "FL", "RL", "RR"))


def support_margin_m(p_feet_p: torch.Tensor, f_feet_p: torch.Tensor, contact: torch.Tensor) -> torch.Tensor:
    """(n,) How far inside the support polygon of the loaded feet the centre of pressure lies, m, in the
    platform's plane: the smallest signed distance from the CoP (the feet's normal forces' weighted
    mean position) to the polygon's edges, taken in the feet's counter-clockwise order (`FEET_CCW`),
    positive inside. 0 with fewer than three loaded feet (a line or a point has no inside). The CoP
    reaches an edge exactly when the robot starts to tip over it, so the margin is its distance
    from tipping. With a foot tucked inside the others' hull (a reflex corner) it is a lower bound."""
    f_n = torch.clamp(f_feet_p[:, FEET_CCW, 2], min=0.0) * contact[:, FEET_CCW]
    loaded = f_n > 0.0
    xy = p_feet_p[:, FEET_CCW, :2]
    cop = (f_n[:, :, None] * xy).sum(dim=1) / f_n.sum(dim=1, keepdim=True).clamp(min=1e-9)
    # each loaded foot's successor: the next loaded foot counter-clockwise (the nearest one wins)
    nxt = torch.zeros_like(f_n, dtype=torch.long)
    for step in (3, 2, 1):
        succ = (torch.arange(4, device=f_n.device) + step) % 4
        nxt = torch.where(loaded[:, succ], succ.expand_as(nxt), nxt)
    edge = torch.gather(xy, 1, nxt[:, :, None].expand(-1, -1, 2)) - xy
    to_cop = cop[:, None, :] - xy
    cross = edge[:, :, 0] * to_cop[:, :, 1] - edge[:, :, 1] * to_cop[:, :, 0]
    dist = cross / torch.linalg.vector_norm(edge, dim=-1).clamp(min=1e-9)
    dist = torch.where(loaded, dist, torch.full_like(dist, float("inf")))
    margin = dist.min(dim=1).values
    return torch.where(loaded.sum(dim=1) >= 3, margin, torch.zeros_like(margin))


@reward_term
def ours_support_margin(s: StepState, c: RewardsCfg) -> torch.Tensor:
    """(ours) The support margin (`support_margin_m`) over `support_margin_ref_m`, clipped to [0, 1]:
    1 with the CoP at least that far inside the loaded feet's polygon, 0 on its edge (tipping) or
    with fewer than three feet loaded. Four feet span a wider polygon than three, so the term also
    pays for the fourth foot."""
    margin = support_margin_m(s.p_feet_p, s.f_feet_p, s.contact)
    bonus = torch.clamp(margin / c.support_margin_ref_m, min=0.0, max=1.0)
    return bonus * task4_height(s, c) if c.support_margin_at_height else bonus


# Paper coefficients k0..k18 with their signs (see the module docstring for the mapping); our own terms off.
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
    "ours_support_margin": 0.0,
}


AIR_TIME_CHARGES = ("touchdown", "accrue", "timeout")


# the shape parameters: each > 0 (a kernel's width, a tolerance), and no larger than what the robot or the
# platform ever reaches, beyond which the term pays (or charges) the same for every state
REWARD_BOUNDS = {
    "sigma_center_m": Bound(0, 10, "m: five times the platform's width", open_lo=True),
    "sigma_alignment": Bound(0, 10, "m/s and rad/s: far beyond any platform's speed", open_lo=True),
    "sigma_level_rad": Bound(0, 3.15, "rad: a half turn", open_lo=True),
    "sigma_height_m": Bound(0, 1, "m: more than the A1's legs reach", open_lo=True),
    "h_des_m": Bound(0, 1, "m: the A1's legs reach 0.4 m", open_lo=True),
    "f_tol_n": Bound(0, 1000, "N per foot: eight times the A1's weight", open_lo=True),
    "t_swing_des_s": Bound(0, 10, "s: an episode", open_lo=True),
    "t_contact_des_s": Bound(0, 10, "s: an episode", open_lo=True),
    "support_margin_ref_m": Bound(0, 1, "m: the A1's support polygon is about 0.4 by 0.3 m", open_lo=True),
}


@dataclass
class RewardsCfg:
    """`env.rewards`: a weight per term (0 skips it) and the terms' shape parameters."""

    weights: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_REWARD_WEIGHTS))
    sigma_center_m: float = 1.2  # k2, task1 length scale, m
    sigma_alignment: float = 0.3  # k4, task2 scale of ‖u_aln‖ (mixed m/s and rad/s)
    sigma_level_rad: float = 0.2  # k6, task3 scale of trunk roll/pitch, rad
    sigma_height_m: float = 0.1  # k8, task4 height scale, m
    h_des_m: float = 0.37  # desired trunk height, measured from `h_des_from`
    # where h_des is measured from: "top" = the platform's top surface (the trunk 0.37 m above it), the
    # paper's reading, the same as the benchmark's height metric; "centre" = the platform frame's
    # origin, its CoM 0.1 m below the top (0.27 m above the surface): a crouch it rewards (ours, an option)
    h_des_from: str = "top"
    f_tol_n: float = 50.0  # contact-force tolerance per foot, N
    t_swing_des_s: float = 0.1  # desired minimal air time, s
    t_contact_des_s: float = 0.5  # desired minimal contact time, s
    support_margin_ref_m: float = 0.1  # ours_support_margin pays in full from this margin on, m
    # (ours) ours_support_margin times task4_height's kernel, exp(-|z - h_des| / sigma_height_m): the
    # CoP's shift under a tilt grows with the trunk's height, so without it the cheapest margin is a
    # crouch (docs/screening.md: sym_air_margin broke the height band in 0.62 of its steps)
    support_margin_at_height: bool = False
    # when reg4 charges a swing: "touchdown" (the paper's literal reg4), "accrue" or "timeout" (ours,
    # closing the loophole of a foot held up to the episode's end; the module docstring)
    air_time_charge: str = "touchdown"

    BOUNDS = REWARD_BOUNDS
    CHOICES = {"h_des_from": ("top", "centre"), "air_time_charge": tuple(AIR_TIME_CHARGES)}
    NAMED = shared.weights_of(REWARD_TERMS)

    def h_des_p_m(self, plf_top_m: float) -> float:
        """h_des in the platform frame (origin at its CoM), m: what rewards and metrics compare p_body_p,z to."""
        return self.h_des_m + (plf_top_m if self.h_des_from == "top" else 0.0)

    def in_platform_frame(self, plf_top_m: float) -> RewardsCfg:
        """The same config with h_des measured from the platform frame's origin: what the terms read."""
        return dataclasses.replace(self, h_des_m=self.h_des_p_m(plf_top_m), h_des_from="centre")
