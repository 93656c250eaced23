"""The trajectory command line, `python -m lasmp.envs.trajectories` (stats, plot, generate), run as
a user runs it."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from lasmp.envs import trajectories as T

REPO = Path(__file__).resolve().parents[2]


def _cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "lasmp.envs.trajectories", *args],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_cli_stats_json():
    r = _cli("stats", "--split", "test", "--num", "200", "--seed", "0", "--json")
    assert r.returncode == 0, r.stderr
    st = json.loads(r.stdout)
    assert st["num"] == 200
    for block in [st["overall"], *st["per_n"].values()]:
        for key in T.STAT_COLUMNS:
            assert key in block
    assert set(st["per_n"]) <= {str(n) for n in range(4, 17)}
    assert sum(b["num"] for b in st["per_n"].values()) == 200


def test_cli_bad_arguments():
    r = _cli("stats", "--split", "val")
    assert r.returncode == 2 and "invalid choice" in r.stderr


def test_cli_plot_and_generate(tmp_path):
    out = tmp_path / "traj.png"
    r = _cli("plot", "--out", str(out), "--num", "30")
    assert r.returncode == 0, r.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    f = tmp_path / "set.npz"
    r = _cli("generate", "--split", "train", "--num", "20", "--seed", "5", "--out", str(f))
    assert r.returncode == 0, r.stderr
    loaded = T.load(f)
    ref = T.sample(20, T.TRAIN_RANGES, np.random.default_rng(5))
    np.testing.assert_array_equal(loaded.coeffs, ref.coeffs)
    assert loaded.meta == {"split": "train", "seed": 5, "num": 20}
