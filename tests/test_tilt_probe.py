"""scripts/tilt_probe.py: the world tilt split into a lean held, a swing about it and the deck's
share, on constructed trunk and deck axes."""

from __future__ import annotations

import numpy as np
import pytest
from testkit import load_script

DT_S = 0.02
T = 500  # 10 s


@pytest.fixture(scope="module")
def probe():
    return load_script("scripts/tilt_probe.py")


def pitched(theta: np.ndarray) -> np.ndarray:
    """z axes of a trunk pitched by theta (+ nose down: z toward +x), shape theta.shape + (3,)."""
    return np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=-1)


def split(probe, z, zp=None, counted=None):
    up = np.tile([0.0, 0.0, 1.0], (z.shape[1], 1))
    zp = np.broadcast_to(up, z.shape) if zp is None else zp
    counted = np.ones(z.shape[:2], bool) if counted is None else counted
    return probe.tilt_split(up, z, up, zp, counted, DT_S)


def test_a_nose_up_posture_held_from_the_start_is_all_lean_and_no_swing(probe):
    s = split(probe, pitched(np.full((T, 1), -0.1)))
    assert s["tilt"][0] == pytest.approx(0.1) and s["lean"][0] == pytest.approx(0.1)
    assert s["swing"][0] == pytest.approx(0.0, abs=1e-9)
    assert s["lean_pitch"][0] == pytest.approx(-0.1) and s["lean_roll"][0] == pytest.approx(0.0)


def test_a_sway_about_the_start_is_all_swing_and_its_frequency_decides_the_slow_share(probe):
    t = np.arange(T)[:, None] * DT_S
    slow = split(probe, pitched(0.1 * np.sin(2 * np.pi * 0.2 * t)))
    assert slow["lean"][0] == pytest.approx(0.0, abs=1e-3)
    assert slow["swing"][0] == pytest.approx(0.2 / np.pi, rel=0.01)  # mean |0.1 sin|
    assert slow["tilt"][0] == pytest.approx(slow["swing"][0], rel=0.01)
    assert slow["slow_share"] > 0.99
    fast = split(probe, pitched(0.1 * np.sin(2 * np.pi * 5.0 * t)))
    assert fast["slow_share"] < 0.01


def test_the_roll_part_is_positive_with_the_right_side_down(probe):
    phi = 0.05  # a rotation about +x: the left side up, z toward -y
    z = np.tile([0.0, -np.sin(phi), np.cos(phi)], (T, 1, 1))
    s = split(probe, z)
    assert s["lean_roll"][0] == pytest.approx(phi) and s["lean_pitch"][0] == pytest.approx(0.0)


def test_the_gain_is_one_swaying_with_the_deck_zero_holding_a_posture_and_negative_against_it(probe):
    t = np.arange(T)[:, None] * DT_S
    deck = pitched(0.2 * np.sin(2 * np.pi * 0.3 * t))
    assert split(probe, deck, zp=deck)["gain_on_deck_tilt"] == pytest.approx(1.0)
    assert split(probe, pitched(np.zeros((T, 1))), zp=deck)["gain_on_deck_tilt"] == pytest.approx(0.0)
    tilted_deck = pitched(0.2 + 0.2 * np.sin(2 * np.pi * 0.3 * t))  # a posture held is not a gain
    assert split(probe, pitched(np.full((T, 1), -0.1)), zp=tilted_deck)["gain_on_deck_tilt"] == pytest.approx(
        0.0
    )
    against = pitched(-0.1 * np.sin(2 * np.pi * 0.3 * t))
    assert split(probe, against, zp=deck)["gain_on_deck_tilt"] == pytest.approx(-0.5, rel=0.02)


def test_steps_after_a_collision_are_not_counted_and_a_fall_leaves_out_the_slow_share(probe):
    theta = np.full((T, 2), -0.1)
    theta[300:, 1] = 1.5  # episode 1 collides at step 300 and tips over
    counted = np.ones((T, 2), bool)
    counted[300:, 1] = False
    s = split(probe, pitched(theta), counted=counted)
    assert s["tilt"] == pytest.approx([0.1, 0.1]) and s["lean"] == pytest.approx([0.1, 0.1])
    assert s["episodes_to_time_out"] == 1
