"""Regenerate an evaluation's per-episode records from its committed policy, and check them.

    python -m lasmp.eval.regenerate RUN_DIR [RUN_DIR ...] [--checkpoint PATH] [--force] [--keep-mismatch]
    python -m lasmp.eval.regenerate --store-digest RUN_DIR [RUN_DIR ...]   # before removing the records

The per-episode records (`episodes.csv.gz`, and a mirror evaluation's `episodes_mirror.csv.gz`) are
derived data: 2 MB per 10,000 episodes, over a hundred evaluations, they would make most of a clone.
The repository keeps each evaluation's metrics.json, which holds a digest of its records
(`lasmp.eval.episodes.table_digest`), and the policy it evaluated; this replays that evaluation
(evaluate.py with the options metrics.json recorded: the benchmark, checked by its SHA-256, the
episodes, the seed, the batch of envs, the mirror twins, the platform probe) into a scratch directory,
then checks the result twice:
- the records against the stored digest, column by column (the columns it covers: one added to the
  records since, like the state at failure, is written but not compared): equal on the CPU that evaluated, where
  physics and policy run the same instructions;
- the metrics recomputed from them against metrics.json's, to a relative 1e-9: what a reader of the
  tables relies on.
Only when both match are the files put into RUN_DIR (an existing one only with --force). Where they
differ (another CPU's floating point, a physics change since), it says which columns and how far each
metric moved, and writes nothing there unless --keep-mismatch (the scratch directory is named).

The policy: `--checkpoint`, else the `policy_<N>.pt` of the iteration evaluated (N from the
checkpoint path metrics.json recorded) in RUN_DIR or the directory above it (a mirror evaluation's
subdirectory); Stand Still needs none. The records a digest was taken of before this tool existed
(the study's) are checked against that digest in the same way.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from lasmp.eval import episodes as ep
from lasmp.eval.report import dumps
from lasmp.io.atomic import atomic_open
from lasmp.io.inputs import file_sha256

METRICS_FILE = "metrics.json"
RELATIVE_TOLERANCE = 1e-9  # metrics recomputed from the same records agree to rounding
DEFAULT_BATCH_ENVS = 1024  # evaluate.py's defaults, for a metrics.json written before it recorded them
DEFAULT_TORCH_THREADS = 1


class RegenerateError(ValueError):
    """A run directory cannot be regenerated; the message says why in one line."""


def read_result(run_dir: Path) -> dict:
    """`run_dir`'s metrics.json, a Xi_eval result that holds the digest of its records."""
    from lasmp.eval.results_table import read_result as read_xi_result

    path = run_dir / METRICS_FILE
    try:
        result = read_xi_result(run_dir)
    except (FileNotFoundError, ValueError) as err:  # missing, not JSON, a suite's (no regeneration yet)
        raise RegenerateError(str(err)) from None
    if ep.DIGEST_KEY not in result:
        raise RegenerateError(
            f"{path}: holds no digest of its records ({ep.DIGEST_KEY}), so a regeneration could not be "
            "checked; evaluate it again (evaluate.py writes the digest)"
        )
    return result


def controller_of(result: dict) -> tuple[str | None, bool]:
    """(evaluate.py's --controller or None for a LAS-MP policy, whether it needs a checkpoint)."""
    method = result["method"]
    if method == "stand_still":
        return "stand_still", False
    m = re.match(r"(rs|rs_oracle) \(", method)
    return (m.group(1) if m else None), True


def committed_policy(run_dir: Path, result: dict) -> Path:
    """The policy checkpoint of the evaluated iteration (from the checkpoint path metrics.json recorded,
    or its method's, in older ones) in `run_dir` or the two directories above it (a mirror or learning-
    curve evaluation inside a run's directory); R-S with the oracle command also looks in the R-S run's
    own directory (the study's rs/ beside rs_oracle/)."""
    recorded = result.get("checkpoint") or next(iter(re.findall(r"(\S+\.pt)\b", result["method"])), "")
    m = re.search(r"_(\d+)\.pt$", recorded)
    if m is None:
        raise RegenerateError(
            f"{run_dir / METRICS_FILE}: its checkpoint {recorded!r} names no iteration: give --checkpoint PATH"
        )
    name = f"policy_{m.group(1)}.pt"
    places = [run_dir, run_dir.parent, run_dir.parent.parent]
    if run_dir.parent.name == "rs_oracle":
        places.append(run_dir.parent.parent / "rs" / run_dir.name)
    for where in places:
        if (where / name).is_file():
            return where / name
    raise RegenerateError(
        f"no {name} in {run_dir} or the directories above it (the policy {recorded} was evaluated from, "
        f"not committed): give --checkpoint PATH{history_hint(run_dir)}"
    )


