"""The ladder's table and figure (scripts/ladder.py table, figure), from the collected runs'
validation curves (results/ladder/<rung>/seed<k>/validation.json)."""

from __future__ import annotations

import json
from pathlib import Path

from ladderlib.rungs import BASE, RESULTS, RUNGS, SEEDS


def read_curve(path: Path) -> dict:
    """A run's validation.json; one line naming the file if it is missing or not JSON."""
    try:
        curve = json.loads(path.read_text())
        history = curve["history"]
    except FileNotFoundError:
        raise SystemExit(f"error: {path}: no such file (collect the run first)") from None
    except (json.JSONDecodeError, KeyError, TypeError) as err:
        raise SystemExit(f"error: {path}: not a validation curve ({err})") from None
    if not history:
        raise SystemExit(f"error: {path}: holds no validation")
    return curve


def curves(results: Path = RESULTS) -> dict[str, dict[int, dict]]:
    """{rung: {seed: curve}} of every collected run."""
    out: dict[str, dict[int, dict]] = {}
    for name in RUNGS:
        for seed in SEEDS:
            path = results / name / f"seed{seed}" / "validation.json"
            if path.exists():
                out.setdefault(name, {})[seed] = read_curve(path)
    return out


# the validation collision rates a run is timed to: the step on the way, and the paper's row
TARGETS = (0.05, 0.029)


def first_reaching(curve: dict, target: float) -> dict | None:
    """The first validation of a run at or below `target` (its env-steps and minutes), None if none."""
    return next((r for r in curve["history"] if r["collision_rate"] <= target), None)


def table_rows(found: dict[str, dict[int, dict]]) -> list[dict]:
    """One row per rung with runs: each seed's final validation collision rate (its last score), their
    mean and spread, the seeds' differences from the baseline rung's same seed, the env-steps and
    training minutes of the last score, and, per seed, the env-steps at which validation first reached
    each of TARGETS (None: never)."""
    base = {seed: c["history"][-1]["collision_rate"] for seed, c in found.get(BASE, {}).items()}
    rows = []
    for name, runs in found.items():
        final = {seed: c["history"][-1] for seed, c in sorted(runs.items())}
        values = [r["collision_rate"] for r in final.values()]
        diffs = {s: r["collision_rate"] - base[s] for s, r in final.items() if s in base and name != BASE}
        rows.append(
            {
                "rung": name,
                "lever": RUNGS[name].lever,
                "label": RUNGS[name].label,
                "per_seed": {str(s): r["collision_rate"] for s, r in final.items()},
                "mean": sum(values) / len(values),
                "spread": max(values) - min(values),
                "diff_from_base": {str(s): d for s, d in diffs.items()},
                "mean_diff_from_base": sum(diffs.values()) / len(diffs) if diffs else None,
                "best_mean": sum(min(r["collision_rate"] for r in c["history"]) for c in runs.values())
                / len(runs),
                "env_steps": max(r["env_steps"] for r in final.values()),
                "minutes": max(r["wall_s"] for r in final.values()) / 60.0,
                "first_reaching": {
                    str(t): {
                        str(s): (hit["env_steps"], hit["wall_s"] / 60.0)
                        if (hit := first_reaching(c, t))
                        else None
                        for s, c in sorted(runs.items())
                    }
                    for t in TARGETS
                },
            }
        )
    return rows


def markdown(rows: list[dict]) -> str:
    out = [
        "| lever | rung | seeds | validation collision per seed | mean | spread | vs baseline, per seed "
        "(mean) | best on the curve, mean | env-steps | minutes | "
        + " | ".join(f"first <= {t} per seed: M steps (min)" for t in TARGETS)
        + " |",
        "|---|---|---|---|---|---|---|---|---|---|" + "---|" * len(TARGETS),
    ]
    for r in rows:
        seeds = ", ".join(r["per_seed"])
        per_seed = " / ".join(f"{v:.3f}" for v in r["per_seed"].values())
        diffs = " / ".join(f"{v:+.3f}" for v in r["diff_from_base"].values())
        diff = f"{diffs} ({r['mean_diff_from_base']:+.3f})" if r["diff_from_base"] else "–"
        out.append(
            f"| {r['lever']} | {r['label']} | {seeds} | {per_seed} | {r['mean']:.3f} | {r['spread']:.3f} | "
            f"{diff} | {r['best_mean']:.3f} | {r['env_steps'] / 1e6:.1f} M | {r['minutes']:.0f} | "
            + " | ".join(_reached(r["first_reaching"][str(t)]) for t in TARGETS)
            + " |"
        )
    return "\n".join(out)


def _reached(per_seed: dict) -> str:
    return " / ".join(f"{hit[0] / 1e6:.1f} ({hit[1]:.0f})" if hit else "never" for hit in per_seed.values())


def figure(found: dict[str, dict[int, dict]], out: Path) -> Path:
    """Validation collision against env-steps: one line per rung (the seeds' mean), seeds as thin lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2))
    for i, (name, runs) in enumerate(found.items()):
        color = f"C{i}"
        series = []
        for curve in runs.values():
            steps = [r["env_steps"] / 1e6 for r in curve["history"]]
            values = [r["collision_rate"] for r in curve["history"]]
            ax.plot(steps, values, color=color, lw=0.7, alpha=0.5)
            series.append(dict(zip(steps, values, strict=True)))
        shared = sorted(set.intersection(*(set(s) for s in series)))
        ax.plot(
            shared,
            [sum(s[x] for s in series) / len(series) for x in shared],
            color=color,
            lw=2,
            label=f"{RUNGS[name].label} ({len(runs)} seed{'s' if len(runs) > 1 else ''})",
        )
    ax.axhline(0.029, color="k", ls="--", lw=1, label="the paper's LAS-MP (Xi_eval)")
    ax.set_xlabel("env-steps (millions)")
    ax.set_ylabel("validation collision rate")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.stem + ".tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(out)
    return out
