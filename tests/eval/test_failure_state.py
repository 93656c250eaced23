"""The state at a failure (lasmp/eval/failure.py): what an evaluation records at each collision step,
the breakdown's tables of it, the failures in the episodes a baseline survives, and the records'
digest taken before these columns existed still checking a replay."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lasmp.eval import benchmark as bm
from lasmp.eval import breakdown as bd
from lasmp.eval import episodes as ep
from lasmp.eval import failure
from lasmp.eval import regenerate as rg
from lasmp.eval.cli import main as evaluate


def test_the_state_at_failure_counts_the_feet_and_measures_both_tilts_from_the_vertical():
    r_wp = Rotation.from_euler("x", [[0.3], [0.0]]).as_matrix()  # the deck rolled 0.3 rad; level
    r_wb = Rotation.from_euler("xy", [[0.0, -0.5], [0.2, 0.0]]).as_matrix()  # pitched 0.5; rolled 0.2
    feet = np.array([[True, True, False, True], [True, True, True, True]])
    state = failure.failure_state(feet, r_wp, r_wb, collided=np.array([True, False]))
    assert state["feet_on_deck_at_failure"][0] == 3
    assert state["deck_tilt_at_failure_rad"][0] == pytest.approx(0.3)
    assert state["trunk_tilt_at_failure_rad"][0] == pytest.approx(0.5)
    assert all(np.isnan(v[1]) for v in state.values())  # the survivor: no failure, no state


def _table(collided, feet, deck, n=None):
    k = len(collided)
    return {
        "episode": np.arange(k),
        "collided": np.asarray(collided, float),
        "foot_friction": np.full(k, 1.0),
        "n_waypoints": np.full(k, 4.0) if n is None else np.asarray(n, float),
        "feet_on_deck_at_failure": np.asarray(feet, float),
        "deck_tilt_at_failure_rad": np.asarray(deck, float),
        "trunk_tilt_at_failure_rad": np.asarray(deck, float) * 2,
    }


def test_the_tables_count_each_failure_once_by_feet_and_by_tilt_and_skip_an_older_record():
    nan = np.nan
    t = _table([1, 1, 0, 1], [4, 2, nan, 4], [0.05, 0.35, nan, 0.9])
    s = failure.state_tables(t)
    assert s["failures"] == 3 and dict(s["by_feet"]) == {"0": 0, "1": 0, "2": 1, "3": 0, "4": 2}
    deck = dict(s["by_deck_tilt"])
    assert (deck["[0.0, 0.1)"], deck["[0.3, 0.4)"], deck[">= 0.8"]) == (1, 1, 1) and sum(deck.values()) == 3
    assert s["median_deck_tilt_rad"] == pytest.approx(0.35)
    older = _table([1, 0], [nan, nan], [nan, nan])  # a record made before the state was kept
    assert failure.state_tables(older) is None


def test_the_baseline_pairing_counts_the_failures_in_the_episodes_it_survives_and_refuses_others():
    t = _table([1, 1, 0, 1], [4] * 4, [0.1] * 4)
    base = _table([0, 1, 0, 1], [4] * 4, [0.1] * 4)
    base = {c: v[::-1] for c, v in base.items()}  # the same episodes in another order
    paired = failure.against_baseline(t, base)
    assert (paired["failures"], paired["in_survived"], paired["survived_episodes"]) == (3, 1, 2)
    assert paired["share_in_survived"] == pytest.approx(1 / 3) and paired["rate_where_failed"] == 1.0
    other = _table([0, 1, 0, 1], [4] * 4, [0.1] * 4, n=[4, 4, 4, 8])
    with pytest.raises(ValueError, match="other episodes: its n_waypoints differs"):
        failure.against_baseline(t, other)
    with pytest.raises(ValueError, match="lacks 2 of the episodes, e.g. episode 0"):
        failure.against_baseline(t, {c: v[2:] for c, v in _table([0, 1, 0, 1], [4] * 4, [0.1] * 4).items()})


def test_an_evaluation_records_the_state_at_each_failure_and_the_breakdown_tables_it(tmp_path, capsys):
    bench = tmp_path / "bench.npz"
    bm.save(bench, bm.generate(num_trajectories=8, num_robots=4, seed=0))
    out = tmp_path / "ev"
    args = ["--controller", "stand_still", "--benchmark", str(bench), "--batch-envs", "4"]
    assert evaluate([*args, "--no-platform-probe", "--out", str(out)]) == 0
    t = ep.read_csv(ep.episodes_path(out))
    failed = t["collided"] > 0.5
    assert failed.any(), "Stand Still survives every episode: the test learns nothing"
    feet = t["feet_on_deck_at_failure"]
    assert set(feet[failed]) <= {0.0, 1.0, 2.0, 3.0, 4.0} and np.isnan(feet[~failed]).all()
    for tilt in ("deck_tilt_at_failure_rad", "trunk_tilt_at_failure_rad"):
        assert (t[tilt][failed] >= 0).all() and (t[tilt][failed] <= np.pi).all()
    capsys.readouterr()
    assert bd.main([str(out), "--baseline", str(out)]) == 0
    text = capsys.readouterr().out
    assert "## Feet on the deck at the failure" in text
    # against itself: every failure is in an episode the baseline fails too
    assert f"0 of the {int(failed.sum())} failures (0.000)" in text


def test_a_digest_taken_before_the_failure_columns_existed_still_checks_the_replay(tmp_path):
    k = 5
    table = {c: np.full(k, 0.5) for c in ep.WRITTEN_COLUMNS}
    table |= {"episode": np.arange(k), "collision_cause": np.array(["trunk"] * k, dtype=object)}
    old_columns = tuple(c for c in ep.WRITTEN_COLUMNS if c not in failure.FAILURE_KEYS)
    stored = ep.table_digest(table, old_columns)  # what an older metrics.json holds
    replay = tmp_path / "episodes.csv.gz"
    ep.write_csv(replay, table)  # a replay today writes the failure columns too
    assert rg._differences(stored, replay) == []
    table["power_w"][2] = 0.25  # a record that moved
    ep.write_csv(replay, table)
    assert rg._differences(stored, replay) == ["power_w"]
