"""The paper's reward terms on constructed step states: the sign, magnitude and shape of each,
and reg4's air-time charge in each of its modes."""

from __future__ import annotations

import math

import pytest
import torch
from testkit import FEET_RECTANGLE_P as RECTANGLE_P
from testkit import REWARD_ENVS as N
from testkit import REWARDS_P as P
from testkit import assert_close_to as close
from testkit import step_state as make_state

from lasmp.config.checks import ConfigError, check_config
from lasmp.envs.moving_platform import rewards as R
from lasmp.envs.moving_platform.rewards import DEFAULT_REWARD_WEIGHTS, REWARD_TERMS, RewardsCfg
from lasmp.envs.moving_platform.state import StepState


def term(name: str, s: StepState) -> torch.Tensor:
    out = REWARD_TERMS[name](s, P)
    assert out.shape == (s.p_body_p.shape[0],), name
    assert torch.all(out >= 0), f"{name} must be a non-negative magnitude"
    return out


@pytest.mark.parametrize("name", sorted(REWARD_TERMS))
def test_every_term_shape_and_sign_on_random_state(name):
    g = torch.Generator().manual_seed(0)
    s = make_state()
    for f in (
        "p_body_p",
        "phi_body_w",
        "u_aln",
        "action",
        "action_prev",
        "tau",
        "tau_prev",
        "q_dot",
        "q_ddot",
        "t_air_s",
        "t_contact_s",
        "v_slip_p",
    ):
        setattr(s, f, torch.randn(getattr(s, f).shape, generator=g))
    s.f_feet_w = 100 * torch.randn(N, 4, 3, generator=g)
    s.p_feet_p = RECTANGLE_P + 0.02 * torch.randn(N, 4, 3, generator=g)
    s.f_feet_p = 100 * torch.randn(N, 4, 3, generator=g).abs()
    for f in ("contact", "touchdown", "liftoff"):
        setattr(s, f, torch.rand(N, 4, generator=g) > 0.5)
    s.collision = torch.tensor([True, False, True])
    out = term(name, s)
    assert out.shape == (N,) and out.dtype == s.p_body_p.dtype
    assert torch.isfinite(out).all()
    if name == "task0_collision":
        assert out.tolist() == [1.0, 0.0, 1.0]
    elif name.startswith("task"):  # exp(-distance / sigma) kernels: in (0, 1], < 1 off target
        assert ((out > 0) & (out < 1)).all(), out
    elif name.startswith("ours_"):  # our bonuses are fractions
        assert ((out >= 0) & (out <= 1)).all() and (out > 0).any(), out
    else:  # penalties are magnitudes: >= 0, and > 0 somewhere on a random state
        assert (out >= 0).all() and (out > 0).any(), out
    w = DEFAULT_REWARD_WEIGHTS[name]
    if name.startswith("ours_"):  # our own terms are off by default: the paper's recipe
        assert w == 0.0
    else:  # task1..4 are bonuses, everything else a penalty
        assert (w > 0) == (name.startswith("task") and name != "task0_collision")


def test_task0_collision():
    s = make_state(collision=torch.tensor([True, False, True]))
    close(term("task0_collision", s), [1.0, 0.0, 1.0])


def test_task1_center():
    p = make_state().p_body_p
    p[1, :2] = torch.tensor([1.2, 0.0])
    p[2, :2] = torch.tensor([0.3, 0.4])  # 0.5 m off centre; z must not count
    p[2, 2] = 5.0
    close(term("task1_center", make_state(p_body_p=p)), [1.0, math.exp(-1.0), math.exp(-0.5 / 1.2)])


def test_task2_alignment():
    u = torch.zeros(N, 3)
    u[1] = torch.tensor([0.3, 0.0, 0.0])
    u[2] = torch.tensor([0.0, 0.3, 0.4])  # the yaw-rate part counts
    close(term("task2_alignment", make_state(u_aln=u)), [1.0, math.exp(-1.0), math.exp(-0.5 / 0.3)])


def test_task3_level():
    phi = torch.zeros(N, 3)
    phi[1] = torch.tensor([0.2, 0.0, 0.0])
    phi[2] = torch.tensor([0.0, 0.0, 3.0])  # yaw does not count
    close(term("task3_level", make_state(phi_body_w=phi)), [1.0, math.exp(-1.0), 1.0])


def test_task4_height():
    p = make_state().p_body_p
    p[1, 2] = P.h_des_m + 0.1
    p[2, 2] = P.h_des_m - 0.2
    p[2, :2] = 1.0  # xy does not count
    close(term("task4_height", make_state(p_body_p=p)), [1.0, math.exp(-1.0), math.exp(-2.0)])


@pytest.mark.parametrize(
    "name, now, prev",
    [("reg0_torque_rate", "tau", "tau_prev"), ("reg0_action_rate", "action", "action_prev")],
)
def test_reg0_rates_are_squared_norms_of_the_difference(name, now, prev):
    a = torch.zeros(N, 12)
    b = torch.zeros(N, 12)
    a[1, :2] = torch.tensor([3.0, 4.0])  # ‖Δ‖ = 5 -> 25
    a[2] = 7.0
    b[2] = 7.0  # same as before -> 0
    close(term(name, make_state(**{now: a, prev: b})), [0.0, 25.0, 0.0])


@pytest.mark.parametrize(
    "name, field", [("reg1_torque", "tau"), ("reg1_joint_vel", "q_dot"), ("reg1_joint_acc", "q_ddot")]
)
def test_reg1_effort_terms_are_squared_norms(name, field):
    x = torch.zeros(N, 12)
    x[1, :2] = torch.tensor([3.0, -4.0])
    x[2] = -2.0  # 12 * 4
    close(term(name, make_state(**{field: x})), [0.0, 25.0, 48.0])


