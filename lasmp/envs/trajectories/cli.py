"""The command line: ``python -m lasmp.envs.trajectories {stats,plot,generate} --help``.

``stats`` prints :func:`~lasmp.envs.trajectories.stats.statistics` (a table, or ``--json``),
``plot`` draws example paths and per-N statistics to a PNG, ``generate`` writes a sampled set to
a trajectory file; each samples a set of a split (``--split --num --seed --kind --degree``) or,
for ``stats`` and ``plot``, reads one (``--file``).
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from lasmp.envs.trajectories.fileformat import load, save
from lasmp.envs.trajectories.generate import ranges_for_split, sample
from lasmp.envs.trajectories.splines import DEFAULT_DEGREE, GENERATED_KINDS, PiecewisePoly, SplineSpec
from lasmp.envs.trajectories.stats import print_table, statistics


def _traj_from_args(args) -> PiecewisePoly:
    if getattr(args, "file", None):
        return load(args.file)
    spline = SplineSpec(args.kind, args.degree)
    return sample(args.num, ranges_for_split(args.split), np.random.default_rng(args.seed), spline=spline)


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
    fig.savefig(out, dpi=90)
    plt.close(fig)


def main(argv=None) -> int:
    from lasmp.envs import trajectories  # the CLI is described by the package docstring's first line

    ap = argparse.ArgumentParser(
        prog="python -m lasmp.envs.trajectories", description=trajectories.__doc__.split("\n")[0]
    )
    sub = ap.add_subparsers(dest="cmd", required=True)

    def common(p, num):
        p.add_argument("--split", choices=("train", "test"), default="test")
        p.add_argument("--num", type=int, default=num)
        p.add_argument("--seed", type=int, default=0)
        p.add_argument("--kind", choices=GENERATED_KINDS, default="approximating", help="spline construction")
        p.add_argument("--degree", type=int, default=DEFAULT_DEGREE, help="approximating B-spline degree")

    ps = sub.add_parser("stats", help="path length / speed / curvature, overall and per N")
    common(ps, 10000)
    ps.add_argument("--file", help="use a saved trajectory file instead of sampling")
    ps.add_argument("--dt", type=float, default=0.02, help="sampling step, s")
    ps.add_argument("--json", action="store_true", help="print one JSON object only")
    pp = sub.add_parser("plot", help="example paths and per-N statistics to a PNG")
    common(pp, 200)
    pp.add_argument("--file", help="use a saved trajectory file instead of sampling")
    pp.add_argument("--dt", type=float, default=0.02)
    pp.add_argument("--out", required=True)
    pg = sub.add_parser("generate", help="sample a set and write it to a file")
    common(pg, 10000)
    pg.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    if getattr(args, "num", 1) < 1:
        ap.error("--num must be >= 1")
    if getattr(args, "dt", 1.0) <= 0:
        ap.error("--dt must be > 0")
    try:
        traj = _traj_from_args(args)
    except ValueError as exc:  # a bad file (TrajectoryFileError) or construction
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.cmd == "stats":
        st = statistics(traj, args.dt)
        if args.json:
            print(json.dumps(st))
        else:
            print_table(st)
    elif args.cmd == "plot":
        _plot(traj, statistics(traj, args.dt), args.out, args.dt)
        print(f"wrote {args.out}", file=sys.stderr)
    else:
        save(args.out, traj, meta={"split": args.split, "seed": args.seed, "num": args.num})
        print(f"wrote {len(traj)} trajectories to {args.out}", file=sys.stderr)
    return 0
