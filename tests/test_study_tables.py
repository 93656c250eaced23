"""The rows scripts/study.py hands to the results table and the tables it makes of them: the
summary's rows and seeds, the table, the headline beside the paper's rows, the ordering of the
ablations, the first pass's comparison of the learners, and the documents' tables rewritten."""

from __future__ import annotations

import json

import numpy as np
import pytest
from testkit import mark_evaluated as evaluated


def test_the_summary_lists_each_row_with_its_evaluated_seeds_and_leaves_out_the_first_pass(study):
    for s in (0, 2):
        evaluated(study.result_dir("lasmp", s, 450))
    evaluated(study.result_dir("lasmp", 0, 1000))
    evaluated(study.result_dir("lasmp", 1, 450, root=study.FIRST_PASS))
    evaluated(study.result_dir("rs", 1, 450, "rs_oracle"))
    for s in (0, 1, 2):  # seed 2 ran float32 and then bfloat16: in no row
        evaluated(study.result_dir("lasmp", s, 450, root=study.RESULTS / "float32_learner"))
    assert study.summary_args() == [
        "--method", "LAS-MP", "results/study/lasmp/seed0", "results/study/lasmp/seed2",
        "--method", "LAS-MP (1,000 it.)", "results/study/lasmp@1000/seed0",
        "--method", "R-S (oracle)", "results/study/rs_oracle/seed1",
        "--method", "LAS-MP, float32 learner",
        "results/study/float32_learner/lasmp/seed0", "results/study/float32_learner/lasmp/seed1",
        "--method", "Stand Still", "results/study/stand_still/seed0",
    ]  # fmt: skip


def _entry(study, seeds: list[str], collision: list[float], ci95: float | None = None) -> dict:
    """A summary row whose every metric holds the same values."""
    metric = {"mean": sum(collision) / len(collision), "ci95": ci95, "per_seed": collision}
    return {"seeds": seeds, "metrics": dict.fromkeys(study.WIDE_COLUMNS, metric)}


def test_the_table_gives_three_seeds_as_mean_and_interval_fewer_per_seed_and_r_s_beside_its_oracle(study):
    methods = {
        "Stand Still": _entry(study, ["results/study/stand_still/seed0"], [0.634]),
        "LAS-MP": _entry(
            study, [f"results/study/lasmp/seed{k}" for k in range(3)], [0.1, 0.2, 0.3], ci95=0.248
        ),
        "R-S": _entry(study, ["results/study/rs/seed0", "results/study/rs/seed2"], [0.16, 0.2]),
        "R-S (oracle)": _entry(
            study, ["results/study/rs_oracle/seed0", "results/study/rs_oracle/seed2"], [0.14, 0.5]
        ),
    }
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"methods": methods}))
    rows = study.table(path).splitlines()
    assert rows[0].startswith("| method | seeds | collision rate |") and len(rows) == 2 + 3
    assert rows[2].startswith("| Stand Still (a = 0) | – | 0.634 |")
    assert rows[3].startswith("| LAS-MP, 450 iterations | 3 | 0.200 ± 0.248 |") and rows[3].endswith(
        "| 0.20 ± 0.25 |"
    )  # power to two places
    assert rows[4].startswith("| R-S (its estimates; the true x_exp) | 0, 2 | 0.160 / 0.200; 0.140 / 0.500 |")
    wide = study.table(path, wide=True).splitlines()  # every summary row on its own, every metric
    assert len(wide) == 2 + 4 and wide[0].endswith("| rotation (rad, rel. to platform) | learner per seed |")
    assert wide[3].startswith("| LAS-MP | 0, 1, 2 | 0.200 ± 0.248 |") and wide[3].endswith(
        "| 0.200 ± 0.248 | – |"
    )
    assert wide[5].startswith("| R-S (oracle) | 0, 2 | 0.140 / 0.500 |")


def test_the_table_with_paper_puts_every_row_of_the_papers_table_ii_below_ours_marked_as_the_papers(study):
    from lasmp.eval.paper import PAPER_ROWS

    methods = {"Stand Still": _entry(study, ["results/study/stand_still/seed0"], [0.634])}
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"methods": methods}))
    assert not any(r.startswith("| paper:") for r in study.table(path).splitlines())
    for wide in (False, True):
        rows = study.table(path, wide=wide, paper=True).splitlines()
        paper = [r for r in rows if r.startswith("| paper:")]
        assert len(paper) == len(PAPER_ROWS) and rows[-len(paper) :] == paper
        assert paper[0] == (
            "| paper: LAS-MP | – | 0.029 ± 0.03 | 0.009 ± 0.01 | 0.366 ± 0.01 | 0.071 ± 0.01 | 2.904 ± 0.45 |"
            + ("  |  |  |" if wide else "")
        )
        assert {r.count("|") for r in rows} == {rows[0].count("|")}  # every row as wide as the header


