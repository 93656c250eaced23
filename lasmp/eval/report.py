"""Evaluation outputs: `metrics.json`, `metrics.md` and the estimate plot, written atomically.

`metrics.json` is strict JSON (a value that is not a finite number is written as null, never NaN),
so every JSON reader, not only Python's, can read it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from lasmp.eval.metrics import ALL_METRICS
from lasmp.eval.mirror import mirror_markdown
from lasmp.io.atomic import atomic_open, atomic_write_with

LABELS = {
    "collision_rate": "collision rate",
    "height_violation_rate": "height-violation rate",
    "position_deviation_m": "position deviation (m)",
    "rotation_deviation_rad": "rotation deviation (rad, world tilt)",
    "power_w": "power (W)",
    "position_deviation_translating_m": "position deviation, translating frame (m)",
    "rotation_deviation_platform_rad": "rotation deviation, relative to the platform (rad)",
}


def strict_json(value):
    """`value` with NaN and infinities as None and numpy scalars and arrays as plain Python."""
    if isinstance(value, dict):
        return {str(k): strict_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [strict_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return strict_json(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def dumps(result: dict) -> str:
    return json.dumps(strict_json(result), indent=2, allow_nan=False) + "\n"


def _num(value, fmt: str = ".4f") -> str:
    return "n/a" if value is None or not np.isfinite(value) else format(value, fmt)


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
    paper = (result.get("paper") or {}).get("metrics", {})
    if paper:
        lines[-2:] = [
            f"| metric | mean | std | the paper's {result['paper']['method']} (Table II, mean ± its std) |",
            "|---|---|---|---|",
        ]
    for key in ALL_METRICS:
        m = result["metrics"].get(key)
        if m is not None:
            row = f"| {LABELS[key]} | {_num(m['mean'])} | {_num(m['std'])} |"
            if paper:
                p = paper.get(key)
                row += f" {_num(p['mean'], '.3f')} ± {_num(p['std'], '.2f')} |" if p else " – |"
            lines.append(row)
    if result.get("forced_episodes") is not None:
        lines += [
            "",
            f"Forced episodes (the platform probe's Coulomb block slides off or loses contact): "
            f"{result['forced_episodes']} of {result['num_episodes']}.",
        ]
    gait = result.get("gait")
    if gait:
        lines += [
            "",
            f"Stance: {gait['four_feet_step_share']:.3f} of the steps on four feet; "
            f"{gait['episodes_with_foot_up_over_2s']:.3f} of the episodes with a foot up for more than 2 s "
            f"(median longest air phase {gait['median_longest_air_s']:.2f} s).",
        ]
    if result.get("mirror"):
        lines += mirror_markdown(result["mirror"])
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
    lines += ["", *inputs_line(result), f"Wall time: {result['wall_time_s']:.1f} s.", ""]
    return "\n".join(lines)


def inputs_line(result: dict) -> list[str]:
    """[one line: the seed and the first 12 hex digits of the inputs' SHA-256 (whole in
    metrics.json)], or [] for a result that does not record them."""
    if "seed" not in result:
        return []
    parts = [f"seed {result['seed']}"]
    for key, name in (
        ("benchmark_sha256", "benchmark"),
        ("trajectories_sha256", "trajectories"),
        ("checkpoint_sha256", "checkpoint"),
    ):
        if result.get(key):
            parts.append(f"{name} sha256 {result[key][:12]}")
    return [f"Inputs: {', '.join(parts)}."]


def write_results(out_dir: Path, result: dict, render=markdown) -> list[str]:
    """`metrics.json` and `metrics.md` (from `render(result)`), each written atomically; their names,
    for evaluate.py's closing line of what it wrote where."""
    atomic_write_text(out_dir / "metrics.json", dumps(result))
    atomic_write_text(out_dir / "metrics.md", render(result))
    return ["metrics.json", "metrics.md"]


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
