"""Per-episode records: the Coulomb-block feasibility bound on constructed platform motions, the
episodes file's round trip (plain and gzip-compressed) and its refusals, the breakdown, and the
collision causes."""

from __future__ import annotations

import gzip
import math

import numpy as np
import pytest

from lasmp.eval import breakdown as bd
from lasmp.eval import episodes as ep
from lasmp.eval import platform_probe as pp
from lasmp.eval.run import cause_names

DT = 0.02
STEPS = 501  # 10 s at the policy rate


def rot_x(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def static(r, steps=STEPS):
    """A platform held still at orientation r: (r_wp, v, omega) of one episode, (T, 1, ...)."""
    z = np.zeros((steps, 1, 3))
    return np.broadcast_to(r, (steps, 1, 3, 3)).copy(), z, z.copy()


def stats(motion, mu):
    return pp.motion_stats(DT, *motion, np.array([mu]), top_m=0.1)


def test_a_level_platform_at_rest_never_forces():
    s = stats(static(np.eye(3)), mu=0.7)
    assert s["forced"][0] == 0 and s["block_offset_max_m"][0] == 0.0 and np.isnan(s["forced_time_s"][0])
    assert s["platform_tilt_max_rad"][0] == 0.0 and s["platform_acc_max_mps2"][0] == 0.0


def test_a_static_tilt_above_atan_mu_slides_the_block_off_within_10_s():
    mu = 0.7
    tilt = math.atan(mu) + 0.05
    s = stats(static(rot_x(tilt)), mu)
    assert s["forced"][0] == 1 and s["block_contact_lost"][0] == 0
    assert s["block_offset_max_m"][0] > 1.0
    # it slides from rest at g (sin - mu cos): 1 m after sqrt(2 / a)
    a = 9.81 * (math.sin(tilt) - mu * math.cos(tilt))
    assert s["forced_time_s"][0] == pytest.approx(math.sqrt(2.0 / a), abs=2 * DT)
    assert s["platform_tilt_max_rad"][0] == pytest.approx(tilt)


def test_a_static_tilt_below_atan_mu_holds_the_block():
    mu = 0.7
    s = stats(static(rot_x(math.atan(mu) - 0.05)), mu)
    assert s["forced"][0] == 0 and s["block_offset_max_m"][0] == 0.0


def test_a_platform_accelerating_down_faster_than_g_loses_contact():
    r, v, omega = static(np.eye(3))
    v[:, 0, 2] = -1.5 * 9.81 * np.arange(STEPS) * DT  # a = -1.5 g
    s = stats((r, v, omega), mu=1.0)
    assert s["block_contact_lost"][0] == 1 and s["forced"][0] == 1
    assert s["platform_acc_max_mps2"][0] == pytest.approx(1.5 * 9.81)


def test_a_platform_accelerating_down_slower_than_g_keeps_contact():
    r, v, omega = static(np.eye(3))
    v[:, 0, 2] = -0.5 * 9.81 * np.arange(STEPS) * DT
    assert stats((r, v, omega), mu=1.0)["forced"][0] == 0


def test_apparent_gravity_includes_the_centripetal_term_of_a_spinning_platform():
    """A platform rolling at a steady rate: the top centre, 0.1 m above the axis, is pulled toward
    it by omega^2 r (the apparent gravity gains +omega^2 r along the platform's z)."""
    w, steps = 2.0, 200
    angles = w * np.arange(steps) * DT
    r_wp = np.stack([rot_x(a) for a in angles])[:, None]
    omega = np.tile([w, 0.0, 0.0], (steps, 1, 1))
    g = pp.apparent_gravity_p(DT, r_wp, np.zeros((steps, 1, 3)), omega, top_m=0.1)
    expected_z = -9.81 * np.cos(angles[1:-1]) + w**2 * 0.1
    np.testing.assert_allclose(g[1:-1, 0, 2], expected_z, atol=2e-3)


def test_a_level_platform_pushed_sideways_harder_than_mu_g_slides_the_block():
    """Apparent gravity decides, not the tilt alone: acceleration tilts it as a slope would."""
    mu = 0.5
    r, v, omega = static(np.eye(3))
    v[:, 0, 0] = 1.2 * mu * 9.81 * np.arange(STEPS) * DT
    s = stats((r, v, omega), mu)
    assert s["forced"][0] == 1 and s["block_contact_lost"][0] == 0


def test_collision_causes_name_the_bodies_then_the_fall_or_a_fault():
    contact = np.zeros((3, 13), bool)
    contact[0, 0] = True  # trunk
    contact[0, 3] = True  # FR_calf (trunk, then FR hip, thigh, calf)
    fell = np.array([[False, False], [True, True], [False, False]])
    assert list(cause_names(contact, fell)) == ["trunk+FR_calf", "off_footprint+below_top", "fault"]
    assert bd.primary_cause("trunk+FR_calf") == "trunk"
    assert bd.primary_cause("RL_thigh") == "thigh"
    assert bd.primary_cause("off_footprint") == "off_footprint"


def table(k=6):
    """A constructed episodes table of k episodes (every column; the probe's too)."""
    t = {c: np.zeros(k) for c in ep.COLUMNS}
    t["episode"] = np.arange(k)
    t["n_waypoints"] = np.array([4, 4, 10, 10, 16, 16][:k])
    t["foot_friction"] = np.linspace(0.7, 1.29, k)
    t["collided"] = np.array([0, 0, 1, 0, 1, 1][:k], float)
    t["collision_time_s"] = np.where(t["collided"] > 0, [0, 0, 3.0, 0, 8.5, 9.9][:k], np.nan)
    t["collision_cause"] = np.array(
        ["", "", "FR_calf", "", "trunk+RL_hip", "off_footprint"][:k], dtype=object
    )
    t["height_violation_rate"] = np.array([0.1, np.nan, 0.2, 0.0, 0.5, 1.0][:k])
    t["platform_tilt_max_rad"] = np.array([0.05, 0.2, 0.45, 0.55, 0.6, 0.9][:k])
    t["forced"] = np.array([0, 0, 0, 0, 0, 1][:k], float)
    t["forced_time_s"] = np.where(t["forced"] > 0, 4.0, np.nan)
    t["com_shift_y_m"] = np.array([0.0, -0.06, 0.04, 0.12, -0.22, 0.24][:k])
    t["com_shift_z_m"] = np.array([-0.22, 0.0, 0.05, -0.05, 0.15, 0.21][:k])
    return t


def write(path):
    """`table()` written to `path`; the path."""
    ep.write_csv(path, table())
    return path


def text_of(path):
    """An episodes file's CSV text, whether it is compressed or not."""
    data = path.read_bytes()
    return (gzip.decompress(data) if path.suffix == ".gz" else data).decode()


@pytest.mark.parametrize("name", [ep.EPISODES_FILE, "episodes.csv"])
def test_episodes_csv_round_trips_with_empty_cells_for_missing_values(tmp_path, name):
    t = table()
    ep.write_csv(tmp_path / name, t)
    back = ep.read_csv(tmp_path / name)
    assert list(back) == list(ep.WRITTEN_COLUMNS)
    for c in ep.OPTIONAL_COLUMNS:  # not in the table: written empty, read as NaN
        assert np.all(np.isnan(back[c])), c
    for c in ep.COLUMNS:
        if c in ep.TEXT_COLUMNS:
            assert list(back[c]) == list(t[c])
        else:
            np.testing.assert_array_equal(back[c], t[c].astype(float), err_msg=c)
    assert (
        text_of(tmp_path / name).splitlines()[2].split(",")[ep.COLUMNS.index("height_violation_rate")] == ""
    )
    assert ((tmp_path / name).read_bytes()[:2] == ep.GZIP_MAGIC) == name.endswith(".gz")


def test_a_compressed_record_is_the_same_bytes_every_time_it_is_written(tmp_path):
    """No time stamp in the gzip header (bytes 4-7, mtime): a rerun of an evaluation that plays the
    same episodes leaves a results directory unchanged in git."""
    first, second = tmp_path / "a" / ep.EPISODES_FILE, tmp_path / "b" / ep.EPISODES_FILE
    ep.write_csv(first, table())
    ep.write_csv(second, table())
    assert first.read_bytes() == second.read_bytes() and first.read_bytes()[4:8] == bytes(4)


def test_a_compressed_record_is_read_by_its_first_bytes_whatever_its_name(tmp_path):
    named_plain = tmp_path / "episodes.csv"
    named_plain.write_bytes(gzip.compress(text_of(write(tmp_path / "x.csv")).encode()))
    np.testing.assert_array_equal(ep.read_csv(named_plain)["episode"], np.arange(6))


@pytest.mark.parametrize(
    "damage, problem",
    [
        (lambda b: b[: len(b) // 2], "Compressed file ended before the end-of-stream marker"),
        (lambda b: b[:40] + bytes(40) + b[80:], "unreadable as gzip-compressed CSV"),  # corrupt data
        (lambda b: b[:-8] + bytes(8), "CRC check failed"),  # the trailer's checksum and size
        (lambda b: gzip.decompress(b), "Not a gzipped file"),  # plain text under a .gz name
    ],
)
def test_a_damaged_compressed_record_names_the_file_and_the_problem_in_one_line(tmp_path, damage, problem):
    path = write(tmp_path / ep.EPISODES_FILE)
    path.write_bytes(damage(path.read_bytes()))
    with pytest.raises(ep.EpisodesFileError) as err:
        ep.read_csv(path)
    message = str(err.value)
    assert message.startswith(f"{path}: unreadable as ") and problem in message and "\n" not in message


def test_reading_a_missing_or_corrupt_episodes_csv_names_the_file_and_the_problem(tmp_path):
    with pytest.raises(ep.EpisodesFileError, match="no such file"):
        ep.read_csv(tmp_path / "none.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("")
    with pytest.raises(ep.EpisodesFileError, match="empty"):
        ep.read_csv(bad)
    bad.write_text("episode,collided\n0,1\n")
    with pytest.raises(ep.EpisodesFileError, match="columns missing: n_waypoints"):
        ep.read_csv(bad)
    ep.write_csv(bad, table())
    lines = bad.read_text().splitlines()
    bad.write_text("\n".join(lines[:1]) + "\n")
    with pytest.raises(ep.EpisodesFileError, match="no episode rows"):
        ep.read_csv(bad)
    bad.write_text("\n".join([lines[0], lines[1].replace(",0,", ",zero,", 1)]) + "\n")
    with pytest.raises(ep.EpisodesFileError, match="row 2, column .*not a number: 'zero'"):
        ep.read_csv(bad)
    bad.write_text("\n".join([lines[0], "0,4"]) + "\n")
    with pytest.raises(ep.EpisodesFileError, match="row 2 has 2 cells"):
        ep.read_csv(bad)


def test_a_record_with_an_episode_in_two_rows_or_a_broken_episode_number_is_refused(tmp_path):
    path = tmp_path / "episodes.csv"
    ep.write_csv(path, table())
    lines = path.read_text().splitlines()
    path.write_text("\n".join([*lines, lines[3]]) + "\n")  # episode 2 pasted again at the end
    with pytest.raises(ep.EpisodesFileError, match=r"episode 2 appears 2 times \(rows 4, 8\)") as err:
        ep.read_csv(path)
    assert str(err.value).startswith(f"{path}: ") and "\n" not in str(err.value)
    for bad in ("1.5", "-1"):
        path.write_text("\n".join([lines[0], bad + lines[1][1:]]) + "\n")
        with pytest.raises(ep.EpisodesFileError, match="row 2: the episode must be a whole number >= 0"):
            ep.read_csv(path)


def test_breakdown_counts_collisions_by_n_tilt_cause_forced_and_late_failures():
    b = bd.breakdown(table(), late_s=8.0)
    assert b["episodes"] == 6 and b["collisions"] == 3
    assert b["by_n"] == [("4", 2, 0), ("10", 2, 1), ("16", 2, 2)]
    by_tilt = {label: (n, c) for label, n, c in b["by_tilt"]}
    assert (
        by_tilt["[0.4, 0.5)"] == (1, 1)
        and by_tilt["[0.5, 0.6)"] == (1, 0)
        and by_tilt["[0.6, 0.7)"] == (1, 1)
        and by_tilt[">= 0.7"] == (1, 1)
    )
    assert b["by_forced"] == [("forced", 1, 1), ("not forced", 5, 2)]
    assert b["tilt_tail"] == {"episodes": 3, "collisions": 2}
    assert dict(b["by_cause"]) == {"calf": 1, "trunk": 1, "off_footprint": 1}
    assert b["late"] == {"after_s": 8.0, "collisions": 2}
    by_com_y = {label: (n, c) for label, n, c in b["by_com_y"]}
    assert by_com_y["[0.00, 0.05)"] == (2, 1) and by_com_y["[0.05, 0.10)"] == (1, 0)
    assert by_com_y["[0.10, 0.15)"] == (1, 0) and by_com_y[">= 0.20"] == (2, 2)  # |-0.22| counts as 0.22
    by_com_z = {label: (n, c) for label, n, c in b["by_com_z"]}
    assert by_com_z["[-0.25, -0.20)"] == (1, 0) and by_com_z["[0.10, 0.20)"] == (1, 1)
    assert by_com_z[">= 0.20"] == (1, 1) and by_com_z["[0.00, 0.10)"] == (2, 1)
    text = bd.markdown(b)
    assert "| 16 | 2 | 2 | 1.000 |" in text and "Failures after 8 s: 2 of 3 (0.667)" in text
    assert "| >= 0.20 | 2 | 2 | 1.000 |" in text.split("By the CoM shift across")[1]


def test_a_run_s_row_counts_forced_tail_below_late_and_the_commonest_causes(tmp_path, capsys):
    t = table()
    t["collision_cause"] = np.array(["", "", "FR_calf", "", "trunk+RL_hip", "FL_calf"], dtype=object)
    ep.write_csv(tmp_path / "episodes.csv", t)
    assert bd.main([str(tmp_path), "--row", "seed 0"]) == 0
    # 3 collisions: 1 forced; 2 of 3 episodes in the tail (>= 0.5 rad) against 1 of 3 below; 2 late
    row = "| seed 0 | 3 | 1 | 2 (0.67) | 0.333 / 0.667 | 2 (0.67) | calf 0.67, trunk 0.33 |"
    assert capsys.readouterr().out.strip() == row
    t["collided"][:] = 0  # no collision: no shares
    ep.write_csv(tmp_path / "episodes.csv", t)
    assert bd.main([str(tmp_path), "--row", "seed 0"]) == 0
    assert capsys.readouterr().out.strip() == "| seed 0 | 0 | 0 | 0 (n/a) | 0.000 / 0.000 | 0 (n/a) |  |"
    t["forced"][:] = np.nan  # no probe: no tail, no row
    ep.write_csv(tmp_path / "episodes.csv", t)
    assert bd.main([str(tmp_path), "--row", "seed 0"]) == 2
    assert "needs the platform probe's columns" in capsys.readouterr().err


def test_breakdown_without_probe_columns_says_so():
    t = table()
    t["forced"][:] = np.nan
    b = bd.breakdown(t)
    assert "by_tilt" not in b and "no tilt or forced tables" in bd.markdown(b)


def test_breakdown_command_prints_and_plots_and_fails_clearly_on_a_missing_csv(tmp_path, capsys):
    ep.write_csv(tmp_path / ep.EPISODES_FILE, table())
    assert bd.main([str(tmp_path), "--plot", str(tmp_path / "b.png")]) == 0
    assert "By number of waypoints N" in capsys.readouterr().out
    assert (tmp_path / "b.png").stat().st_size > 5_000
    assert bd.main([str(tmp_path / "nowhere")]) == 2
    assert "nowhere/episodes.csv.gz: no such file" in capsys.readouterr().err


def test_an_evaluation_directory_s_record_is_its_csv_gz_else_the_plain_csv_of_an_older_evaluation(
    tmp_path, capsys
):
    ep.write_csv(tmp_path / "episodes.csv", {c: v[:4] for c, v in table().items()})
    assert ep.episodes_path(tmp_path) == tmp_path / "episodes.csv"
    assert bd.main([str(tmp_path)]) == 0 and capsys.readouterr().out.startswith("4 episodes")
    ep.write_csv(tmp_path / ep.EPISODES_FILE, table())
    assert ep.episodes_path(tmp_path) == tmp_path / ep.EPISODES_FILE
    assert bd.main([str(tmp_path)]) == 0 and capsys.readouterr().out.startswith("6 episodes")


def test_breakdown_of_the_first_k_episodes_counts_only_those_and_refuses_a_k_the_file_lacks(tmp_path, capsys):
    ep.write_csv(tmp_path / "episodes.csv", table())
    assert bd.main([str(tmp_path), "--episodes", "4"]) == 0
    assert capsys.readouterr().out.startswith("4 episodes, 1 collisions (rate 0.250).")
    assert bd.main([str(tmp_path), "--episodes", "7"]) == 2
    assert (
        f"{tmp_path / 'episodes.csv'}: asked for the first 7 episodes, the file has 6"
        in capsys.readouterr().err
    )
    with pytest.raises(SystemExit):
        bd.main([str(tmp_path), "--episodes", "0"])
    assert "--episodes: must be an integer >= 1, got '0'" in capsys.readouterr().err


def test_the_probe_columns_of_one_run_serve_another_run_of_the_same_episodes_and_other_episodes_are_refused(
    tmp_path, capsys
):
    with_probe, without = tmp_path / "stand_still", tmp_path / "policy"
    for d in (with_probe, without):
        d.mkdir()
    ep.write_csv(with_probe / "episodes.csv", table())
    t = table()
    for c in ep.PROBE_COLUMNS:  # evaluated with --no-platform-probe
        t[c][:] = np.nan
    t["collided"] = np.array([1, 0, 0, 0, 0, 1], float)  # its own collisions
    t["collision_cause"] = np.array(["trunk", "", "", "", "", "FL_hip"], dtype=object)
    t["collision_time_s"] = np.where(t["collided"] > 0, 2.0, np.nan)
    ep.write_csv(without / "episodes.csv", t)
    assert bd.main([str(without), "--probe-from", str(with_probe)]) == 0
    out = capsys.readouterr().out
    assert "| forced | 1 | 1 | 1.000 |" in out and "| not forced | 5 | 1 | 0.200 |" in out
    assert bd.main([str(without), "--probe-from", str(without)]) == 2  # it has none to give
    assert "has no probe columns" in capsys.readouterr().err
    other = table()
    other["foot_friction"] = other["foot_friction"][::-1]  # other robots: other episodes
    ep.write_csv(with_probe / "episodes.csv", other)
    assert bd.main([str(without), "--probe-from", str(with_probe)]) == 2
    assert "its foot_friction differs" in capsys.readouterr().err
    ep.write_csv(with_probe / "episodes.csv", {c: v[:4] for c, v in table().items()})
    assert bd.main([str(without), "--probe-from", str(with_probe)]) == 2
    assert "lacks 2 of the episodes, e.g. episode 4" in capsys.readouterr().err