def test_the_headline_puts_each_of_our_rows_beside_the_papers_row_it_reproduces_metric_by_metric(study):
    plus = [f"results/study/lasmp_plus/seed{k}" for k in range(3)]
    methods = {
        "Stand Still": _entry(study, ["results/study/stand_still/seed0"], [0.634]),
        "LAS-MP+": _entry(study, plus, [0.036, 0.069, 0.054], ci95=0.04),
        study.FRESH_ROW: _entry(
            study, [f"results/study/lasmp_plus/seed{k}" for k in (3, 4, 5)], [0.1] * 3, 0.02
        ),
    }
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"methods": methods}))
    rows = study.headline(path).splitlines()
    assert rows[0].startswith("| ours, vs the paper's row | collision rate: ours | paper | height-violation")
    assert len(rows) == 2 + 3 <= 2 + 8  # the paper's recipe and R-S not evaluated: left out
    shipped, fresh, still = rows[2:]
    # the shipped policy is seed 0's own value, not the mean over seeds; each metric beside the paper's
    assert shipped.startswith("| the shipped policy: LAS-MP+ seed 0, 450 iterations, vs the paper's LAS-MP |")
    assert shipped.split(" | ")[1:3] == ["0.036", "0.029 ± 0.03"]
    assert fresh.split(" | ")[1:3] == ["0.100 ± 0.020", "0.029 ± 0.03"] and "fresh seeds 3-5" in fresh
    assert still.split(" | ")[1:3] == ["0.634", "0.612 ± 0.29"]
    assert {r.count("|") for r in rows} == {rows[0].count("|")}


def test_a_truncated_summary_is_named_in_one_line(study, capsys):
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"methods": {"LAS-MP": {"seeds": ["a", "b", "c"]}}})[:-7])  # a copy cut short
    for command in (["table"], ["table", "--headline"], ["ordering"]):
        with pytest.raises(SystemExit) as stop:
            study.main(command)
        assert str(stop.value) == f"error: {path}: truncated: the file ends before its JSON does"
    path.unlink()
    with pytest.raises(
        SystemExit, match="summary.json: no such file; write it with `python scripts/study.py"
    ):
        study.main(["table"])


def test_tables_rewrites_each_documents_table_in_place_and_refuses_a_document_without_one(study):
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(
        json.dumps({"methods": {"Stand Still": _entry(study, ["results/study/stand_still/seed0"], [0.5])}})
    )
    old = study.headline(path).replace("0.500", "0.999")
    old_wide = study.table(path, wide=True, paper=True).replace("0.500", "0.999")
    (study.ROOT / "docs").mkdir()
    (study.ROOT / "README.md").write_text(f"# intro\n\n{old}\n\nafter the table\n")
    (study.ROOT / "docs" / "results.md").write_text(f"text\n{old_wide}")  # a table ending the file
    study.write_tables(path)
    readme = (study.ROOT / "README.md").read_text()
    assert readme == f"# intro\n\n{study.headline(path)}\n\nafter the table\n" and "0.500" in readme
    assert (
        study.ROOT / "docs" / "results.md"
    ).read_text() == f"text\n{study.table(path, wide=True, paper=True)}"
    (study.ROOT / "README.md").write_text("# no table here\n")
    with pytest.raises(ValueError, match="no table with the header"):
        study.write_tables(path)


def test_ordering_calls_two_rows_ordered_only_when_their_three_seed_intervals_are_apart(study):
    three = [f"s/seed{k}" for k in range(3)]
    methods = {
        "LAS-MP+": _entry(study, three, [0.04, 0.05, 0.06], ci95=0.02),  # 0.03-0.07
        "LAS-MP+ w/o alignment command": _entry(study, three, [0.09, 0.10, 0.11], ci95=0.02),  # above
        "LAS-MP+ w/o platform velocity estimates": _entry(study, three, [0.07, 0.08, 0.09], ci95=0.02),
        "LAS-MP+ w/o explicit estimator": _entry(study, three, [0.0, 0.01, 0.02], ci95=0.015),  # below
        "LAS-MP+ w/o explicit estimator, with the history": _entry(study, three[:2], [0.3, 0.4]),
    }
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"methods": methods}))
    rows = study.ordering(path).splitlines()[2:]
    assert [r.split(" | ")[1:4] for r in rows] == [
        ["w/o alignment command", "3", "above"],
        ["w/o platform velocity estimates", "3", "overlap"],  # 0.06-0.10 touches 0.03-0.07
        ["w/o explicit estimator", "3", "below"],
        ["w/o explicit estimator, with the history", "2", "–"],  # two seeds order nothing
    ]
    # against LAS-MP+ on the fresh seeds too, once that row is in the summary
    methods[study.FRESH_ROW] = _entry(study, [f"s/seed{k}" for k in (3, 4, 5)], [0.1, 0.11, 0.12], ci95=0.01)
    path.write_text(json.dumps({"methods": methods}))
    fresh = [r.split(" | ")[1:4] for r in study.ordering(path).splitlines()[2:] if study.FRESH_ROW in r]
    assert fresh[:3] == [
        ["w/o alignment command", "3", "overlap"],  # 0.08-0.12 against 0.10-0.12
        ["w/o platform velocity estimates", "3", "overlap"],  # 0.06-0.10 touches 0.10-0.12
        ["w/o explicit estimator", "3", "below"],
    ]


