"""What the bad-input tests (tests/bad_inputs/) share: a tiny training, calling an entry point as a
process would, the checks of a clear refusal, and the bad files several of them build.

The bad-input matrix: what a hostile file or a hurried user gives the tools. Each case asserts a
clear error (exit code != 0, a message that names the problem, no traceback) or the correct
behaviour, and that nothing was lost (the files already there are unchanged). Most cases call the
entry points in this process (`lasmp.cli.train.main` after Hydra's composition,
`lasmp.algo.checkpoint.main`, `lasmp.eval.cli.main`); a few run the real CLI where only it shows the
behaviour (Hydra's error printing, signals, another process holding a run's lock).

A plain module beside the tests (pytest puts their directory on sys.path): `from badkit import train`."""

from __future__ import annotations

import contextlib
import errno
import io
import os
import re
import subprocess
import sys
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from hydra import compose, initialize_config_dir
from hydra.errors import CompactHydraException

from lasmp.config.train import register_configs
from lasmp.envs import trajectories as trj
from lasmp.eval import benchmark as bm

ROOT = Path(__file__).resolve().parents[2]
register_configs()


# a tiny run: 4 envs, small networks, the float32 learner (no compilation), one iteration
TINY = {
    "env.num_envs": "4",
    "runner.num_steps_per_env": "5",
    "runner.save_interval": "1",
    "runner.max_iterations": "1",
    "policy.actor_hidden_dims": "[32,32,32]",
    "policy.critic_hidden_dims": "[32,32]",
    "algo.num_mini_batches": "2",
    "algo.num_learning_epochs": "1",
    "algo.precision": "float32",
    "torch_threads": "1",
}


def tiny(*overrides: str) -> list[str]:
    """TINY with `overrides` (key=value) replacing or adding keys."""
    keys = dict(TINY)
    for o in overrides:
        key, value = o.split("=", 1)
        keys[key] = value
    return [f"{k}={v}" for k, v in keys.items()]


@dataclass
class Outcome:
    code: int
    text: str  # stdout and stderr


