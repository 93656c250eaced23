"""Learning curves of a training run from its TensorBoard logs: a PNG and a JSON summary.

    python -m lasmp.eval.curves RUN_DIR --out curve.png [--json] [--every 50]
    python -m lasmp.eval.curves RUN_DIR RUN_DIR... --labels A B... --out compare.png [--last-iteration 449]

Panels: success rate (episodes that reach T without a collision) and curriculum level N; mean
episode reward and length; the per-term episode rewards (`Episode_Reward/<term>`), so the terms
that dominate are visible. `--json` prints, every `--every` iterations, the mean over that window
of success rate, level, reward, episode length and every reward term.

Given several runs, one figure compares them: the four main panels with one smoothed curve per run
(`--last-iteration` cuts every run there, to compare runs at one budget), and `--json` gives each
run's windows.

`--out` is claimed before the event files are read (`lasmp.io.atomic.claim_output`): an existing file is
refused without `--force`.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

import numpy as np

from lasmp.io.atomic import atomic_write_with, claim_output
from lasmp.io.inputs import InputError, check_out_file

MAIN_TAGS = {
    "Episode/success_rate": "success rate",
    "Curriculum/level": "curriculum level N",
    "Train/mean_reward": "mean episode reward",
    "Episode/length_s": "mean episode length (s)",
}
# tags that event files may hold for a main tag, read as it: R-S runs' logs that tag the share of
# episodes reaching the time limit `Episode/timeout_rate` (both tasks log it as `Episode/success_rate`)
TAG_ALIASES = {"Episode/timeout_rate": "Episode/success_rate"}


def read_scalars(run_dir: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """tag -> (iterations, values) of every scalar in the run's event files (later files win; a tag of
    `TAG_ALIASES` under the name it stands for)."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    files = sorted(Path(run_dir).glob("events.out.tfevents.*"))
    if not files:
        raise FileNotFoundError(f"{run_dir}: no TensorBoard event files (events.out.tfevents.*)")
    series: dict[str, dict[int, float]] = {}
    for f in files:  # a resumed run writes a new file; its iterations continue the old ones
        acc = EventAccumulator(str(f), size_guidance={"scalars": 0})
        acc.Reload()
        for tag in acc.Tags()["scalars"]:
            series.setdefault(TAG_ALIASES.get(tag, tag), {}).update(
                {e.step: e.value for e in acc.Scalars(tag)}
            )
    return {t: (np.array(sorted(s)), np.array([s[k] for k in sorted(s)])) for t, s in series.items()}


def windows(scalars: dict, every: int) -> list[dict]:
    """Means over consecutive windows of `every` iterations of the main tags and reward terms."""
    last = max(int(it.max()) for it, _ in scalars.values() if len(it))
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


def smoothed(it: np.ndarray, v: np.ndarray, points: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """A running mean over about len(v) / points iterations (at least 1)."""
    k = max(1, len(v) // points)
    return it[k - 1 :], np.convolve(v, np.ones(k) / k, mode="valid")


def truncated(scalars: dict, last_iteration: int | None) -> dict:
    """The scalars of iterations <= last_iteration (all if None)."""
    if last_iteration is None:
        return scalars
    return {t: (it[it <= last_iteration], v[it <= last_iteration]) for t, (it, v) in scalars.items()}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_comparison(runs: dict[str, dict], out: str | Path, title: str) -> None:
    """One panel per main tag, one smoothed curve per run (label -> scalars)."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 4, figsize=(20, 4.5))
    for ax, (tag, label) in zip(axes.flat, MAIN_TAGS.items(), strict=True):
        for name, scalars in runs.items():
            if tag in scalars and len(scalars[tag][0]):
                ax.plot(*smoothed(*scalars[tag]), lw=1.3, label=name)
        ax.set(xlabel="iteration", title=label)
    axes.flat[0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    atomic_write_with(out, lambda tmp: fig.savefig(tmp, dpi=80, format="png"))
    plt.close(fig)


def plot(scalars: dict, out: str | Path, title: str) -> None:
    plt = _pyplot()
    fig, axes = plt.subplots(2, 3, figsize=(16, 8))
    for ax, (tag, label) in zip(axes.flat[:4], MAIN_TAGS.items(), strict=True):
        if tag in scalars:
            it, v = scalars[tag]
            ax.plot(it, v, lw=0.6, alpha=0.4)
            ax.plot(*smoothed(it, v), lw=1.5)
        ax.set(xlabel="iteration", title=label)
    ax = axes.flat[4]
    terms = sorted(t for t in scalars if t.startswith("Episode_Reward/"))
    for tag in terms:
        ax.plot(*smoothed(*scalars[tag]), label=tag.split("/", 1)[1])
    ax.set(xlabel="iteration", title="episode reward per term")
    ax.legend(fontsize=6, ncol=2)
    axes.flat[5].axis("off")
    fig.suptitle(title)
    fig.tight_layout()
    atomic_write_with(out, lambda tmp: fig.savefig(tmp, dpi=80, format="png"))
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lasmp.eval.curves", description=__doc__.split("\n")[0])
    ap.add_argument("run_dirs", nargs="+", metavar="run_dir", help="one run, or several to compare")
    ap.add_argument("--labels", nargs="+", help="one name per run (default: the directories)")
    ap.add_argument("--last-iteration", type=int, help="leave out the iterations after this one")
    ap.add_argument("--out", help="write the learning-curve PNG here")
    ap.add_argument("--force", action="store_true", help="replace an existing --out")
    ap.add_argument("--json", action="store_true", help="print the windowed means as one JSON object")
    ap.add_argument("--every", type=int, default=50, help="window, iterations")
    args = ap.parse_args(argv)
    if args.every < 1:
        ap.error("--every must be >= 1")
    if args.last_iteration is not None and args.last_iteration < 0:
        ap.error(f"--last-iteration must be >= 0, got {args.last_iteration}")
    labels = args.labels or args.run_dirs
    if len(labels) != len(args.run_dirs):
        ap.error(f"--labels gives {len(labels)} names for {len(args.run_dirs)} runs")
    if len(set(labels)) != len(labels):
        ap.error(f"the runs need distinct labels, got {labels}")
    with contextlib.ExitStack() as claim:
        try:
            if args.out:
                check_out_file(args.out, suffixes=(".png",), force=True, option="--out")
                claim.enter_context(claim_output(args.out, force=args.force, option="--out"))
            runs = {
                name: truncated(read_scalars(d), args.last_iteration)
                for name, d in zip(labels, args.run_dirs, strict=True)
            }
        except (FileNotFoundError, FileExistsError, InputError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        return _report(args, runs, labels)


def _report(args, runs: dict, labels: list[str]) -> int:
    """The figure (into `--out`, claimed by `main`) and the JSON windows."""
    if args.out:
        if len(runs) == 1:
            plot(next(iter(runs.values())), args.out, str(args.run_dirs[0]))
        else:
            plot_comparison(runs, args.out, ", ".join(labels))
        print(f"wrote {args.out}", file=sys.stderr)
    if args.json:
        if len(runs) == 1:
            print(
                json.dumps(
                    {"run_dir": str(args.run_dirs[0]), "windows": windows(runs[labels[0]], args.every)}
                )
            )
        else:
            print(
                json.dumps(
                    {
                        "runs": [
                            {"label": name, "run_dir": str(d), "windows": windows(runs[name], args.every)}
                            for name, d in zip(labels, args.run_dirs, strict=True)
                        ]
                    }
                )
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
