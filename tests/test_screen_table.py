"""scripts/screen_table.py: the screening table's figures come from the records they name."""

from __future__ import annotations

import json

import numpy as np
import pytest
from testkit import load_script

from lasmp.eval import episodes as ep


def _records(k: int = 2400) -> dict[str, np.ndarray]:
    """k episodes: every tenth collides; the CoM shift and N cycle so that each hard case is known."""
    t = {c: np.zeros(k) for c in ep.COLUMNS}
    t["episode"] = np.arange(k)
    t["collided"] = (np.arange(k) % 10 == 0).astype(float)
    t["com_shift_y_m"] = np.where(np.arange(k) % 4 == 0, -0.22, 0.05)  # every fourth one 0.22 m to the right
    t["n_waypoints"] = np.where(np.arange(k) % 5 == 0, 16, 4)
    return t


def test_the_hard_cases_count_only_the_first_2000_episodes_and_both_sides_of_the_com():
    table = load_script("scripts/screen_table.py")
    t = _records()
    wide, many = table.hard_cases(t)
    first = t["episode"] < 2000
    # episodes 0, 20, 40, ... collide and are both wide (multiples of 4) and of N = 16 (multiples of 5)
    expected_wide = t["collided"][first & (t["com_shift_y_m"] < -0.2)].mean()
    expected_many = t["collided"][first & (t["n_waypoints"] == 16)].mean()
    assert (wide, many) == (expected_wide, expected_many) == (0.2, 0.5)
    t["collided"][2000:] = 1.0  # the episodes past the first 2,000 change nothing
    assert table.hard_cases(t) == (wide, many)


def test_a_baseline_row_is_read_from_the_study_s_episode_record(tmp_path, monkeypatch):
    table = load_script("scripts/screen_table.py")
    seed_dir = tmp_path / "seed0"
    seed_dir.mkdir()
    t = _records()
    t["height_violation_rate"][:] = 0.25
    t["rotation_deviation_rad"][:] = 0.125
    ep.write_csv(seed_dir / ep.EPISODES_FILE, t)
    monkeypatch.setitem(table.BASELINES, "lasmp_float32", tmp_path)
    cells = [c.strip() for c in table.row("lasmp_float32", seed_dir).strip("|").split("|")]
    # candidate, seed, collision, height violation, world tilt, 5 stance/mirror cells (none), the two hard cases
    assert cells[:5] == ["lasmp_float32", "0", "0.100", "0.250", "0.125"] and cells[-2:] == ["0.200", "0.500"]


def test_a_truncated_metrics_file_is_named_in_one_line_not_a_json_error(tmp_path, monkeypatch, capsys):
    table = load_script("scripts/screen_table.py")
    monkeypatch.setattr(table, "SCREEN", tmp_path)
    monkeypatch.setattr(table, "BASELINES", {})
    metrics = tmp_path / "candidate" / "seed0" / "metrics_2000.json"
    metrics.parent.mkdir(parents=True)
    metrics.write_text(json.dumps({"metrics": {"collision_rate": {"mean": 0.1}}})[:-3])  # a copy cut short
    with pytest.raises(SystemExit) as stop:
        table.main([])
    assert str(stop.value) == f"error: {metrics}: truncated: the file ends before its JSON does"
    assert capsys.readouterr().out.startswith("| candidate | seed |")  # the header, then the error


def test_a_candidate_s_row_reads_the_same_from_its_stored_hard_cases_once_its_records_are_gone(tmp_path):
    table = load_script("scripts/screen_table.py")
    seed_dir = tmp_path / "seed0"
    seed_dir.mkdir()
    ep.write_csv(seed_dir / table.RECORDS_2000, _records())
    m = {k: {"mean": 0.1} for k in ("collision_rate", "height_violation_rate", "rotation_deviation_rad")}
    (seed_dir / "metrics_2000.json").write_text(json.dumps({"metrics": m}))
    from_records = table.row("candidate", seed_dir)
    stored = json.loads(table.store_hard_cases(seed_dir).read_text())
    assert stored["records_digest"] == ep.file_digest(seed_dir / table.RECORDS_2000)["sha256"]
    (seed_dir / table.RECORDS_2000).unlink()
    assert table.row("candidate", seed_dir) == from_records and from_records.endswith("| 0.200 | 0.500 |")
