"""Our support-margin bonus (ours_support_margin) on constructed stances: the distance of the feet's
centre of pressure to the edge of their support polygon, and its reference length."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch
from testkit import FEET_RECTANGLE_P as RECTANGLE_P
from testkit import REWARDS_P as P
from testkit import assert_close_to as close
from testkit import step_state as make_state

from lasmp.config.checks import ConfigError, check_config
from lasmp.envs.moving_platform import rewards as R
from lasmp.envs.moving_platform.rewards import RewardsCfg
from lasmp.envs.moving_platform.state import StepState


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


@pytest.mark.parametrize("bad", [0.0, -0.1, math.nan])
def test_a_support_margin_reference_that_is_not_a_positive_length_is_refused_by_name(bad):
    with pytest.raises(ConfigError, match="support_margin_ref_m"):
        check_config(RewardsCfg(support_margin_ref_m=bad), "env.rewards")