def history_hint(run_dir: Path) -> str:
    """Where the records were last committed, for a run whose policy never was: '; or restore them
    as committed: git checkout REV -- FILES', or nothing outside a git checkout."""
    names = [str(run_dir / n) for n in (ep.EPISODES_FILE, ep.MIRROR_EPISODES_FILE)]
    try:
        out = subprocess.run(
            ["git", "log", "-1", "--format=%h", "--diff-filter=D", "--", *names],
            capture_output=True,
            text=True,
            timeout=30,
        )
    except (OSError, subprocess.SubprocessError):
        return ""
    rev = out.stdout.strip()
    if out.returncode or not rev:
        return ""
    there = [n for n in names if not subprocess.run(["git", "cat-file", "-e", f"{rev}^:{n}"]).returncode]
    return f"; or restore the records as committed: git checkout {rev}^ -- {' '.join(there)}" if there else ""


def evaluate_args(run_dir: Path, result: dict, checkpoint: Path | None, out: Path) -> list[str]:
    """evaluate.py's command line that replays the evaluation of `run_dir` into `out`."""
    controller, needs_policy = controller_of(result)
    args = []
    if controller is not None:
        args += ["--controller", controller]
    if needs_policy:
        args += ["--checkpoint", str(checkpoint or committed_policy(run_dir, result))]
    bench = Path(result["benchmark"])
    args += [
        "--benchmark",
        str(bench),
        "--num-trajectories",
        str(result["num_episodes"]),
        "--seed",
        str(result.get("seed", 0)),
        "--batch-envs",
        str(result.get("batch_envs") or DEFAULT_BATCH_ENVS),
        "--torch-threads",
        str(result.get("torch_threads") or DEFAULT_TORCH_THREADS),
        "--out",
        str(out),
    ]
    if result.get("forced_episodes") is None:
        args.append("--no-platform-probe")
    if result.get("mirror"):
        args += ["--mirror", str(result["mirror"]["episodes"])]
    return args


def check_benchmark(result: dict) -> None:
    """The benchmark file must be the one evaluated (its SHA-256), or be one that evaluate.py makes on
    first use (Xi_eval's, the validation set's: its hash is checked after the replay)."""
    from lasmp.eval.benchmark import SETS

    bench = Path(result["benchmark"])
    if not bench.is_file():
        if any(bench == Path(which.path) for which in SETS.values()):
            return
        raise RegenerateError(f"benchmark file {bench} does not exist (metrics.json names it)")
    got = file_sha256(bench)
    if result.get("benchmark_sha256") and got != result["benchmark_sha256"]:
        raise RegenerateError(
            f"{bench} is not the benchmark evaluated (SHA-256 {got[:12]}..., metrics.json "
            f"{result['benchmark_sha256'][:12]}...)"
        )


def metric_differences(stored: dict, got: dict) -> list[str]:
    """'name: stored -> regenerated (relative difference)' for each metric mean that moved."""
    out = []
    for name, m in stored["metrics"].items():
        a, b = m.get("mean"), (got["metrics"].get(name) or {}).get("mean")
        if a is None and b is None:
            continue
        if a is None or b is None or abs(a - b) > RELATIVE_TOLERANCE * max(abs(a), abs(b), 1e-12):
            rel = abs(a - b) / max(abs(a), 1e-12) if a is not None and b is not None else float("nan")
            out.append(f"{name}: {a} -> {b} ({rel:.2e} relative)")
    return out


def _differences(digest: dict, replayed: Path) -> list[str]:
    """The columns of the stored `digest` whose records differ in the replay; columns added to the
    records since the digest was taken are not compared (the digest cannot speak for them)."""
    try:
        got = ep.file_digest(replayed, list(digest["columns"]))
    except ep.EpisodesFileError:  # the replay lacks one of them: every column, the lacking one named
        got = ep.file_digest(replayed)
    return ep.digest_differences(digest, got)


