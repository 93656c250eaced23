"""Reward terms (sign, magnitude, shape) and the RewardManager."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from lasmp.config import ConfigError
from lasmp.envs.moving_platform import rewards as R
from lasmp.envs.moving_platform.rewards import DEFAULT_REWARD_WEIGHTS, REWARD_TERMS, RewardsCfg
from lasmp.envs.moving_platform.state import StepState
from lasmp.envs.rewards import RewardManager

N = 3
P = RewardsCfg(h_des_from="centre")  # what the terms read: h_des in the platform frame (`in_platform_frame`)


def make_state(n: int = N, dt_s: float = 0.02, **overrides) -> StepState:
    """A StepState at a 'perfect' pose: centred, level, at h_des, nothing moving."""
    z = lambda *shape: torch.zeros(n, *shape)  # noqa: E731
    p_body = z(3)
    p_body[:, 2] = P.h_des_m
    fields = dict(
        dt_s=dt_s,
        p_body_p=p_body,
        phi_body_w=z(3),
        v_body_b=z(3),
        omega_body_b=z(3),
        v_plf_b=z(3),
        omega_plf_b=z(3),
        u_aln=z(3),
        action=z(12),
        action_prev=z(12),
        tau=z(12),
        tau_prev=z(12),
        q_dot=z(12),
        q_ddot=z(12),
        f_feet_w=z(4, 3),
        contact=torch.zeros(n, 4, dtype=torch.bool),
        touchdown=torch.zeros(n, 4, dtype=torch.bool),
        liftoff=torch.zeros(n, 4, dtype=torch.bool),
        t_air_s=z(4),
        t_contact_s=z(4),
        t_air_running_s=z(4),
        at_time_limit=torch.zeros(n, dtype=torch.bool),
        v_slip_p=z(4, 2),
        p_feet_p=z(4, 3),
        f_feet_p=z(4, 3),
        collision=torch.zeros(n, dtype=torch.bool),
    )
    fields.update(overrides)
    return StepState(**fields)


def term(name: str, s: StepState) -> torch.Tensor:
    out = REWARD_TERMS[name](s, P)
    assert out.shape == (s.p_body_p.shape[0],), name
    assert torch.all(out >= 0), f"{name} must be a non-negative magnitude"
    return out


def close(a: torch.Tensor, expected) -> None:
    torch.testing.assert_close(a, torch.as_tensor(expected, dtype=a.dtype), rtol=1e-5, atol=1e-6)


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
        RewardsCfg(air_time_charge="sometimes").validate("env.rewards")


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


# ---- manager ----------------------------------------------------------------------------


# four feet at the corners of a 0.36 m x 0.26 m rectangle on the deck (LEG_NAMES order: FR, FL, RR, RL)
RECTANGLE_P = torch.tensor([[0.18, -0.13, 0.1], [0.18, 0.13, 0.1], [-0.18, -0.13, 0.1], [-0.18, 0.13, 0.1]])


def _stance(loads_n, contact=None, n: int = 1) -> StepState:
    """The feet on RECTANGLE_P pressed with normal forces `loads_n` (FR, FL, RR, RL), N."""
    f = torch.zeros(n, 4, 3)
    f[:, :, 2] = torch.as_tensor(loads_n, dtype=torch.float32)
    c = f[:, :, 2] > 0 if contact is None else torch.as_tensor(contact).expand(n, 4)
    return make_state(n=n, p_feet_p=RECTANGLE_P.expand(n, 4, 3).clone(), f_feet_p=f, contact=c)


def test_the_support_margin_of_four_evenly_loaded_feet_is_half_the_stance_width():
    s = _stance([30.0, 30.0, 30.0, 30.0])
    close(R.support_margin_m(s.p_feet_p, s.f_feet_p, s.contact), [0.13])
    close(R.ours_support_margin(s, RewardsCfg(support_margin_ref_m=0.2)), [0.65])
    close(R.ours_support_margin(s, P), [1.0])  # clipped at support_margin_ref_m = 0.1 m


def test_the_support_margin_shrinks_as_the_load_moves_onto_one_side():
    # 90 N on each left foot, 10 N on each right one: the CoP sits 0.13 * 80/100 m left of the centre
    s = _stance([10.0, 90.0, 10.0, 90.0])
    close(R.support_margin_m(s.p_feet_p, s.f_feet_p, s.contact), [0.13 - 0.104])
    # all of it on the left feet: the CoP is on the left edge, where the robot tips
    s = _stance([1e-6, 100.0, 1e-6, 100.0])
    assert float(R.support_margin_m(s.p_feet_p, s.f_feet_p, s.contact)) == pytest.approx(0.0, abs=1e-6)


def test_three_feet_give_less_margin_than_four_so_the_term_pays_for_the_fourth():
    # RL up: the triangle FR, FL, RR, evenly loaded; the CoP is its centroid, whose distance to a side is
    # 2 * area / (3 * side); the nearest side is the diagonal FL-RR
    s = _stance([30.0, 30.0, 30.0, 0.0])
    diagonal = math.hypot(0.36, 0.26)
    expected = 2 * (0.5 * 0.36 * 0.26) / (3 * diagonal)
    close(R.support_margin_m(s.p_feet_p, s.f_feet_p, s.contact), [expected])
    four = float(R.ours_support_margin(_stance([30.0] * 4), P))
    three = float(R.ours_support_margin(s, P))
    assert three == pytest.approx(expected / 0.1) and three < four


@pytest.mark.parametrize("loads", [[50.0, 50.0, 0.0, 0.0], [0.0, 0.0, 0.0, 80.0], [0.0] * 4])
def test_fewer_than_three_loaded_feet_have_no_support_margin(loads):
    s = _stance(loads)
    assert float(R.ours_support_margin(s, P)) == 0.0


def test_a_foot_not_in_contact_carries_no_load_whatever_its_force_reads():
    # RL reads a force but is flagged in the air: the triangle's margin, not the rectangle's
    s = _stance([30.0, 30.0, 30.0, 30.0], contact=[True, True, True, False])
    three = _stance([30.0, 30.0, 30.0, 0.0])
    close(R.ours_support_margin(s, P), R.ours_support_margin(three, P))


def test_the_support_margin_at_height_pays_the_bonus_times_the_height_kernel_so_a_crouch_earns_less():
    at_height = dataclasses.replace(P, support_margin_at_height=True)
    s = _stance([30.0, 30.0, 30.0, 30.0], n=3)
    s.p_body_p[:, 2] = torch.tensor([P.h_des_m, P.h_des_m - 0.1, P.h_des_m + 0.2])  # at h_des, crouched, high
    close(R.ours_support_margin(s, P), [1.0, 1.0, 1.0])  # without it the height does not matter
    close(R.ours_support_margin(s, at_height), [1.0, math.exp(-1.0), math.exp(-2.0)])
    three = _stance([30.0, 30.0, 30.0, 0.0])
    three.p_body_p[:, 2] = P.h_des_m - 0.1
    close(R.ours_support_margin(three, at_height), R.ours_support_margin(three, P) * math.exp(-1.0))


def test_the_support_margin_is_the_same_for_a_mirrored_stance():
    s = _stance([20.0, 50.0, 35.0, 10.0])
    mirrored = _stance([50.0, 20.0, 10.0, 35.0])  # left and right loads swapped
    close(
        R.support_margin_m(mirrored.p_feet_p, mirrored.f_feet_p, mirrored.contact),
        R.support_margin_m(s.p_feet_p, s.f_feet_p, s.contact),
    )


def test_default_weight_keys_match_registry():
    assert set(DEFAULT_REWARD_WEIGHTS) == set(REWARD_TERMS)
    assert len(REWARD_TERMS) == 16  # the paper's 15 atomic terms and ours_support_margin


def test_default_params():
    c = RewardsCfg()
    params = (
        c.sigma_center_m,
        c.sigma_alignment,
        c.sigma_level_rad,
        c.sigma_height_m,
        c.h_des_m,
        c.f_tol_n,
        c.t_swing_des_s,
        c.t_contact_des_s,
    )
    assert params == (1.2, 0.3, 0.2, 0.1, 0.37, 50.0, 0.1, 0.5)


def test_unknown_name_refused_with_valid_names():
    with pytest.raises(ValueError) as e:
        RewardManager(REWARD_TERMS, {"task1_centre": 1.0}, P, N, "cpu")
    msg = str(e.value)
    assert "task1_centre" in msg
    for name in REWARD_TERMS:
        assert name in msg


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_weight_refused_naming_term(bad):
    with pytest.raises(ValueError, match="reg2_power"):
        RewardManager(REWARD_TERMS, {"task1_center": 1.0, "reg2_power": bad}, P, N, "cpu")


def test_zero_weight_skips_term(monkeypatch):
    def boom(s, p):
        raise AssertionError("a weight-0 term was computed")

    monkeypatch.setitem(REWARD_TERMS, "reg6_foot_slip", boom)
    m = RewardManager(REWARD_TERMS, {"task1_center": 1.0, "reg6_foot_slip": 0.0}, P, N, "cpu")
    m.compute(make_state())
    assert m.term_names == ["task1_center"]
    assert "reg6_foot_slip" not in m.reset()


def test_compute_is_weighted_sum_times_dt():
    dt = 0.02
    col = torch.tensor([True, False, False])
    m = RewardManager(REWARD_TERMS, {"task0_collision": -10.0, "task1_center": 3.0}, P, N, "cpu")
    r = m.compute(make_state(dt_s=dt, collision=col))
    assert r.shape == (N,)
    close(r, [(-10.0 + 3.0) * dt, 3.0 * dt, 3.0 * dt])


def test_default_weights_perfect_standing_state():
    dt = 0.005
    m = RewardManager(REWARD_TERMS, DEFAULT_REWARD_WEIGHTS, P, N, "cpu")
    # perfect state: all task bonuses = 1, all penalties 0
    close(m.compute(make_state(dt_s=dt)), [(3.0 + 2.0 + 1.0 + 4.0) * dt] * N)


def test_episode_sums_accumulate_and_reset_per_env():
    dt = 0.1
    m = RewardManager(REWARD_TERMS, {"task0_collision": -10.0, "task1_center": 2.0}, P, N, "cpu")
    col = torch.tensor([True, False, False])
    for _ in range(3):
        m.compute(make_state(dt_s=dt, collision=col))
    log = m.reset(torch.tensor([0, 1]))
    assert set(log) == {"task0_collision", "task1_center"}
    assert log["task0_collision"] == pytest.approx((-10.0 * 3 * dt + 0.0) / 2)
    assert log["task1_center"] == pytest.approx(2.0 * 3 * dt)
    # env 2 untouched, envs 0 and 1 zeroed
    m.compute(make_state(dt_s=dt, collision=col))
    log = m.reset([2])
    assert log["task1_center"] == pytest.approx(2.0 * 4 * dt)
    log = m.reset([0])
    assert log["task0_collision"] == pytest.approx(-10.0 * dt)
    assert log["task1_center"] == pytest.approx(2.0 * dt)
    assert m.reset([]) == {}


def test_registry_module_attributes_match():
    # every registered function is a module-level function of the same name
    for name, fn in REWARD_TERMS.items():
        assert getattr(R, name) is fn


def test_h_des_reading_resolves_to_the_platform_frame():
    """h_des = 0.37 m is measured from the platform's top surface by default (0.1 m above the
    platform frame's origin); "centre" measures it from the origin."""
    from lasmp.config import ConfigError
    from lasmp.envs.moving_platform.cfg import RewardsCfg

    assert RewardsCfg().h_des_p_m(0.1) == pytest.approx(0.47)
    assert RewardsCfg(h_des_from="centre").h_des_p_m(0.1) == pytest.approx(0.37)
    with pytest.raises(ConfigError, match="h_des_from"):
        RewardsCfg(h_des_from="floor").validate("env.rewards")