def call(fn, *args) -> Outcome:
    """Run fn(*args) as a process would: its return value or SystemExit is the exit code; an exception
    escaping it is printed as the interpreter prints it (a traceback), exit code 1."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = fn(*args) or 0
        except SystemExit as stop:
            code = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
        except Exception:
            traceback.print_exc(file=err)
            code = 1
    return Outcome(code, out.getvalue() + err.getvalue())


def _entry(cfg, overrides: list[str]) -> int:
    """What train.py does with a composed config."""
    import lasmp.cli.train as lt

    if hasattr(lt, "main"):
        return lt.main(cfg, overrides)
    # an older train.py, without main(): its train(cfg)
    from lasmp.algo.checkpoint import CheckpointError
    from lasmp.algo.stopping import TrainingInterrupted
    from lasmp.config.checks import ConfigError

    try:
        lt.train(cfg)
    except TrainingInterrupted as stop:
        return 128 + stop.signum
    except (CheckpointError, ConfigError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


def train(overrides: list[str]) -> Outcome:
    """`python train.py OVERRIDES` in this process: Hydra's composition (its errors printed as Hydra
    prints them), then the entry point."""

    def run():
        with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
            try:
                cfg = compose("config", overrides=overrides)
            except CompactHydraException as err:
                print(err, file=sys.stderr)
                if isinstance(err.__cause__, Exception):
                    print(err.__cause__, file=sys.stderr)
                return 1
            return _entry(cfg, overrides)

    return call(run)


def files(d: Path) -> dict[str, bytes]:
    """Every file under d (relative path -> bytes); {} if d does not exist."""
    if not d.exists():
        return {}
    if d.is_file():
        return {d.name: d.read_bytes()}
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def refused(out: Outcome, *patterns: str) -> None:
    """A clear error: exit code != 0, no traceback, and each pattern found in the output."""
    assert out.code != 0, out.text[-3000:]
    assert "Traceback" not in out.text, out.text[-3000:]
    for pattern in patterns:
        assert re.search(pattern, out.text), f"{pattern!r} not in:\n{out.text[-3000:]}"


def succeeded(out: Outcome) -> None:
    assert out.code == 0, out.text[-3000:]
    assert "Traceback" not in out.text, out.text[-3000:]


def progress_lines(out: Outcome) -> list[str]:
    return [line for line in out.text.splitlines() if line.startswith("it ")]


def latest(run: Path) -> Path:
    return max(run.glob("model_*.pt"), key=lambda p: int(p.stem.split("_")[1]))


def train_py(args: list[str], cwd: Path, **kw) -> subprocess.Popen:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        [sys.executable, str(ROOT / "train.py"), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=cwd,
        env=env,
        **kw,
    )


def _write(content: bytes):
    def make(good: Path, dst: Path) -> Path:
        dst.write_bytes(content)
        return dst

    return make


def _truncated(good: Path, dst: Path) -> Path:
    dst.write_bytes(good.read_bytes()[:2000])
    return dst


def _disk_full(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _one_line_naming(out: Outcome, where: str) -> None:
    refused(out, "No space left on device")
    lines = [line for line in out.text.splitlines() if "No space left on device" in line]
    assert len(lines) == 1 and where in lines[0], out.text[-3000:]


def _generated(n: int = 3) -> dict:
    traj = trj.sample(n, trj.ranges_for_split("test"), np.random.default_rng(0))
    return {
        "format": np.array("lasmp-trajectories"),
        "version": np.array(2),
        "kind": np.array("waypoints"),
        **trj.waypoint_arrays(traj),
    }


def _samples(t, poses) -> dict:
    return {
        "format": np.array("lasmp-trajectories"),
        "version": np.array(2),
        "kind": np.array("samples"),
        "t_s": np.asarray(t, dtype=np.float64),
        "poses": np.asarray(poses, dtype=np.float64),
    }


def _line_samples(k: int = 11, duration_s: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, duration_s, k)
    poses = np.zeros((1, k, 6))
    poses[0, :, 0] = 0.1 * t  # 0.1 m/s along x
    poses[0, :, 5] = 0.05 * t
    return t, poses


def _traj_case(kind: str, change=None):
    """A trajectory file: a generated set or a user-made line, its arrays changed by `change`."""

    def make(path: Path) -> Path:
        arrays = _generated() if kind == "waypoints" else _samples(*_line_samples())
        if change is not None:
            change(arrays)
        np.savez(path, **arrays)
        return path

    return make


def _pose_far(a):
    a["poses"][0, 5, 0] = 1e6  # a waypoint 1,000 km away


def _waypoint_far(a):
    a["waypoints"][0, 2, 0] = 1e6


def _raw(content: bytes):
    def make(path: Path) -> Path:
        path.write_bytes(content)
        return path

    return make


def _bench_arrays() -> dict:
    bench = bm.generate(4, 2, seed=0)
    path = Path("bench_base.npz")
    bm.save(path, bench)
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    path.unlink()
    return arrays


def _bench_case(change):
    def make(path: Path) -> Path:
        arrays = _bench_arrays()
        change(arrays)
        np.savez(path, **arrays)
        return path

    return make


def _scale(key, value, index=(0,)):
    def change(a):
        a[key] = a[key].copy()
        a[key][index] = value

    return change


def remount(where: Path, read_only: bool) -> None:
    """Turn a tmpfs from the `tmpfs` fixture (conftest.py) read-only (or writable again) under a running command."""
    subprocess.run(["mount", "-o", f"remount,{'ro' if read_only else 'rw'}", str(where)], check=True)


def evaluate(*argv: str) -> Outcome:
    """evaluate.py's main in this process."""
    from lasmp.eval import cli

    return call(cli.main, list(argv))


def stand_still(bench: Path, out: Path, *extra: str, probe: bool = False) -> Outcome:
    """One Stand Still episode on one env of `bench` into `out`: the smallest whole evaluation (the
    platform probe only with `probe`)."""
    argv = ["--controller", "stand_still", "--benchmark", str(bench), "--num-trajectories", "1"]
    argv += ["--batch-envs", "1", *([] if probe else ["--no-platform-probe"]), "--out", str(out)]
    return evaluate(*argv, *extra)