def curves(study, method, seed, level_up_at):
    """A learning curve whose success climbs to 0.9 and whose level leaves 5 at `level_up_at`."""
    windows = [
        {
            "iterations": [lo, lo + 9],
            "Episode/success_rate": min(0.9, lo / 200),
            "Curriculum/level": 5.0 if lo < level_up_at else 6.0,
        }
        for lo in range(0, 450, 10)
    ]
    d = study.result_dir(method, seed, 450, root=study.FIRST_PASS)
    d.mkdir(parents=True, exist_ok=True)
    (d / "curves_450.json").write_text(json.dumps({"windows": windows}))


def test_compare_tabulates_both_learners_of_the_first_pass_per_seed_from_their_curves_and_first_episodes(
    study, monkeypatch
):
    from lasmp.eval import episodes as ep

    monkeypatch.setattr(study.tables, "FLOAT32_EPISODES", 20)

    def evaluated_episodes(method, seed, collided_first_20):
        t = {c: np.zeros(24) for c in ep.COLUMNS}
        t["episode"] = np.arange(24)
        t["collision_cause"] = np.array([""] * 24, dtype=object)
        t["collided"] = np.r_[np.arange(20) < collided_first_20, np.ones(4)].astype(
            float
        )  # 20-23 not counted
        d = study.result_dir(method, seed, 450, root=study.FIRST_PASS)
        ep.write_csv(d / "episodes.csv", t)
        evaluated(d)

    for seed in (0, 1):
        curves(study, "lasmp", seed, 200 + 10 * seed)
        curves(study, "lasmp_float32", seed, 300)
        evaluated_episodes("lasmp", seed, 5 + 5 * seed)  # an evaluation of more than the first 20
    evaluated_episodes("lasmp_float32", 0, 6)
    table = study.compare().splitlines()
    assert table[0] == "| iterations | fast, seed 0 | fast, seed 1 | float32, seed 0 | float32, seed 1 |"
    assert table[2] == "| 0-49 | 0.10 (level 5) | 0.10 (level 5) | 0.10 (level 5) | 0.10 (level 5) |"
    assert table[6] == "| 200-249 | 0.90 (level 6) | 0.90 (level 6) | 0.90 (level 5) | 0.90 (level 5) |"
    assert table[-2] == "| first window above level 5 | 200 | 210 | 300 | 300 |"
    assert table[-1] == "| collision, Xi_eval's first 20 | 0.250 | 0.500 | 0.300 | not evaluated |"


def test_compare_says_how_to_regenerate_an_evaluated_runs_missing_records(study):
    for seed in (0, 1):
        curves(study, "lasmp", seed, 200)
        curves(study, "lasmp_float32", seed, 300)
    d = study.result_dir("lasmp", 0, 450, root=study.FIRST_PASS)
    evaluated(d)  # its metrics.json, not its per-episode records
    with pytest.raises(SystemExit) as stop:
        study.main(["compare"])
    assert str(stop.value) == (
        f"error: {d / 'episodes.csv.gz'}: no such file; per-episode records are derived data: regenerate "
        f"them with `python -m lasmp.eval.regenerate {d}` (or evaluate.py writes them beside metrics.json)"
    )


def test_compare_names_the_missing_run(study):
    curves(study, "lasmp", 0, 200)
    curves(study, "lasmp", 1, 200)
    evaluated(study.result_dir("lasmp_float32", 0, 450))  # a current-pass directory is not the first pass's
    with pytest.raises(SystemExit, match="entropy_0.01/lasmp_float32/seed0/curves_450.json does not exist"):
        study.compare()


def test_the_new_rows_compare_seed_by_seed_with_the_mean_difference_and_its_interval(study):
    plus, paper = study.ROW_NAMES
    methods = {
        plus: _entry(study, [f"results/study/rows_plus/seed{k}" for k in (20, 21, 22)], [0.03, 0.05, 0.04]),
        # the paper's row in another seed order, one seed short of LAS-MP+'s at first
        paper: _entry(
            study, ["results/study/rows_paper/seed21", "results/study/rows_paper/seed20"], [0.08, 0.06]
        ),
    }
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"methods": methods}))
    rows = study.paired(path).splitlines()
    assert rows[0].startswith("| seed | collision rate: LAS-MP+ − paper |") and len(rows) == 2 + 2 + 1
    assert rows[2].startswith("| 20 | -0.030 |") and rows[3].startswith("| 21 | -0.030 |")
    assert rows[4].startswith("| mean ± 95 % | -0.030 ± 0.000 |")  # two equal differences: no spread
    methods[paper] = _entry(
        study, [f"results/study/rows_paper/seed{k}" for k in (21, 20, 22)], [0.08, 0.06, 0.09]
    )
    path.write_text(json.dumps({"methods": methods}))
    last = study.paired(path).splitlines()[-1]
    # -0.03, -0.03, -0.05: mean -0.0367, sd 0.0115, t(0.975, 2) = 4.303 -> half-width 0.0287
    assert last.startswith("| mean ± 95 % | -0.037 ± 0.029 |")
    del methods[paper]
    path.write_text(json.dumps({"methods": methods}))
    assert study.paired(path) == "the new rows: not both evaluated yet"
