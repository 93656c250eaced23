"""lasmp.envs.trajectories' statistics (fast): the testing split against the paper's figures, path
length against the number of waypoints, a straight line's exact figures, and long recordings
evaluated in bounded passes."""

import numpy as np
import pytest

from lasmp.envs import trajectories as T


def test_testing_split_matches_the_papers_statistics():
    """docs/trajectories.md: the paper's testing set has a mean path length of 7.12 m and mean speed of 0.69 m/s."""
    st = T.statistics(T.sample(2000, T.TEST_RANGES, np.random.default_rng(11)))["overall"]
    assert st["mean_path_length_m"] == pytest.approx(7.12, rel=0.10)
    assert st["mean_speed_mps"] == pytest.approx(0.69, rel=0.10)
    assert st["max_speed_mps"] < 15.0 and st["p99_acceleration_mps2"] > 0.0


def test_more_waypoints_longer_paths():
    rng = np.random.default_rng(1)
    stats = T.statistics(T.sample(400, T.TEST_RANGES, rng, n_waypoints=np.repeat([4, 16], 200)))
    few, many = stats["per_n"]["4"], stats["per_n"]["16"]
    assert many["mean_path_length_m"] > 1.5 * few["mean_path_length_m"]
    assert many["mean_speed_mps"] > few["mean_speed_mps"]
    assert stats["overall"]["num"] == 400 and few["num"] == 200


def test_statistics_of_a_straight_line():
    # a straight segment: length known, curvature ~0
    t = np.linspace(0.0, 4.0, 41)
    poses = np.zeros((1, 41, 6))
    poses[0, :, 0] = 0.5 * t  # x = 0.5 t  -> 2 m in 4 s
    st = T.statistics(T.from_samples(t, poses))
    assert st["overall"]["mean_path_length_m"] == pytest.approx(2.0, abs=1e-9)
    assert st["overall"]["mean_speed_mps"] == pytest.approx(0.5, abs=1e-9)
    assert st["overall"]["mean_curvature_per_m"] == pytest.approx(0.0, abs=1e-6)
    assert list(st["per_n"]) == ["-1"]


def test_statistics_of_long_recordings_evaluate_in_passes_of_bounded_size(monkeypatch):
    """60 rows of 200 s at dt 0.02 (600,600 samples): more than one pass allows, so two passes, with
    the same statistics as one row per pass."""
    from lasmp.envs.trajectories import stats as S

    t = np.linspace(0.0, 200.0, 41)
    poses = np.zeros((60, len(t), 6))
    poses[:, :, 0] = 0.05 * t * np.linspace(0.5, 1.5, 60)[:, None]
    traj = T.from_samples(t, poses)
    sizes = []
    evaluate = type(traj).evaluate
    monkeypatch.setattr(
        type(traj), "evaluate", lambda self, *a: sizes.append(len(a[0])) or evaluate(self, *a)
    )
    st = T.statistics(traj)
    assert len(sizes) == 2 and max(sizes) <= S._CHUNK_SAMPLES
    assert st == T.statistics(traj, chunk=1)
