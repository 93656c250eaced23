"""The probes that play a checkpoint (scripts/tilt_probe.py, scripts/curriculum_probe.py) on a tiny
trained run: what they report, and the arguments they refuse."""

from __future__ import annotations

import json

import numpy as np
import pytest
from testkit import load_script


def test_tilt_probe_plays_the_first_benchmark_episodes_and_splits_their_world_tilt(run_dir, tmp_path):
    from lasmp.eval import benchmark as bm

    probe = load_script("scripts/tilt_probe.py")
    bench, out = tmp_path / "bench.npz", tmp_path / "tilt.json"
    bm.save(bench, bm.generate(2, 2))
    assert probe.main([str(run_dir), "--episodes", "2", "--benchmark", str(bench), "--json", str(out)]) == 0
    figures = json.loads(out.read_text())
    assert figures["episodes"] == 2 and 0 <= figures["episodes_to_time_out"] <= 2
    # the lean and the swing bound the tilt (a triangle inequality per step, averaged)
    assert figures["tilt"] <= figures["lean"] + figures["swing"] + 1e-9
    assert np.isfinite(figures["gain_on_deck_tilt"])  # Xi_eval's decks tilt
    with pytest.raises(SystemExit) as err:
        probe.main([str(run_dir), "--episodes", "0"])
    assert err.value.code == 2


def test_curriculum_probe_plays_one_episode_per_env_and_zero_noise_sampling_equals_the_mean(
    run_dir, tmp_path
):
    probe = load_script("scripts/curriculum_probe.py")
    out = tmp_path / "probe.json"
    assert probe.main([str(run_dir), "--envs", "2", "--std-scales", "0", "--json", str(out)]) == 0
    results = json.loads(out.read_text())
    modes = ("mean", "sampled", "sampled_std_x0", "stand_still")
    assert all(results[m]["episodes"] == 2 and results[m]["level"] == 5 for m in modes)
    # the same envs and seed in every mode: with the std scaled to 0 the draws are the mean actions
    assert results["sampled_std_x0"] == results["mean"]
    with pytest.raises(SystemExit) as err:
        probe.main([str(run_dir), "--envs", "0"])
    assert err.value.code == 2
