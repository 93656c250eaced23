"""Learning curves of a training run from its TensorBoard logs: a PNG and a JSON summary.

    python -m lasmp.eval.curves RUN_DIR --out curve.png [--json] [--every 50]

Panels: success rate (episodes that reach T without a collision) and curriculum level N; mean
episode reward and length; the per-term episode rewards (`Episode_Reward/<term>`), so the terms
that dominate are visible. `--json` prints, every `--every` iterations, the mean over that window
of success rate, level, reward, episode length and every reward term.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from lasmp.atomic import atomic_write_with

MAIN_TAGS = {
    "Episode/success_rate": "success rate",
    "Curriculum/level": "curriculum level N",
    "Train/mean_reward": "mean episode reward",
    "Episode/length_s": "mean episode length (s)",
}


def read_scalars(run_dir: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """tag -> (iterations, values) of every scalar in the run's event files (later files win)."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    files = sorted(Path(run_dir).glob("events.out.tfevents.*"))
    if not files:
        raise FileNotFoundError(f"{run_dir}: no TensorBoard event files (events.out.tfevents.*)")
    series: dict[str, dict[int, float]] = {}
    for f in files:  # a resumed run writes a new file; its iterations continue the old ones
        acc = EventAccumulator(str(f), size_guidance={"scalars": 0})
        acc.Reload()
        for tag in acc.Tags()["scalars"]:
            series.setdefault(tag, {}).update({e.step: e.value for e in acc.Scalars(tag)})
    return {t: (np.array(sorted(s)), np.array([s[k] for k in sorted(s)])) for t, s in series.items()}


def windows(scalars: dict, every: int) -> list[dict]:
    """Means over consecutive windows of `every` iterations of the main tags and reward terms."""
    last = max(int(it.max()) for it, _ in scalars.values())
    out = []
    for lo in range(0, last + 1, every):
        row = {"iterations": [lo, min(lo + every, last + 1) - 1]}
        for tag, (it, v) in sorted(scalars.items()):
            if tag in MAIN_TAGS or tag.startswith("Episode_Reward/"):
                sel = (it >= lo) & (it < lo + every)
                if sel.any():
                    row[tag] = float(v[sel].mean())
        out.append(row)
    return out


def plot(scalars: dict, out: str | Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(16, 8))
    for ax, (tag, label) in zip(axes.flat[:4], MAIN_TAGS.items(), strict=True):
        if tag in scalars:
            it, v = scalars[tag]
            ax.plot(it, v, lw=0.6, alpha=0.4)
            k = max(1, len(v) // 50)
            ax.plot(it[k - 1 :], np.convolve(v, np.ones(k) / k, mode="valid"), lw=1.5)
        ax.set(xlabel="iteration", title=label)
    ax = axes.flat[4]
    terms = sorted(t for t in scalars if t.startswith("Episode_Reward/"))
    for tag in terms:
        it, v = scalars[tag]
        k = max(1, len(v) // 50)
        ax.plot(it[k - 1 :], np.convolve(v, np.ones(k) / k, mode="valid"), label=tag.split("/", 1)[1])
    ax.set(xlabel="iteration", title="episode reward per term")
    ax.legend(fontsize=6, ncol=2)
    axes.flat[5].axis("off")
    fig.suptitle(title)
    fig.tight_layout()
    atomic_write_with(out, lambda tmp: fig.savefig(tmp, dpi=80, format="png"))
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lasmp.eval.curves", description=__doc__.split("\n")[0])
    ap.add_argument("run_dir")
    ap.add_argument("--out", help="write the learning-curve PNG here")
    ap.add_argument("--json", action="store_true", help="print the windowed means as one JSON object")
    ap.add_argument("--every", type=int, default=50, help="window, iterations")
    args = ap.parse_args(argv)
    if args.every < 1:
        ap.error("--every must be >= 1")
    try:
        scalars = read_scalars(args.run_dir)
    except FileNotFoundError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.out:
        plot(scalars, args.out, str(args.run_dir))
        print(f"wrote {args.out}", file=sys.stderr)
    if args.json:
        print(json.dumps({"run_dir": str(args.run_dir), "windows": windows(scalars, args.every)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
