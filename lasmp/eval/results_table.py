"""The README's results tables from evaluation outputs (`evaluate.py --out DIR` on Xi_eval).

    python -m lasmp.eval.results_table DIR [DIR ...] [--labels NAME ...]

prints two Markdown tables: methods x the five metrics (mean ± std over the evaluation's batches of
episodes), and, for the methods that estimate, the estimators' mean absolute error per dimension of
x_exp and the mean ‖l̂_imp − l_imp‖. Every result must come from the same benchmark and episodes.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from lasmp.eval.metrics import METRICS
from lasmp.eval.report import LABELS


def load_results(result_dirs: list, labels: list[str] | None = None) -> tuple[list[dict], list[str]]:
    """The `metrics.json` of each directory and its label; refuses mixed benchmarks or episode counts."""
    results = []
    for d in result_dirs:
        path = Path(d) / "metrics.json"
        if not path.exists():
            raise FileNotFoundError(f"{path} does not exist: run `python evaluate.py ... --out {d}` first")
        result = json.loads(path.read_text())
        if "metrics" not in result or "suite" in result:
            raise ValueError(f"{path}: not a Xi_eval benchmark result (the suite has its own table)")
        results.append(result)
    labels = labels or [Path(d).name for d in result_dirs]
    if len(labels) != len(results):
        raise ValueError(f"{len(labels)} labels for {len(results)} results")
    keys = {(r["benchmark"], r["num_episodes"]) for r in results}
    if len(keys) > 1:
        raise ValueError(f"the results come from different benchmarks or episode counts: {sorted(keys)}")
    return results, labels


def metrics_table(results: list[dict], labels: list[str]) -> str:
    lines = ["| method | " + " | ".join(LABELS[k] for k in METRICS) + " |", "|---|" + "---|" * len(METRICS)]
    for label, r in zip(labels, results, strict=True):
        cells = [f"{r['metrics'][k]['mean']:.3f} ± {r['metrics'][k]['std']:.3f}" for k in METRICS]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def estimator_table(results: list[dict], labels: list[str]) -> str:
    """Methods with estimators as rows; '' if none has them. Dimensions a method lacks stay empty."""
    rows = [(label, r["estimator"]) for label, r in zip(labels, results, strict=True) if r.get("estimator")]
    if not rows:
        return ""
    dims: list[str] = []
    for _, est in rows:
        dims += [d for d in est["x_exp_mean_abs_error"] if d not in dims]
    lines = ["| method | " + " | ".join(dims) + " | ‖l̂ − l‖ |", "|---|" + "---|" * (len(dims) + 1)]
    for label, est in rows:
        err = est["x_exp_mean_abs_error"]
        cells = [f"{err[d]:.3f}" if d in err else "" for d in dims]
        l_imp = est.get("l_imp_mean_l2_error")
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {'' if l_imp is None else f'{l_imp:.3f}'} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dirs", nargs="+", help="evaluation output directories (each with metrics.json)")
    p.add_argument("--labels", nargs="+", help="row names (default: the directory names)")
    args = p.parse_args(argv)
    try:
        results, labels = load_results(args.dirs, args.labels)
    except (FileNotFoundError, ValueError) as err:
        p.error(str(err))
    print(metrics_table(results, labels))
    est = estimator_table(results, labels)
    if est:
        print("\nEstimator accuracy (mean absolute error per dimension of x_exp; mean ‖l̂_imp − l_imp‖):\n")
        print(est)


if __name__ == "__main__":
    main()
