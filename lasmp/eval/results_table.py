"""The results tables (docs/results.md) from evaluation outputs (`evaluate.py --out DIR` on Xi_eval), over seeds.

    python -m lasmp.eval.results_table --method NAME DIR [DIR ...] [--method NAME DIR ...] [--json PATH]
    python -m lasmp.eval.results_table DIR [DIR ...] [--labels NAME ...]      # one seed per method

Each `--method NAME DIR [DIR ...]` names a method and its seeds: one evaluation directory (with a
metrics.json) per training seed, e.g. `--method LAS-MP results/study/lasmp/seed0 results/study/lasmp/seed1
results/study/lasmp/seed2`. (Chosen over a fixed study layout: any directory names work, and a method
with a single run, Stand Still, is one directory.) The plain form (positional DIRs) is one method per
directory, labelled by `--labels` or the directory's name.

Per method and metric: the mean over seeds of each seed's benchmark mean, a 95 % t-interval
half-width over seeds (t_{0.975, n-1} s / sqrt(n), scipy.stats.t; null for a single seed: no
spread can be estimated from one), and the per-seed values. Printed as a Markdown table
`mean ± ci95` (a single seed: its value alone) and the number of seeds, with, for the methods that estimate, the
estimators' errors averaged over seeds. Written (atomically, strict JSON) to --json, by default
results/study/summary.json; a file already there is refused unless --force (the name is claimed
before the results are read, lasmp.io.atomic.claim_output):

    {"methods": {NAME: {"seeds": [DIR, ...],
                        "learner_per_seed": ["bfloat16" | "float32" | null, ...],
                        "metrics": {METRIC: {"mean": m, "ci95": h or null, "per_seed": [v, ...]}}}}}

`learner_per_seed` says how each seed's learner computed (bfloat16 autocast or float32), read from the
policy checkpoint (`policy_<it>.pt`) beside its metrics.json: `algo.precision=auto` chooses by the
machine, so seeds trained on different CPUs can differ, and a reader must see it. null: no policy
checkpoint there (Stand Still) or one saved before the learner was recorded.

Every result must come from the same benchmark and number of episodes.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
from scipy import stats

from lasmp.algo.checkpoint import read_checkpoint
from lasmp.eval.metrics import ALL_METRICS, METRICS
from lasmp.eval.report import LABELS, atomic_write_text, dumps
from lasmp.io.atomic import claim_output

DEFAULT_JSON = Path("results") / "study" / "summary.json"


def read_result(d) -> dict:
    """The `metrics.json` of directory `d`, checked to be a Xi_eval benchmark result."""
    path = Path(d) / "metrics.json"
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist: run `python evaluate.py ... --out {d}` first")
    try:
        result = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ValueError(f"{path}: not valid JSON ({err})") from None
    if not isinstance(result, dict) or "metrics" not in result or "suite" in result:
        raise ValueError(f"{path}: not a Xi_eval benchmark result (the suite has its own table)")
    return result


def load_results(result_dirs: list, labels: list[str] | None = None) -> tuple[list[dict], list[str]]:
    """The `metrics.json` of each directory and its label; refuses mixed benchmarks or episode counts."""
    results = [read_result(d) for d in result_dirs]
    labels = labels or [Path(d).name for d in result_dirs]
    if len(labels) != len(results):
        raise ValueError(f"{len(labels)} labels for {len(results)} results")
    check_same_benchmark(results)
    return results, labels


def check_same_benchmark(results: list[dict]) -> None:
    keys = {(r["benchmark"], r["num_episodes"]) for r in results}
    if len(keys) > 1:
        raise ValueError(f"the results come from different benchmarks or episode counts: {sorted(keys)}")


def _iteration(path: Path) -> int:
    tail = path.stem.removeprefix("policy_")
    return int(tail) if tail.isdigit() else -1


def learner_of(d) -> str | None:
    """'bfloat16' or 'float32': how the learner of the policy checkpoint in directory `d` computed
    (its latest `policy_<it>.pt`); None without one, or for a checkpoint that did not record it."""
    policies = sorted(Path(d).glob("policy_*.pt"), key=_iteration)
    if not policies:
        return None
    ran = read_checkpoint(policies[-1]).get("learner_precision") or {}
    if "bf16_autocast" not in ran:
        return None
    return "bfloat16" if ran["bf16_autocast"] else "float32"


def t_interval(values) -> tuple[float | None, float | None]:
    """(mean, 95 % t-interval half-width) of per-seed values; (mean, None) for one value; (None, None)
    for none. Values that are missing (None or NaN) are left out."""
    v = np.array([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    if len(v) == 0:
        return None, None
    if len(v) == 1:
        return float(v[0]), None
    half = stats.t.ppf(0.975, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v))
    return float(v.mean()), float(half)


def summarize_method(results: list[dict], seeds: list[str]) -> dict:
    """One method's entry of summary.json from its seeds' results."""
    metrics = {}
    for key in ALL_METRICS:
        per_seed = [r["metrics"].get(key, {}).get("mean") for r in results]
        if all(v is None for v in per_seed):
            continue  # an older result without this column
        mean, half = t_interval(per_seed)
        metrics[key] = {"mean": mean, "ci95": half, "per_seed": per_seed}
    entry = {
        "seeds": [str(s) for s in seeds],
        "learner_per_seed": [learner_of(s) for s in seeds],
        "metrics": metrics,
    }
    est = [r["estimator"] for r in results if r.get("estimator")]
    if est:
        dims = list(dict.fromkeys(d for e in est for d in e["x_exp_mean_abs_error"]))
        entry["estimator"] = {
            "x_exp_mean_abs_error": {
                d: float(
                    np.mean([e["x_exp_mean_abs_error"][d] for e in est if d in e["x_exp_mean_abs_error"]])
                )
                for d in dims
            },
            "l_imp_mean_l2_error": _mean_or_none([e.get("l_imp_mean_l2_error") for e in est]),
        }
    return entry


def _mean_or_none(values) -> float | None:
    v = [x for x in values if x is not None]
    return float(np.mean(v)) if v else None


def summary(groups: dict[str, list]) -> dict:
    """{"methods": {name: summarize_method(...)}} for method name -> evaluation directories."""
    loaded = {name: [read_result(d) for d in dirs] for name, dirs in groups.items()}
    check_same_benchmark([r for rs in loaded.values() for r in rs])
    return {"methods": {name: summarize_method(rs, groups[name]) for name, rs in loaded.items()}}


SHORT_LEARNER = {"bfloat16": "bf16", "float32": "fp32"}


def _cell(m: dict | None, fmt: str = ".3f") -> str:
    if m is None or m["mean"] is None:
        return ""
    if m["ci95"] is None:
        return f"{m['mean']:{fmt}}"
    return f"{m['mean']:{fmt}} ± {m['ci95']:{fmt}}"


def metrics_table(summ: dict, columns: tuple[str, ...] = ALL_METRICS) -> str:
    """Methods x metrics, `mean ± ci95` over seeds (a method of one seed: its value)."""
    lines = [
        "| method | " + " | ".join(LABELS[k] for k in columns) + " | seeds | learner per seed |",
        "|---|" + "---|" * (len(columns) + 2),
    ]
    for name, entry in summ["methods"].items():
        cells = [_cell(entry["metrics"].get(k)) for k in columns]
        learners = ", ".join(SHORT_LEARNER.get(x, "–") for x in entry.get("learner_per_seed", []))
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {len(entry['seeds'])} | {learners} |")
    return "\n".join(lines)


def estimator_table(summ: dict) -> str:
    """Methods with estimators as rows (errors averaged over seeds); '' if none has them."""
    rows = [(name, e["estimator"]) for name, e in summ["methods"].items() if e.get("estimator")]
    if not rows:
        return ""
    dims = list(dict.fromkeys(d for _, est in rows for d in est["x_exp_mean_abs_error"]))
    lines = ["| method | " + " | ".join(dims) + " | ‖l̂ − l‖ |", "|---|" + "---|" * (len(dims) + 1)]
    for name, est in rows:
        err = est["x_exp_mean_abs_error"]
        cells = [f"{err[d]:.3f}" if d in err else "" for d in dims]
        l_imp = est.get("l_imp_mean_l2_error")
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {'' if l_imp is None else f'{l_imp:.3f}'} |")
    return "\n".join(lines)


def _groups(argv: list[str]) -> tuple[list[str], list[tuple[str, list[str]]]]:
    """Split `--method NAME DIR ...` groups out of argv (argparse cannot nest them)."""
    rest, groups, i = [], [], 0
    while i < len(argv):
        if argv[i] == "--method":
            if i + 1 >= len(argv) or argv[i + 1].startswith("--"):
                raise ValueError("--method needs a NAME and at least one DIR")
            name, dirs, i = argv[i + 1], [], i + 2
            while i < len(argv) and not argv[i].startswith("--"):
                dirs.append(argv[i])
                i += 1
            if not dirs:
                raise ValueError(f"--method {name}: give at least one evaluation directory")
            groups.append((name, dirs))
        else:
            rest.append(argv[i])
            i += 1
    return rest, groups


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    p = argparse.ArgumentParser(
        prog="python -m lasmp.eval.results_table",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("dirs", nargs="*", help="evaluation directories, one method each (or use --method groups)")
    p.add_argument("--labels", nargs="+", help="with plain DIRs: row names (default: the directory names)")
    p.add_argument("--json", type=Path, default=DEFAULT_JSON, help=f"summary file (default {DEFAULT_JSON})")
    p.add_argument("--force", action="store_true", help="overwrite --json if it exists")
    p.add_argument("--paper-columns", action="store_true", help="print only the paper's five metrics")
    try:
        rest, method_groups = _groups(argv)
    except ValueError as err:
        p.error(str(err))
    args = p.parse_args(rest)
    if method_groups and args.dirs:
        p.error("give either --method groups or plain directories, not both")
    if not method_groups and not args.dirs:
        p.error("give --method NAME DIR [DIR ...] (one DIR per seed), or plain directories")
    if args.dirs:
        labels = args.labels or [Path(d).name for d in args.dirs]
        if len(labels) != len(args.dirs):
            p.error(f"{len(labels)} labels for {len(args.dirs)} results")
        method_groups = [(label, [d]) for label, d in zip(labels, args.dirs, strict=True)]
    elif args.labels:
        p.error("--labels applies to plain directories; --method names its own")
    names = [name for name, _ in method_groups]
    if len(set(names)) != len(names):
        p.error(f"a method is named twice: {names}")
    try:
        with claim_output(args.json, force=args.force, option="--json") as out:  # claimed before reading
            try:
                summ = summary(dict(method_groups))
            except (FileNotFoundError, ValueError) as err:
                p.error(str(err))
            atomic_write_text(out, dumps(summ))
    except OSError as err:  # a user's file (OutputExistsError), a full disk: one line naming it
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(metrics_table(summ, METRICS if args.paper_columns else ALL_METRICS))
    est = estimator_table(summ)
    if est:
        print("\nEstimator accuracy (mean absolute error per dimension of x_exp; mean ‖l̂_imp − l_imp‖):\n")
        print(est)
    print(f"\n(mean ± 95 % t-interval over seeds; summary written to {args.json})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
