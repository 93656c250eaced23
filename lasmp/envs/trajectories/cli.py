"""The command line: ``python -m lasmp.envs.trajectories {stats,plot,generate} --help``.

``stats`` prints :func:`~lasmp.envs.trajectories.stats.statistics` (a table, or ``--json``),
``plot`` draws example paths and per-N statistics to a PNG, ``generate`` writes a sampled set to
a trajectory file; each samples a set of a split (``--split --num --seed --kind --degree``) or,
for ``stats`` and ``plot``, reads one (``--file``; the sampling options then are refused, not ignored).

The file ``plot`` or ``generate`` writes (``--out``) is checked before any sampling (its extension,
its directory, and that it replaces no file without ``--force``) and written whole or not at all;
a write that fails is one line naming it (exit 1).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from lasmp.envs.trajectories.fileformat import load, save
from lasmp.envs.trajectories.generate import PROBE_ROWS, ranges_for_split, sample, sample_bytes
from lasmp.envs.trajectories.splines import (
    DEFAULT_DEGREE,
    GENERATED_KINDS,
    MAX_DEGREE,
    PiecewisePoly,
    SplineSpec,
)
from lasmp.envs.trajectories.stats import print_table, statistics
from lasmp.io.atomic import OutputExistsError, atomic_open, claim_output
from lasmp.io.inputs import InputError, check_out_file, float_arg, int_arg, seed_arg, size_in_words
from lasmp.io.memory import available_memory

PLOT_SUFFIXES = (".png", ".pdf", ".svg")
# what a sampled set is drawn with, and its defaults (--num's is per command): with --file, none applies
SAMPLING = {"split": "test", "seed": 0, "kind": "approximating", "degree": DEFAULT_DEGREE}


def _traj_from_args(args) -> PiecewisePoly:
    if getattr(args, "file", None):
        return load(args.file)
    spline = SplineSpec(args.kind, args.degree)
    check_memory(args.num, ranges_for_split(args.split), spline)
    return sample(args.num, ranges_for_split(args.split), np.random.default_rng(args.seed), spline=spline)


def check_memory(num: int, ranges, spline: SplineSpec) -> None:
    """Refuse a --num whose trajectories cannot fit in memory, before sampling, with the estimate
    (`sample_bytes`, a lower bound) and the limit it meets (`lasmp.io.memory.available_memory`): numpy would
    otherwise fail (or the machine swap) only after allocating what it could."""
    found = available_memory()
    need, per_row = sample_bytes(num, ranges, spline)
    if found is None or need <= found[0]:
        return
    left, source = found
    raise InputError(
        f"--num {num}: sampling {num:,} trajectories needs at least {size_in_words(need)} ({size_in_words(per_row)} "
        f"per trajectory, measured on {PROBE_ROWS}), and {size_in_words(left)} is available ({source}). Give "
        f"--num {max(left // per_row, 1):,} or fewer"
    )


def _plot(traj: PiecewisePoly, stats: dict, out: str, dt_s: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(15, 9))
    ax3 = fig.add_subplot(2, 3, (1, 4), projection="3d")
    axz = fig.add_subplot(2, 3, 2)
    ns = np.unique(traj.n_waypoints)
    picks = [int(np.flatnonzero(traj.n_waypoints == n)[0]) for n in ns[:: max(1, len(ns) // 5)]]
    for r in picks:
        grid = np.arange(0.0, traj.duration_s[r] + 1e-9, dt_s)
        p = traj.evaluate(grid, np.full(len(grid), r))[0]
        ax3.plot(p[:, 0], p[:, 1], p[:, 2], label=f"N={traj.n_waypoints[r]}")
        wp = traj.knot_poses[r, : traj.n_knots[r]]
        ax3.scatter(wp[:, 0], wp[:, 1], wp[:, 2], s=8)
        axz.plot(grid, p[:, 2], label=f"N={traj.n_waypoints[r]}")
    ax3.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)", title="example translational paths")
    ax3.legend(fontsize=7)
    axz.set(xlabel="t (s)", ylabel="z (m)", title="height over time")
    keys = list(stats["per_n"])
    for i, (col, lab) in enumerate(
        (
            ("mean_path_length_m", "path length (m)"),
            ("mean_speed_mps", "mean speed (m/s)"),
            ("mean_curvature_per_m", "mean curvature (1/m)"),
        )
    ):
        ax = fig.add_subplot(2, 3, (3, 5, 6)[i])
        ax.bar(keys, [stats["per_n"][k][col] for k in keys])
        ax.set(xlabel="N waypoints", ylabel=lab, title=f"{lab} per N")
    fig.tight_layout()
    with atomic_open(out) as f:
        fig.savefig(f, dpi=90, format=Path(out).suffix[1:].lower())
    plt.close(fig)


def main(argv=None) -> int:
    from lasmp.envs import trajectories  # the CLI is described by the package docstring's first line

    ap = argparse.ArgumentParser(
        prog="python -m lasmp.envs.trajectories", description=trajectories.__doc__.split("\n")[0]
    )
    sub = ap.add_subparsers(dest="cmd", required=True)

    def common(p, num):
        # defaults None, filled in below: an option given with --file is refused, not ignored
        p.add_argument("--split", choices=("train", "test"), help="default test")
        p.add_argument("--num", type=int_arg(1), help=f"default {num}")
        p.add_argument("--seed", type=seed_arg, help="default 0")
        p.add_argument("--kind", choices=GENERATED_KINDS, help="spline construction (default approximating)")
        p.add_argument(
            "--degree",
            type=int_arg(3, MAX_DEGREE),
            help=f"approximating B-spline degree (default {DEFAULT_DEGREE})",
        )
        p.set_defaults(default_num=num)

    ps = sub.add_parser("stats", help="path length / speed / curvature, overall and per N")
    common(ps, 10000)
    ps.add_argument("--file", help="use a saved trajectory file instead of sampling")
    ps.add_argument("--dt", type=float_arg(0.0, open_lo=True), default=0.02, help="sampling step, s")
    ps.add_argument("--json", action="store_true", help="print one JSON object only")
    pp = sub.add_parser("plot", help="example paths and per-N statistics to a PNG")
    common(pp, 200)
    pp.add_argument("--file", help="use a saved trajectory file instead of sampling")
    pp.add_argument("--dt", type=float_arg(0.0, open_lo=True), default=0.02, help="sampling step, s")
    pp.add_argument("--out", required=True, help=f"the figure ({' or '.join(PLOT_SUFFIXES)})")
    pp.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    pg = sub.add_parser("generate", help="sample a set and write it to a file")
    common(pg, 10000)
    pg.add_argument("--out", required=True, help="the trajectory file (.npz)")
    pg.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    args = ap.parse_args(argv)
    given = [f"--{k}" for k in ("num", *SAMPLING) if getattr(args, k) is not None]
    if getattr(args, "file", None) and given:
        ap.error(
            f"give --file or the sampling options ({', '.join(given)}), not both: a saved set is read as it is"
        )
    args.num = args.default_num if args.num is None else args.num
    for key, default in SAMPLING.items():
        setattr(args, key, default if getattr(args, key) is None else getattr(args, key))
    if args.cmd == "stats":
        return _run(args)
    try:  # the file it writes: extension checked, then claimed (create-exclusive) before any sampling
        suffixes = PLOT_SUFFIXES if args.cmd == "plot" else (".npz",)
        check_out_file(args.out, suffixes=suffixes, force=True, option="--out")
        with claim_output(args.out, force=args.force, option="--out"):
            return _run(args)
    except (InputError, OutputExistsError) as exc:  # a bad extension; the file exists (no --force)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as err:  # AtomicWriteError (a full disk, ...): it names the file, left as it was
        print(f"error: {err}", file=sys.stderr)
        return 1


def _run(args) -> int:
    """Sample or read the set, then print its statistics or write --out (claimed by `main`)."""
    try:
        traj = _traj_from_args(args)
    except ValueError as exc:  # InputError, a bad file (TrajectoryFileError) or construction
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted" + ("" if args.cmd == "stats" else f": {args.out} not written"), file=sys.stderr)
        return 130
    if args.cmd == "stats":
        st = statistics(traj, args.dt)
        if args.json:
            print(json.dumps(st))
        else:
            print_table(st)
        return 0
    try:  # an OSError (a full disk) reaches `main`, which reports it
        if args.cmd == "plot":
            _plot(traj, statistics(traj, args.dt), args.out, args.dt)
            print(f"wrote {args.out}", file=sys.stderr)
        else:
            save(args.out, traj, meta={"split": args.split, "seed": args.seed, "num": args.num})
            print(f"wrote {len(traj)} trajectories to {args.out}", file=sys.stderr)
    except KeyboardInterrupt:
        print(f"interrupted: {args.out} not written", file=sys.stderr)
        return 130
    return 0
