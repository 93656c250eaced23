"""The RewardManager (the weights it takes, the weighted sum, the episode sums and their state) and
the rewards config (the registry of terms, the defaults, the frame h_des is read in)."""

from __future__ import annotations

import math

import pytest
import torch
from testkit import REWARD_ENVS as N
from testkit import REWARDS_P as P
from testkit import assert_close_to as close
from testkit import step_state as make_state

from lasmp.envs.moving_platform import rewards as R
from lasmp.envs.moving_platform.rewards import DEFAULT_REWARD_WEIGHTS, REWARD_TERMS, RewardsCfg
from lasmp.envs.rewards import RewardManager


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
    from lasmp.config.checks import ConfigError, check_config
    from lasmp.envs.moving_platform.cfg import RewardsCfg

    assert RewardsCfg().h_des_p_m(0.1) == pytest.approx(0.47)
    assert RewardsCfg(h_des_from="centre").h_des_p_m(0.1) == pytest.approx(0.37)
    with pytest.raises(ConfigError, match="h_des_from"):
        check_config(RewardsCfg(h_des_from="floor"), "env.rewards")


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
