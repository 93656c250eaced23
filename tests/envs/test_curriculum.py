"""Waypoint curriculum (docs/environment.md, Curriculum)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from lasmp.envs.curriculum import WaypointCurriculum


def feed(c: WaypointCurriculum, n_success: int, n_fail: int, level: int | None = None) -> bool:
    level = c.level if level is None else level
    success = np.array([True] * n_success + [False] * n_fail)
    return c.update(np.full(success.shape, level), success)


def test_starts_at_level_min_with_empty_window():
    c = WaypointCurriculum()
    assert c.level == 5
    assert math.isnan(c.success_rate)


def test_promotes_at_80_percent_over_full_window():
    c = WaypointCurriculum(window_episodes=100)
    assert feed(c, 80, 20) is True
    assert c.level == 6
    assert math.isnan(c.success_rate)  # window cleared


def test_no_promotion_at_79_percent():
    c = WaypointCurriculum(window_episodes=100)
    assert feed(c, 79, 21) is False
    assert c.level == 5
    assert c.success_rate == pytest.approx(0.79)


def test_no_promotion_before_window_full():
    c = WaypointCurriculum(window_episodes=100)
    assert feed(c, 99, 0) is False
    assert c.level == 5
    assert feed(c, 1, 0) is True


def test_window_slides_over_latest_episodes():
    c = WaypointCurriculum(window_episodes=10)
    assert feed(c, 0, 10) is False
    assert feed(c, 7, 0) is False  # window = 3 fails + 7 successes
    assert c.success_rate == pytest.approx(0.7)
    assert feed(c, 1, 0) is True


def test_clamps_at_level_max():
    c = WaypointCurriculum(level_min=5, level_max=7, window_episodes=10)
    for expected in (6, 7):
        assert feed(c, 10, 0) is True
        assert c.level == expected
    assert feed(c, 10, 0) is False
    assert c.level == 7
    assert c.success_rate == 1.0


def test_other_level_episodes_do_not_count():
    c = WaypointCurriculum(window_episodes=10)
    feed(c, 10, 0)
    assert c.level == 6
    assert feed(c, 10, 0, level=5) is False  # replayed mastered level
    assert math.isnan(c.success_rate)
    levels = np.array([5, 6, 5, 6, 6])
    assert c.update(levels, np.array([True, False, True, True, True])) is False
    assert c.success_rate == pytest.approx(2 / 3)


def test_update_rejects_mismatched_lengths():
    c = WaypointCurriculum()
    with pytest.raises(ValueError):
        c.update(np.array([5, 5]), np.array([True]))


def test_sampling_at_level_min_has_no_replay():
    c = WaypointCurriculum()
    levels = c.sample_levels(1000, np.random.default_rng(0))
    assert levels.shape == (1000,)
    assert np.all(levels == 5)


def test_replay_fraction_and_only_mastered_levels():
    c = WaypointCurriculum(window_episodes=1, replay_lower_fraction=0.2)
    for _ in range(4):
        feed(c, 1, 0)
    assert c.level == 9
    levels = c.sample_levels(20000, np.random.default_rng(1))
    assert np.issubdtype(levels.dtype, np.integer)
    lower = levels < 9
    assert lower.mean() == pytest.approx(0.2, abs=0.015)
    assert set(np.unique(levels[lower])) == {5, 6, 7, 8}  # uniform over mastered levels
    assert levels.max() == 9
    counts = np.bincount(levels[lower])[5:9]
    assert counts.min() > 0.8 * counts.max()


def test_sampling_is_seeded():
    c = WaypointCurriculum(window_episodes=1)
    feed(c, 1, 0)
    feed(c, 1, 0)
    a = c.sample_levels(100, np.random.default_rng(3))
    b = c.sample_levels(100, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)


def test_state_dict_round_trip(tmp_path):
    c = WaypointCurriculum(window_episodes=10)
    feed(c, 10, 0)
    feed(c, 3, 2)
    path = tmp_path / "cur.pt"
    torch.save(c.state_dict(), path)
    d = WaypointCurriculum(window_episodes=10)
    d.load_state_dict(torch.load(path, weights_only=True))
    assert d.level == 6
    assert d.success_rate == pytest.approx(0.6)
    assert d.state_dict() == c.state_dict()
    # the restored window continues exactly like the original
    assert feed(d, 5, 0) is feed(c, 5, 0)
    assert d.level == c.level


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(level_min=10, level_max=5), "level_max"),
        (dict(promote_success_rate=0.0), "promote_success_rate"),
        (dict(promote_success_rate=1.1), "promote_success_rate"),
        (dict(window_episodes=0), "window_episodes"),
        (dict(replay_lower_fraction=-0.1), "replay_lower_fraction"),
        (dict(replay_lower_fraction=1.0), "replay_lower_fraction"),
    ],
)
def test_bad_constructor_args(kwargs, field):
    with pytest.raises(ValueError, match=field):
        WaypointCurriculum(**kwargs)


def test_rate_of_one_is_allowed():
    c = WaypointCurriculum(promote_success_rate=1.0, window_episodes=5)
    assert feed(c, 4, 1) is False
    assert feed(c, 5, 0) is True


@pytest.mark.parametrize(
    "state, key",
    [
        ({"window": []}, "level"),
        ({"level": 5}, "window"),
        ({"level": 16, "window": []}, "level"),
        ({"level": "6", "window": []}, "level"),
        ({"level": 6, "window": [1, 0]}, "window"),
        ({"level": 6, "window": [True] * 11}, "window"),
    ],
)
def test_malformed_state_dict(state, key):
    c = WaypointCurriculum(window_episodes=10)
    with pytest.raises(ValueError, match=key):
        c.load_state_dict(state)
    assert c.level == 5  # unchanged