def regenerate(run_dir: Path, checkpoint: Path | None, force: bool, keep_mismatch: bool) -> int:
    result = read_result(run_dir)
    stored = result[ep.DIGEST_KEY]
    there = [name for name in stored if (run_dir / name).exists()]
    if there and not force:
        raise RegenerateError(f"{run_dir / there[0]} exists: give --force to write over it")
    check_benchmark(result)
    from lasmp.eval.cli import main as evaluate_main

    scratch = Path(tempfile.mkdtemp(prefix=".regenerate-", dir=run_dir))
    out = scratch / "eval"
    start = time.perf_counter()
    try:
        args = evaluate_args(run_dir, result, checkpoint, out)
        print(f"regenerating {run_dir}: evaluate.py {' '.join(args)}", flush=True)
        code = evaluate_main(args)
        if code != 0:
            raise RegenerateError(f"evaluate.py ended with exit code {code}")
        replay = json.loads((out / METRICS_FILE).read_text())
        if result.get("benchmark_sha256") and replay["benchmark_sha256"] != result["benchmark_sha256"]:
            raise RegenerateError(f"the benchmark made here differs from the one {run_dir} evaluated")
        differ = {name: _differences(digest, out / name) for name, digest in stored.items()}
        moved = metric_differences(result, replay)
        seconds = time.perf_counter() - start
        if not any(differ.values()) and not moved:
            for name in stored:
                install(out / name, run_dir / name)
            digests = ", ".join(f"{name} {digest['sha256'][:16]}" for name, digest in stored.items())
            print(
                f"{run_dir}: the records match metrics.json's digest ({digests}) and its metrics; "
                f"written in {seconds:.0f} s",
                flush=True,
            )
            return 0
        for name, columns in differ.items():
            if columns:
                print(f"{run_dir}: {name} differs from its digest in {', '.join(columns)}", file=sys.stderr)
        for line in moved:
            print(f"{run_dir}: {line}", file=sys.stderr)
        if keep_mismatch:
            for name in stored:
                install(out / name, run_dir / name)
            print(f"{run_dir}: written all the same (--keep-mismatch), in {seconds:.0f} s", file=sys.stderr)
        else:
            kept = run_dir.parent / f"{run_dir.name}.regenerated"
            n = 1
            while kept.exists():  # never over an earlier replay
                n += 1
                kept = run_dir.parent / f"{run_dir.name}.regenerated-{n}"
            shutil.move(str(out), kept)
            print(
                f"{run_dir}: not regenerated to the bit (another CPU, or the code changed since); the "
                f"replay is in {kept}",
                file=sys.stderr,
            )
        return 1
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def store_digest(run_dir: Path) -> str:
    """Write the digest of `run_dir`'s episodes files (those there: episodes.csv.gz, a mirror
    evaluation's episodes_mirror.csv.gz) into its metrics.json, before the files are removed: an
    evaluation made before evaluate.py stored it. A digest already there must agree (never replaced)."""
    path = run_dir / METRICS_FILE
    if not path.is_file():
        raise RegenerateError(f"{path}: no such file")
    result = json.loads(path.read_text())
    names = [n for n in (ep.EPISODES_FILE, ep.MIRROR_EPISODES_FILE) if (run_dir / n).is_file()]
    if not names:
        raise RegenerateError(f"{run_dir}: no {ep.EPISODES_FILE} to take a digest of")
    digests = {n: ep.file_digest(run_dir / n) for n in names}
    stored = result.get(ep.DIGEST_KEY) or {}
    for name, digest in digests.items():
        if name in stored and stored[name]["sha256"] != digest["sha256"]:
            raise RegenerateError(f"{run_dir / name}: differs from the digest metrics.json holds")
    if all(n in stored for n in digests):
        return f"{run_dir}: metrics.json holds the digest already"
    result[ep.DIGEST_KEY] = {**stored, **digests}
    with atomic_open(path, "w") as f:
        f.write(dumps(result))
    return f"{run_dir}: stored the digest of {', '.join(names)}"


def install(src: Path, dst: Path) -> None:
    with open(src, "rb") as f, atomic_open(dst, "wb") as g:
        shutil.copyfileobj(f, g)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run_dirs", nargs="+", type=Path, metavar="RUN_DIR", help="an evaluation's directory")
    p.add_argument("--checkpoint", type=Path, help="the policy evaluated (default: the run's policy_<N>.pt)")
    p.add_argument("--force", action="store_true", help="write over records already there")
    p.add_argument(
        "--store-digest",
        action="store_true",
        help="regenerate nothing: store the digest of the records there in metrics.json (before removing them)",
    )
    p.add_argument(
        "--keep-mismatch",
        action="store_true",
        help="write the records even where they differ from the digest",
    )
    args = p.parse_args(argv)
    worst = 0
    for run_dir in args.run_dirs:
        try:
            if args.store_digest:
                print(store_digest(run_dir))
                continue
            worst = max(worst, regenerate(run_dir, args.checkpoint, args.force, args.keep_mismatch))
        except RegenerateError as err:
            print(f"error: {err}", file=sys.stderr)
            worst = 2
    return worst


if __name__ == "__main__":
    raise SystemExit(main())
