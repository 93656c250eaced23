"""Evaluation outputs: `metrics.json`, `metrics.md` and the estimate plot, written atomically."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from lasmp.atomic import atomic_open, atomic_write_with
from lasmp.eval.metrics import METRICS

LABELS = {
    "collision_rate": "collision rate",
    "height_violation_rate": "height-violation rate",
    "position_deviation_m": "position deviation (m)",
    "rotation_deviation_rad": "rotation deviation (rad)",
    "power_w": "power (W)",
}


def atomic_write_text(path: Path, text: str) -> None:
    with atomic_open(path, "w") as f:
        f.write(text)


def markdown(result: dict) -> str:
    lines = [
        f"# {result['method']}",
        "",
        f"{result['num_episodes']} benchmark episodes; mean ± std over {result['std_over']}.",
        "",
        "| metric | mean | std |",
        "|---|---|---|",
    ]
    for key in METRICS:
        m = result["metrics"][key]
        lines.append(f"| {LABELS[key]} | {m['mean']:.4f} | {m['std']:.4f} |")
    est = result.get("estimator")
    if est:
        lines += [
            "",
            "## Estimator accuracy (mean absolute error per dimension)",
            "",
            "| dim | error |",
            "|---|---|",
        ]
        lines += [f"| {name} | {value:.4f} |" for name, value in est["x_exp_mean_abs_error"].items()]
        lines.append(f"| l_imp (mean L2) | {est['l_imp_mean_l2_error']:.4f} |")
    lines += ["", f"Wall time: {result['wall_time_s']:.1f} s.", ""]
    return "\n".join(lines)


def write_results(out_dir: Path, result: dict, render=markdown) -> None:
    """`metrics.json` and `metrics.md` (from `render(result)`), each written atomically."""
    atomic_write_text(out_dir / "metrics.json", json.dumps(result, indent=2) + "\n")
    atomic_write_text(out_dir / "metrics.md", render(result))


def plot_estimates(trace: dict, names: tuple[str, ...], dt_s: float, path: Path) -> None:
    """Estimated vs true x_exp over one episode, one panel per dimension."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    true, est = np.asarray(trace["true"]), np.asarray(trace["estimate"])
    t = np.arange(len(true)) * dt_s
    cols = 4
    rows = int(np.ceil(len(names) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 2.4 * rows), squeeze=False, sharex=True)
    for i, name in enumerate(names):
        ax = axes[i // cols][i % cols]
        ax.plot(t, true[:, i], label="true", color="k", lw=1.2)
        ax.plot(t, est[:, i], label="estimate", color="tab:orange", lw=1.0)
        ax.set_title(name, fontsize=9)
    for j in range(len(names), rows * cols):
        axes[j // cols][j % cols].axis("off")
    axes[0][0].legend(fontsize=8)
    fig.suptitle(f"benchmark episode {trace['episode']}: estimated vs true x_exp ({len(true) * dt_s:.1f} s)")
    for ax in axes[-1]:
        ax.set_xlabel("t (s)")
    fig.tight_layout()
    atomic_write_with(path, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    plt.close(fig)
