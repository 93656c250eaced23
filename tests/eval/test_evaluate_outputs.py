"""Where and how evaluate.py writes its results: an earlier result refused unless forced, the last
line naming the place, an unwritable directory refused at once, the default directory one per
checkpoint file, and missing values written as null."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from testkit import run_script

from lasmp.eval import benchmark as bm
from lasmp.eval import episodes as ep


def run_evaluate(*args, cwd):
    """evaluate.py run as a user runs it; its exit status is the test's to check."""
    return run_script("evaluate.py", *args, cwd=cwd, ok=False)


def strict_load(path):
    """JSON that a strict reader accepts: NaN or Infinity fail the test."""
    return json.loads(Path(path).read_text(), parse_constant=lambda c: pytest.fail(f"{path}: non-strict {c}"))


def tiny_benchmark(tmp_path):
    path = tmp_path / "bench.npz"
    bm.save(path, bm.generate(num_trajectories=4, num_robots=2, seed=0))
    return path


STAND_STILL_2 = ("--controller", "stand_still", "--num-trajectories", "2", "--batch-envs", "2")


def test_evaluate_refuses_an_earlier_result_before_playing_unless_forced(tmp_path):
    bench = tiny_benchmark(tmp_path)
    out_dir = tmp_path / "ev"
    out_dir.mkdir()
    (out_dir / "metrics.json").write_text('{"earlier": true}')
    out = run_evaluate(*STAND_STILL_2, "--benchmark", str(bench), "--out", str(out_dir), cwd=tmp_path)
    assert out.returncode == 2 and f"{out_dir / 'metrics.json'} already exists" in out.stderr
    assert "--force" in out.stderr and "episodes" not in out.stderr  # refused before any episode
    assert json.loads((out_dir / "metrics.json").read_text()) == {"earlier": True}
    out = run_evaluate(
        *STAND_STILL_2,
        "--benchmark",
        str(bench),
        "--out",
        str(out_dir),
        "--force",
        "--no-platform-probe",
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    result = strict_load(out_dir / "metrics.json")  # strict JSON: null, never NaN
    assert result["num_episodes"] == 2 and result["forced_episodes"] is None
    assert np.isnan(ep.read_csv(out_dir / ep.EPISODES_FILE)["forced"]).all()  # no probe: empty cells
    assert out.stdout.splitlines()[-1] == f"results in {out_dir}: metrics.json, metrics.md, episodes.csv.gz"


def test_evaluate_says_last_where_it_wrote_its_results_and_git_ignores_the_default_place(tmp_path):
    """Without --out the results land in eval/<controller> of the working directory: the last line
    printed names it and every file written there, and the repository's .gitignore keeps it out of
    git (tests/test_repository.py checks the pattern against the package's own eval/ folders)."""
    bench = tiny_benchmark(tmp_path)
    out = run_evaluate(*STAND_STILL_2, "--benchmark", str(bench), "--no-platform-probe", cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    where, names = out.stdout.splitlines()[-1].removeprefix("results in ").split(": ")
    assert Path(where) == Path("eval") / "stand_still"
    assert names.split(", ") == ["metrics.json", "metrics.md", ep.EPISODES_FILE]
    assert sorted(p.name for p in (tmp_path / where).iterdir()) == sorted(names.split(", "))


def test_evaluate_fails_at_once_on_an_unwritable_output_directory(tmp_path):
    bench = tiny_benchmark(tmp_path)
    (tmp_path / "a_file").write_text("")
    out = run_evaluate(
        *STAND_STILL_2, "--benchmark", str(bench), "--out", str(tmp_path / "a_file" / "ev"), cwd=tmp_path
    )
    assert out.returncode == 2 and "cannot write results to" in out.stderr and "a_file" in out.stderr
    assert "Traceback" not in out.stderr and "episodes" not in out.stderr


def test_the_default_output_directory_is_one_per_checkpoint_file_even_where_names_repeat(tmp_path):
    """results/study/lasmp/seed0/policy_449.pt and results/study/lasmp_centre/seed0/policy_449.pt
    have the same run-directory and file names; their default directories still differ. The same
    file always lands in the same place, however it is named on the command line."""
    import hashlib
    from types import SimpleNamespace

    from lasmp.eval.outdir import default_out_dir

    def out_dir(checkpoint, controller=None):
        return default_out_dir(SimpleNamespace(checkpoint=checkpoint, controller=controller), Path("eval"))

    def run_hash(run):
        return hashlib.sha256(str(run.resolve()).encode()).hexdigest()[:8]

    study = tmp_path / "results" / "study"
    a = out_dir(str(study / "lasmp" / "seed0" / "policy_449.pt"))
    b = out_dir(str(study / "lasmp_centre" / "seed0" / "policy_449.pt"))
    assert a != b
    assert a == Path(f"eval/seed0-{run_hash(study / 'lasmp' / 'seed0')}/policy_449")
    assert out_dir(str(study / "lasmp" / "seed0" / ".." / "seed0" / "policy_449.pt")) == a
    assert out_dir(str(study / "lasmp" / "seed0" / "policy_450.pt")).parent == a.parent  # one run, one folder
    assert out_dir(None, "stand_still") == Path("eval/stand_still")
    rs = tmp_path / "rs_run"
    assert out_dir(str(rs / "model_9.pt"), "rs_oracle") == Path(
        f"eval/rs_run-{run_hash(rs)}/model_9_rs_oracle"
    )
    run = tmp_path / "runs" / "seed2"
    run.mkdir(parents=True)
    for k in (9, 10):
        (run / f"model_{k}.pt").write_text("")
    assert out_dir(str(run)) == Path(f"eval/seed2-{run_hash(run)}/model_10")  # a run directory: its latest


def test_metrics_json_writes_missing_values_as_null(tmp_path):
    from lasmp.eval.report import write_results

    result = {
        "method": "m",
        "num_episodes": 1,
        "std_over": "1 batch",
        "wall_time_s": 1.0,
        "metrics": {
            "collision_rate": {"mean": 1.0, "std": 0.0},
            "power_w": {"mean": float("nan"), "std": np.float64("nan")},
        },
        "extra": [np.inf, np.int64(3)],
    }
    write_results(tmp_path, result)
    back = strict_load(tmp_path / "metrics.json")
    assert back["metrics"]["power_w"] == {"mean": None, "std": None} and back["extra"] == [None, 3]
    assert "| power (W) | n/a | n/a |" in (tmp_path / "metrics.md").read_text()