def test_a_manager_restored_from_its_state_dict_continues_the_same_episode_sums():
    """A checkpoint's running state stores the manager's episode sums as plain tensors; loaded into a
    fresh manager of the same terms, it computes and sums the same; other terms are refused."""
    m = RewardManager(REWARD_TERMS, DEFAULT_REWARD_WEIGHTS, P, N, "cpu")
    state = make_state(dt_s=0.02)
    m.compute(state)
    loaded = RewardManager(REWARD_TERMS, DEFAULT_REWARD_WEIGHTS, P, N, "cpu")
    loaded.load_state_dict(m.state_dict())
    assert torch.equal(loaded.compute(state), m.compute(state))
    assert torch.equal(loaded._episode_sums, m._episode_sums)
    with pytest.raises(ValueError, match="saved reward sums are for terms"):
        RewardManager(REWARD_TERMS, {"task1_center": 1.0}, P, N, "cpu").load_state_dict(m.state_dict())


def test_the_terms_read_the_rewards_config_with_h_des_in_the_platform_frame():
    """One declaration of the shape parameters: the env hands its `env.rewards` to the terms, h_des
    resolved to the platform frame (the top's 0.37 m is 0.47 m above a 0.2 m platform's centre)."""
    cfg = RewardsCfg(sigma_height_m=0.2)
    terms = cfg.in_platform_frame(0.1)
    assert (terms.h_des_m, terms.h_des_from, terms.sigma_height_m) == (pytest.approx(0.47), "centre", 0.2)
    assert terms.h_des_p_m(0.1) == cfg.h_des_p_m(0.1) and cfg.h_des_from == "top"  # the config is unchanged
    p = make_state().p_body_p
    p[:, 2] = 0.47
    p[1, 2] = 0.67
    out = REWARD_TERMS["task4_height"](make_state(p_body_p=p), terms)
    close(out, [1.0, math.exp(-1.0), 1.0])


@pytest.mark.parametrize("bad", [0.0, -0.1, math.nan])
def test_a_support_margin_reference_that_is_not_a_positive_length_is_refused_by_name(bad):
    with pytest.raises(ConfigError, match="support_margin_ref_m"):
        RewardsCfg(support_margin_ref_m=bad).validate("env.rewards")
