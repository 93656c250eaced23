"""The results table: seeds aggregated per method (mean, 95 % t-interval, per-seed values), the
summary file, and the refusals."""

from __future__ import annotations

import json
import math

import pytest
import torch

from lasmp.algo.checkpoint import CHECKPOINT_FORMAT, REQUIRED_KEYS
from lasmp.eval import results_table as rt
from lasmp.eval.metrics import ALL_METRICS, METRICS

T_975_2 = 4.302653  # t_{0.975} with 2 degrees of freedom, from a printed table


def write(root, name, collision, estimator=None, episodes=100, others=0.5):
    d = root / name
    d.mkdir(parents=True)
    metrics = {k: {"mean": others, "std": 0.01} for k in ALL_METRICS}
    metrics["collision_rate"] = {"mean": collision, "std": 0.02}
    result = {"method": name, "benchmark": "b.npz", "num_episodes": episodes, "metrics": metrics}
    if estimator:
        result["estimator"] = estimator
    (d / "metrics.json").write_text(json.dumps(result))
    return d


def test_three_seeds_give_their_mean_and_a_95_percent_t_interval_checked_by_hand(tmp_path):
    dirs = [write(tmp_path, f"seed{k}", c) for k, c in enumerate((0.2, 0.3, 0.4))]
    entry = rt.summary({"LAS-MP": dirs})["methods"]["LAS-MP"]
    m = entry["metrics"]["collision_rate"]
    # mean 0.3; sample std 0.1; half-width t * s / sqrt(3)
    assert m["mean"] == pytest.approx(0.3)
    assert m["ci95"] == pytest.approx(T_975_2 * 0.1 / math.sqrt(3), rel=1e-6)
    assert m["per_seed"] == pytest.approx([0.2, 0.3, 0.4])
    assert entry["seeds"] == [str(d) for d in dirs]
    assert set(entry["metrics"]) == set(ALL_METRICS)


def test_a_single_seed_gives_a_null_interval_in_strict_json(tmp_path, capsys):
    ss = write(tmp_path, "stand_still", 0.65)
    out_json = tmp_path / "study" / "summary.json"
    assert rt.main(["--method", "Stand Still", str(ss), "--json", str(out_json)]) == 0
    text = out_json.read_text()
    assert "NaN" not in text
    summ = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))
    m = summ["methods"]["Stand Still"]["metrics"]["collision_rate"]
    assert m == {"mean": 0.65, "ci95": None, "per_seed": [0.65]}
    assert "| Stand Still | 0.650 |" in capsys.readouterr().out


def test_method_groups_print_mean_plus_minus_ci95_per_method(tmp_path, capsys):
    lasmp = [write(tmp_path, f"lasmp/seed{k}", c) for k, c in enumerate((0.2, 0.3, 0.4))]
    ss = write(tmp_path, "ss", 0.65)
    rt.main(
        [
            "--method",
            "LAS-MP",
            *map(str, lasmp),
            "--method",
            "Stand Still",
            str(ss),
            "--json",
            str(tmp_path / "s.json"),
            "--paper-columns",
        ]
    )
    out = capsys.readouterr().out
    half = T_975_2 * 0.1 / math.sqrt(3)
    assert f"| LAS-MP | 0.300 ± {half:.3f} | 0.500 ± 0.000 |" in out
    assert out.splitlines()[0].count("|") == len(METRICS) + 4  # method, five metrics, seeds, learners
    assert "| Stand Still | 0.650 | 0.500 |" in out and out.splitlines()[3].endswith("| 1 | – |")
    summ = json.loads((tmp_path / "s.json").read_text())
    assert list(summ["methods"]) == ["LAS-MP", "Stand Still"]


def test_results_table_rows_and_refusals(tmp_path, capsys):
    est = {"x_exp_mean_abs_error": {"contact_FR": 0.1, "v_body_x": 0.2}, "l_imp_mean_l2_error": 0.3}
    dirs = [
        write(tmp_path, "ss", 0.65),
        write(tmp_path, "lasmp", 0.25, est),
        write(tmp_path, "noexp", 0.3, {"x_exp_mean_abs_error": {}, "l_imp_mean_l2_error": 0.4}),
    ]
    rt.main(
        [str(d) for d in dirs]
        + ["--labels", "Stand Still", "LAS-MP", "no explicit", "--json", str(tmp_path / "s.json")]
    )
    out = capsys.readouterr().out
    assert "| Stand Still | 0.650 |" in out and "| LAS-MP | 0.250 |" in out  # one seed each: the value alone
    assert "| LAS-MP | 0.100 | 0.200 | 0.300 |" in out  # the estimator table: only methods that estimate
    assert "| no explicit |  |  | 0.400 |" in out and "| Stand Still | 0.650" in out.split("Estimator")[0]
    with pytest.raises(ValueError, match="different benchmarks or episode counts"):
        rt.load_results([dirs[0], write(tmp_path, "short", 0.5, episodes=10)])
    with pytest.raises(ValueError, match="different benchmarks or episode counts"):
        rt.summary({"a": [dirs[0]], "b": [tmp_path / "short"]})
    with pytest.raises(FileNotFoundError, match="run `python evaluate.py"):
        rt.load_results([tmp_path / "missing"])
    with pytest.raises(ValueError, match="2 labels for 1 results"):
        rt.load_results([dirs[0]], ["a", "b"])


def test_the_command_refuses_bad_groups_and_corrupt_results(tmp_path, capsys):
    ss = write(tmp_path, "ss", 0.65)
    for argv, message in (
        (["--method"], "--method needs a NAME and at least one DIR"),
        (["--method", "A"], "give at least one evaluation directory"),
        (["--method", "A", "--json", "x"], "give at least one evaluation directory"),
        (["--method", "A", str(ss), "--method", "A", str(ss)], "a method is named twice"),
        ([], "give --method NAME DIR"),
    ):
        with pytest.raises(SystemExit):
            rt.main(argv)
        assert message in capsys.readouterr().err
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "metrics.json").write_text("{not json")
    with pytest.raises(SystemExit):
        rt.main(["--method", "A", str(tmp_path / "bad"), "--json", str(tmp_path / "s.json")])
    assert "not valid JSON" in capsys.readouterr().err


def save_policy(d, iteration, learner):
    """A policy checkpoint of the format read_checkpoint accepts; `learner`: the recorded parts or None."""
    data = {"format": CHECKPOINT_FORMAT, "kind": "policy", "iter": iteration}
    data.update({k: {} for k in REQUIRED_KEYS if k != "iter"})
    if learner is not None:
        data["learner_precision"] = learner
    torch.save(data, d / f"policy_{iteration}.pt")


def test_the_summary_says_how_each_seeds_learner_computed_from_its_policy_checkpoint(tmp_path):
    bf16, fp32 = ({"precision": "auto", "bf16_autocast": flag} for flag in (True, False))
    dirs = [write(tmp_path, f"seed{k}", 0.1) for k in range(4)]
    save_policy(dirs[0], 449, bf16)
    save_policy(dirs[1], 449, fp32)
    save_policy(dirs[1], 99, bf16)  # an earlier policy beside the latest: the latest speaks
    save_policy(dirs[2], 449, None)  # saved before the learner was recorded
    entry = rt.summary({"LAS-MP": dirs})["methods"]["LAS-MP"]
    assert entry["learner_per_seed"] == ["bfloat16", "float32", None, None]
    assert (
        rt.metrics_table({"methods": {"LAS-MP": entry}}).splitlines()[2].endswith("| 4 | bf16, fp32, –, – |")
    )
