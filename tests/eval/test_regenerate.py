"""Per-episode records as derived data: evaluate stores their digest in metrics.json, and
`python -m lasmp.eval.regenerate RUN_DIR` makes them again from the run's committed policy (full or
light) and checks them against it; the light checkpoint plays the full one's actions; a reader of a
missing record says how to make it again; git keeps the records and the export folder out."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from testkit import tiny

from lasmp.algo.checkpoint import policy_checkpoint
from lasmp.algo.checkpoint.light import LIGHT_KIND, convert_in_place
from lasmp.algo.checkpoint.light import main as light_main
from lasmp.cli.train import train
from lasmp.deploy import load_policy
from lasmp.eval import benchmark as bm
from lasmp.eval import breakdown as bd
from lasmp.eval import episodes as ep
from lasmp.eval import regenerate as rg
from lasmp.eval.cli import main as evaluate

ROOT = Path(__file__).resolve().parents[2]
FILES = (ep.EPISODES_FILE, ep.MIRROR_EPISODES_FILE)


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory):
    """A result directory as the study lays one out: a tiny 2-iteration policy's `policy_1.pt`,
    evaluated there on 6 episodes of a tiny benchmark in batches of 3 envs, with the mirror twins of
    the first 2. Returns (directory, {file: its bytes})."""
    tmp = tmp_path_factory.mktemp("regenerate")
    train(tiny(tmp / "run", plain=True))
    result = tmp / "result"
    result.mkdir()
    policy_checkpoint(tmp / "run" / "model_1.pt", result / "policy_1.pt")
    bench = tmp / "bench.npz"
    bm.save(bench, bm.generate(num_trajectories=6, num_robots=2, seed=0))
    args = ["--checkpoint", str(result / "policy_1.pt"), "--benchmark", str(bench), "--batch-envs", "3"]
    assert evaluate([*args, "--mirror", "2", "--no-platform-probe", "--out", str(result)]) == 0
    return result, {name: (result / name).read_bytes() for name in FILES}


def stored(result: Path) -> dict:
    return json.loads((result / "metrics.json").read_text())


def test_evaluate_stores_the_digest_of_each_record_it_writes_and_the_options_to_replay_it(evaluated):
    result, _ = evaluated
    saved = stored(result)
    assert set(saved[ep.DIGEST_KEY]) == set(FILES)
    for name in FILES:
        assert saved[ep.DIGEST_KEY][name] == ep.file_digest(result / name)
    assert saved[ep.DIGEST_KEY][ep.EPISODES_FILE]["rows"] == 6
    assert (saved["batch_envs"], saved["torch_threads"]) == (3, 1)


def test_a_deleted_record_is_regenerated_from_the_policy_to_the_byte_and_matches_the_stored_digest(
    evaluated, capsys
):
    result, original = evaluated
    for name in FILES:
        (result / name).unlink()
    assert rg.main([str(result)]) == 0
    for name in FILES:
        assert (result / name).read_bytes() == original[name]
    assert "the records match metrics.json's digest" in capsys.readouterr().out
    assert not list(result.glob(".regenerate-*"))  # its scratch directory is gone
    assert rg.main([str(result)]) == 2  # the records are there: not written over without --force
    assert "exists: give --force" in capsys.readouterr().err


def test_the_light_checkpoint_is_smaller_plays_the_same_actions_and_regenerates_the_same_records(evaluated):
    result, original = evaluated
    path = result / "policy_1.pt"
    full = load_policy(path)
    before, after = convert_in_place(path)
    assert after < before  # the critic gone (at the study's size: 1.83 MB -> 0.96 MB)
    light = load_policy(path)
    assert light.checkpoint["kind"] == LIGHT_KIND and light.checkpoint["critic_state_dict"] == {}
    layout = full.checkpoint["obs_layout"]
    obs = TensorDict(
        {k: torch.randn(16, *v, generator=torch.Generator().manual_seed(1)) for k, v in layout.items()},
        batch_size=[16],
    )
    with torch.inference_mode():
        assert torch.equal(light.policy(obs), full.policy(obs))
    for name in FILES:
        (result / name).unlink()
    assert rg.main([str(result)]) == 0  # evaluate accepts it, and the episodes come out the same
    for name in FILES:
        assert (result / name).read_bytes() == original[name]
    assert convert_in_place(path) == (after, after)  # a light one stays as it is


def test_the_light_tool_refuses_a_full_checkpoint_in_one_line(evaluated, capsys, tmp_path):
    result, _ = evaluated
    full = result.parent / "run" / "model_1.pt"
    assert light_main([str(full), str(tmp_path / "light.pt")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "a full checkpoint" in err and len(err.strip().splitlines()) == 1


def test_a_regeneration_that_differs_names_the_columns_and_metrics_and_writes_nothing_into_the_run(
    evaluated, capsys
):
    result, original = evaluated
    text = (result / "metrics.json").read_text()
    saved = json.loads(text)
    digest = saved[ep.DIGEST_KEY][ep.EPISODES_FILE]
    digest["sha256"], digest["columns"]["power_w"] = "0" * 64, "0" * 16
    saved["metrics"]["power_w"]["mean"] *= 1.01
    (result / "metrics.json").write_text(json.dumps(saved))
    try:
        for name in FILES:
            (result / name).unlink()
        assert rg.main([str(result)]) == 1
        err = capsys.readouterr().err
        assert f"{ep.EPISODES_FILE} differs from its digest in power_w\n" in err
        assert "power_w: " in err and "(9.9" in err  # how far the metric moved, relative
        assert not any((result / name).exists() for name in FILES)
        kept = result.parent / f"{result.name}.regenerated"
        assert (kept / ep.EPISODES_FILE).read_bytes() == original[ep.EPISODES_FILE]
    finally:
        (result / "metrics.json").write_text(text)
        for name in FILES:
            (result / name).write_bytes(original[name])


def test_the_digest_of_records_is_the_same_from_the_table_and_from_its_file_and_names_a_changed_column(
    tmp_path,
):
    n = 5
    table = {c: np.linspace(0.1, 1.0, n) / 3 for c in ep.COLUMNS}  # repr'd to 17 digits
    table["episode"] = np.arange(n)
    table["collision_cause"] = np.array(["", "trunk", "", "FR_calf+below_top", ""], dtype=object)
    table["power_w"][2] = np.nan  # an empty cell
    digest = ep.table_digest(table)
    for name in ("e.csv", "e.csv.gz"):
        ep.write_csv(tmp_path / name, table)
        assert ep.file_digest(tmp_path / name) == digest
    changed = {**table, "power_w": table["power_w"].copy()}
    changed["power_w"][0] += 1e-15  # the last digit of one cell
    assert ep.digest_differences(digest, ep.table_digest(changed)) == ["power_w"]
    assert ep.digest_differences(digest, digest) == []


def test_store_digest_records_the_files_there_once_and_refuses_one_that_differs(evaluated, tmp_path, capsys):
    result, _ = evaluated
    copy = tmp_path / "copy"
    copy.mkdir()
    saved = stored(result)
    expected = saved.pop(ep.DIGEST_KEY)
    (copy / "metrics.json").write_text(json.dumps(saved))
    for name in FILES:
        (copy / name).write_bytes((result / name).read_bytes())
    assert rg.main(["--store-digest", str(copy)]) == 0
    assert stored(copy)[ep.DIGEST_KEY] == expected
    assert (
        rg.main(["--store-digest", str(copy)]) == 0 and "holds the digest already" in capsys.readouterr().out
    )
    ep.write_csv(copy / ep.EPISODES_FILE, {**ep.read_csv(copy / ep.EPISODES_FILE), "power_w": np.zeros(6)})
    assert rg.main(["--store-digest", str(copy)]) == 2
    assert "differs from the digest metrics.json holds" in capsys.readouterr().err


def test_a_missing_record_is_said_in_one_line_with_the_command_that_regenerates_it(tmp_path, capsys):
    assert bd.main([str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert f"regenerate them with `python -m lasmp.eval.regenerate {tmp_path}`" in err


def test_git_keeps_the_records_under_results_and_the_export_folder_out():
    paths = [
        "results/study/x/seed0/episodes.csv.gz",
        "results/x/mirror/episodes_mirror.csv.gz",
        "deploy/policy.onnx",
    ]
    out = subprocess.run(["git", "check-ignore", *paths], cwd=ROOT, capture_output=True, text=True)
    assert out.stdout.split() == paths
    tracked = subprocess.run(
        ["git", "ls-files", "*episodes.csv.gz"], cwd=ROOT, capture_output=True, text=True
    )
    # the real-motion suite's records stay: regenerate replays Xi_eval evaluations only
    assert all(p.startswith("results/real_motion/") for p in tracked.stdout.split())
    kept = ["results/real_motion/x/episodes.csv.gz"]
    assert subprocess.run(["git", "check-ignore", *kept], cwd=ROOT, capture_output=True).returncode == 1


def test_the_policy_is_found_beside_the_evaluation_above_it_or_in_the_r_s_runs_directory(tmp_path):
    seed = tmp_path / "study" / "lasmp_plus" / "seed0"
    (seed / "curve" / "it449").mkdir(parents=True)
    (seed / "policy_449.pt").write_bytes(b"")
    older = {"method": "LAS-MP checkpoint runs/x/model_449.pt (lasmp)"}  # no "checkpoint" key yet
    assert rg.committed_policy(seed, older) == seed / "policy_449.pt"
    assert rg.committed_policy(seed / "curve" / "it449", older) == seed / "policy_449.pt"
    rs, oracle = tmp_path / "study" / "rs" / "seed1", tmp_path / "study" / "rs_oracle" / "seed1"
    oracle.mkdir(parents=True)
    rs.mkdir(parents=True)
    (rs / "policy_449.pt").write_bytes(b"")
    assert (
        rg.committed_policy(oracle, {"method": "rs_oracle (runs/rs/seed1/model_449.pt)"})
        == rs / "policy_449.pt"
    )
    with pytest.raises(rg.RegenerateError, match="no policy_149.pt in .* give --checkpoint PATH"):
        rg.committed_policy(seed, {"method": "m", "checkpoint": "runs/x/model_149.pt"})


def test_the_benchmark_must_be_the_one_evaluated_or_one_evaluate_makes_on_first_use(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # benchmarks/ absent: Xi_eval's and the validation set's are made on use
    for name in (bm.XI_EVAL.path, bm.VALIDATION.path):
        rg.check_benchmark({"benchmark": name, "benchmark_sha256": "0" * 64})
    with pytest.raises(rg.RegenerateError, match="mine.npz does not exist"):
        rg.check_benchmark({"benchmark": "mine.npz"})
    (tmp_path / "mine.npz").write_bytes(b"other")
    with pytest.raises(rg.RegenerateError, match="is not the benchmark evaluated"):
        rg.check_benchmark({"benchmark": "mine.npz", "benchmark_sha256": "0" * 64})