def test_reg2_power_counts_only_positive_power():
    tau = torch.zeros(N, 12)
    qd = torch.zeros(N, 12)
    tau[1, :2] = torch.tensor([2.0, 3.0])
    qd[1, :2] = torch.tensor([5.0, -1.0])  # +10, -3 (ignored)
    tau[2, 0], qd[2, 0] = -2.0, -4.0  # +8
    close(term("reg2_power", make_state(tau=tau, q_dot=qd)), [0.0, 10.0, 8.0])


def test_reg3_contact_force_above_tolerance():
    f = torch.zeros(N, 4, 3)
    f[1, 0] = torch.tensor([0.0, 0.0, 70.0])  # 70 N with tolerance 50 -> 20
    f[1, 1] = torch.tensor([0.0, 0.0, 40.0])  # below tolerance -> 0
    f[2, 2] = torch.tensor([30.0, 40.0, 0.0])  # ‖f‖ = 50 -> 0
    f[2, 3] = torch.tensor([0.0, 60.0, 80.0])  # 100 -> 50
    close(term("reg3_contact_force", make_state(f_feet_w=f)), [0.0, 20.0, 50.0])


def test_reg4_air_time_only_at_touchdown_and_clipped():
    td = torch.zeros(N, 4, dtype=torch.bool)
    t_air = torch.zeros(N, 4)
    td[0, 0], t_air[0, 0] = True, 0.3  # 0.2
    td[1, 1], t_air[1, 1] = True, 0.05  # tap: clipped to 0, not a bonus
    t_air[2, :] = 1.0  # no touchdown -> 0
    td[2, 2], t_air[2, 2] = True, 0.15  # 0.05
    close(term("reg4_air_time", make_state(touchdown=td, t_air_s=t_air)), [0.2, 0.0, 0.05])


def _swing_charges(charge: str, lands_at_step: int | None, steps: int = 50, dt: float = 0.02) -> float:
    """reg4's total over one foot's swing from lift-off: it lands at step `lands_at_step` (None: it is
    still up when the episode's time limit comes, at the last step)."""
    cfg = RewardsCfg(h_des_from="centre", air_time_charge=charge)
    t_air = torch.zeros(1, 4)
    total = 0.0
    for k in range(steps):
        landing = lands_at_step == k
        ended = t_air.clone()
        t_air = torch.zeros(1, 4) if landing else t_air + torch.tensor([[dt, 0.0, 0.0, 0.0]])
        td = torch.zeros(1, 4, dtype=torch.bool)
        td[0, 0] = landing
        s = make_state(
            n=1,
            dt_s=dt,
            touchdown=td,
            t_air_s=torch.where(td, ended, 0.0),
            t_air_running_s=t_air,
            at_time_limit=torch.tensor([k == steps - 1]),
        )
        total += float(R.reg4_air_time(s, cfg))
        if landing:
            break
    return total


@pytest.mark.parametrize("charge", ["touchdown", "accrue", "timeout"])
def test_reg4_charges_a_finished_swing_its_excess_air_time_in_every_mode(charge):
    # up for 20 steps of 0.02 s = 0.4 s, then it lands: 0.3 s beyond t_swing_des = 0.1 s
    assert _swing_charges(charge, lands_at_step=20) == pytest.approx(0.3, abs=1e-5)


def test_reg4_a_foot_held_up_to_the_time_limit_is_free_only_under_the_papers_touchdown_charge():
    # up for all 50 steps (1.0 s): 0.9 s beyond t_swing_des, never landing
    assert _swing_charges("touchdown", lands_at_step=None) == 0.0
    assert _swing_charges("accrue", lands_at_step=None) == pytest.approx(0.9, abs=1e-5)
    assert _swing_charges("timeout", lands_at_step=None) == pytest.approx(0.9, abs=1e-5)


def test_an_unknown_air_time_charge_is_refused_by_name():
    with pytest.raises(ConfigError, match="air_time_charge"):
        check_config(RewardsCfg(air_time_charge="sometimes"), "env.rewards")


def test_reg5_contact_time_only_at_liftoff_and_clipped():
    lo = torch.zeros(N, 4, dtype=torch.bool)
    t_c = torch.zeros(N, 4)
    lo[0, 0], t_c[0, 0] = True, 0.2  # 0.3
    lo[0, 3], t_c[0, 3] = True, 0.4  # + 0.1
    lo[1, 1], t_c[1, 1] = True, 2.0  # long stance: clipped to 0, not a bonus
    t_c[2, :] = 0.0  # no lift-off -> 0
    close(term("reg5_contact_time", make_state(liftoff=lo, t_contact_s=t_c)), [0.4, 0.0, 0.0])


def test_reg6_foot_slip_only_feet_in_contact():
    c = torch.zeros(N, 4, dtype=torch.bool)
    v = torch.zeros(N, 4, 2)
    v[0, 0] = torch.tensor([3.0, 4.0])  # in contact: 5
    c[0, 0] = True
    v[0, 1] = torch.tensor([10.0, 0.0])  # in the air: ignored
    v[1, :] = 1.0  # all in the air
    c[2, :] = True
    v[2, :, 0] = 0.5  # 4 * 0.5
    close(term("reg6_foot_slip", make_state(contact=c, v_slip_p=v)), [5.0, 0.0, 2.0])
