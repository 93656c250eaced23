"""Calibrate the open readings of the paper's world against its Stand Still row (docs/world.md).

Plays Stand Still (a = 0) on the first K episodes of Xi_eval's pairing (trajectory k, robot
k mod 1,024) in each candidate world, and scores every candidate reading of the metrics at once
from the same steps (counted up to the first collision, as in lasmp.eval.metrics):
- height violation with h_des = 0.37 m measured from the platform's centre (its CoM, 0.27 m above
  the top surface) and from its top surface;
- position deviation in the platform frame and in a frame that follows the platform's centre
  but keeps the world's axes (translating, not rotating);
- rotation deviation as the trunk's tilt change in the world (`rot_world`, the metric's reading)
  and as its rotation relative to the platform (`rot_platform`; rows written before the world
  reading existed have it as `rot`).
A candidate world is a trajectory construction (kind, degree) plus env overrides (platform
tracking, contacts, initial placement). Trajectories of a world are drawn with Xi_eval's seed
and stream, so candidates differ only by their construction.

    python bench/calibrate_world.py --episodes 2048 --worlds stiff_4hz soft_1hz --json out.jsonl
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np
import torch

from lasmp.config.base import build_env_cfg
from lasmp.envs import trajectories as T
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.robot import as_numpy
from lasmp.eval import benchmark as bm
from lasmp.eval.build import eval_env_overrides
from lasmp.eval.metrics import EpisodeMetrics, TrunkPose, metric_h_des_p_m
from lasmp.eval.run import BenchmarkSource

PAPER = {
    "collision": (0.612, 0.29),
    "height_violation": (0.142, 0.07),
    "position_deviation_m": (0.394, 0.04),
    "rotation_deviation_rad": (0.182, 0.07),
    "power_w": (1.031, 0.17),
}
TWO_PI = 2.0 * math.pi


def _platform(hz: float, feedforward: bool, mass_kg: float = 800.0) -> dict:
    """Platform overrides: natural frequency `hz` at factor 1, velocity feedforward or a position drive."""
    return {"omega_n_rad_s": TWO_PI * hz, "velocity_feedforward": feedforward, "mass_kg": mass_kg}


# the chosen world: the config defaults (lasmp/envs/moving_platform/cfg.py: PlatformCfg)
FINAL = _platform(1.2 / TWO_PI, False, 1.0e5)
# name -> (trajectory construction, env overrides): the candidate worlds of
# docs/world.md#how-the-readings-were-found-candidate-worlds
WORLDS = {
    "interp_4hz": ({"kind": "interpolating"}, {"platform": _platform(4.0, True)}),
    "deg5_4hz": ({"degree": 5}, {"platform": _platform(4.0, True)}),
    "deg10_4hz": ({}, {"platform": _platform(4.0, True)}),
    "deg10_1hz": ({}, {"platform": _platform(1.0, True)}),
    "deg10_0.3hz": ({}, {"platform": _platform(0.3, True)}),
    "deg10_4hz_noslip": ({}, {"platform": _platform(4.0, True), "sim": {"noslip_iterations": 4}}),
    "deg10_4hz_elliptic": (
        {},
        {"platform": _platform(4.0, True), "sim": {"cone": "elliptic", "impratio": 10.0}},
    ),
    "deg10_1hz_posdrive": ({}, {"platform": _platform(1.0, False)}),
    "deg10_0.3hz_posdrive": ({}, {"platform": _platform(0.3, False)}),
    "deg10_0.16hz_posdrive": ({}, {"platform": _platform(1.0 / TWO_PI, False)}),
    "deg10_0.16hz_posdrive_noslip": (
        {},
        {"platform": _platform(1.0 / TWO_PI, False), "sim": {"noslip_iterations": 4}},
    ),
    # which channels topple the standing robot: the others' control points are zeroed
    "deg10_4hz_rollpitch_only": ({"channels": "roll pitch"}, {"platform": _platform(4.0, True)}),
    "deg10_4hz_translation_only": ({"channels": "x y z"}, {"platform": _platform(4.0, True)}),
    "deg10_4hz_still": ({"channels": ""}, {"platform": _platform(4.0, True)}),
    "final": ({}, {"platform": FINAL}),
    # the platform drive's omega_n around the default (docs/world.md#the-platform-drive)
    "final_wn1.0": ({}, {"platform": {**FINAL, "omega_n_rad_s": 1.0}}),
    "final_wn1.1": ({}, {"platform": {**FINAL, "omega_n_rad_s": 1.1}}),
    "final_wn1.3": ({}, {"platform": {**FINAL, "omega_n_rad_s": 1.3}}),
    "final_offset_0.5m": ({}, {"platform": FINAL, "init_state": {"xy_offset_max_m": 0.5}}),
    "final_offset_0.7m": ({}, {"platform": FINAL, "init_state": {"xy_offset_max_m": 0.7}}),
    "final_deg5": ({"degree": 5}, {"platform": FINAL}),
    "final_interp": ({"kind": "interpolating"}, {"platform": FINAL}),
}


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def play_world(name: str, episodes: int, num_envs: int, bench: bm.Benchmark) -> dict:
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    spline_kw, overrides = WORLDS[name]
    spline_kw = dict(spline_kw)
    channels = spline_kw.pop("channels", None)
    spline = T.SplineSpec(**spline_kw)
    traj = T.sample(
        len(bench.trajectories),
        T.ranges_for_split("test"),
        np.random.default_rng([bench.seed, 0]),
        spline=spline,
    )
    if channels is not None:  # keep only these pose channels moving
        keep = np.isin(T.POSE_NAMES, channels.split())
        poses = np.where(keep, traj.knot_poses, 0.0 * traj.knot_poses)  # NaN padding stays NaN
        traj = T.PiecewisePoly.from_knots(
            traj.knot_times_s, poses, traj.n_knots, traj.kind, traj.degree, traj.n_waypoints
        )
    world = bm.Benchmark(traj.subset(np.arange(episodes)), bench.robots, bench.seed)
    stats = T.statistics(traj)["overall"]
    env_overrides = _merge(eval_env_overrides(min(num_envs, episodes), 0), overrides)
    cfg = build_env_cfg(env_overrides, schema=MovingPlatformCfg)
    env = MovingPlatformEnv(cfg)
    top = env.plf_top_m
    h_des = {"centre": cfg.rewards.h_des_m, "surface": metric_h_des_p_m(top)}
    source = BenchmarkSource(world, episodes, env.num_envs)
    env.episode_source = source
    # one accumulator per height reading, both fed the same steps (h_des from the centre, from the
    # surface); the positions, rotations and power are the same in both
    metrics = {ref: EpisodeMetrics(env.num_envs, h) for ref, h in h_des.items()}
    cap = {}

    def capture(readout, collision):
        cap.update(readout=as_numpy(readout), collision=collision.numpy().copy())

    def start(ids, readout):
        for m in metrics.values():
            m.start(ids, TrunkPose.from_readout(readout).rows(ids))

    env.on_step = capture
    env.reset()
    n = env.num_envs
    start(np.arange(n), as_numpy(env.readout))
    keys = (
        "steps",
        "viol_centre",
        "viol_surface",
        "pos_platform",
        "pos_translating",
        "rot_world",
        "rot_platform",
        "power",
    )
    out = {k: np.full(episodes, np.nan) for k in (*keys, "collision")}
    zeros = torch.zeros(n, 12)
    done_count, t0 = 0, time.perf_counter()
    while done_count < episodes:
        ep = source.episode_of_env.copy()
        _, _, done, extras = env.step(zeros)
        r = cap["readout"]
        pose = TrunkPose.from_readout(r)
        for m in metrics.values():
            m.step(ep >= 0, cap["collision"], pose, r.tau, r.q_dot)
        done = done.numpy()
        ids = np.flatnonzero(done & (ep >= 0))
        if len(ids):
            collided = ~extras["time_outs"].numpy()[ids]
            c, s = (metrics[ref].close(ids, collided) for ref in ("centre", "surface"))
            rows = ep[ids]
            out["collision"][rows], out["steps"][rows] = c["collision"], c["steps"]
            out["viol_centre"][rows], out["viol_surface"][rows] = (
                c["height_violation_rate"],
                s["height_violation_rate"],
            )
            out["pos_platform"][rows] = c["position_deviation_m"]
            out["pos_translating"][rows] = c["position_deviation_translating_m"]
            out["rot_world"][rows] = c["rotation_deviation_rad"]
            out["rot_platform"][rows] = c["rotation_deviation_platform_rad"]
            out["power"][rows] = c["power_w"]
            done_count += len(ids)
        restarted = np.flatnonzero(done)
        if len(restarted):
            start(restarted, as_numpy(env.readout))
    counted = out["steps"] > 0
    mean = {k: float(np.mean(out[k][counted])) for k in keys if k != "steps"}
    row = {
        "world": name,
        "spline": {"kind": spline.kind, "degree": spline.degree, "channels": channels},
        "overrides": overrides,
        "episodes": episodes,
        "path_length_m": stats["mean_path_length_m"],
        "speed_mps": stats["mean_speed_mps"],
        "collision": float(np.mean(out["collision"])),
        **mean,
        "median_episode_s": float(np.median(out["steps"]) * env.dt_s),
        "wall_s": time.perf_counter() - t0,
    }
    return row


def _rot(row: dict) -> str:
    """'world / platform' rotation deviation of a row; rows from before the world reading hold only the
    platform-relative angle, as `rot`."""
    world = row.get("rot_world")
    platform = row.get("rot_platform", row.get("rot"))
    return f"{'n/a' if world is None else f'{world:.3f}'} / {platform:.3f}"


def markdown_table(rows: list[dict]) -> str:
    """The candidate-world table of docs/world.md from rows of `play_world` (one JSON line each)."""
    head = (
        "| world | path m | speed m/s | collision | height viol. (top / centre) | "
        "pos. dev. m (platform / translating) | rot. dev. rad (world tilt / platform) | power W |"
    )
    lines = [head, "|" + "---|" * 8]
    p = PAPER
    lines.append(
        f"| paper, Stand Still | 7.12 | 0.69 | {p['collision'][0]} | {p['height_violation'][0]} | "
        f"{p['position_deviation_m'][0]} | {p['rotation_deviation_rad'][0]} | {p['power_w'][0]} |"
    )
    for r in rows:
        lines.append(
            f"| {r['world']} | {r['path_length_m']:.2f} | {r['speed_mps']:.2f} | {r['collision']:.3f} | "
            f"{r['viol_surface']:.3f} / {r['viol_centre']:.3f} | {r['pos_platform']:.3f} / {r['pos_translating']:.3f} | "
            f"{_rot(r)} | {r['power']:.2f} |"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=2048)
    ap.add_argument("--num-envs", type=int, default=1024)
    ap.add_argument("--worlds", nargs="+", default=list(WORLDS), choices=list(WORLDS))
    ap.add_argument("--json", help="append one JSON line per world to this file")
    ap.add_argument("--table", help="print the markdown table of a --json file (last row per world) and exit")
    args = ap.parse_args(argv)
    if args.table:
        with open(args.table) as f:
            rows = {r["world"]: r for r in map(json.loads, f)}
        print(markdown_table(list(rows.values())))
        return 0
    bench = bm.generate()  # Xi_eval's robots and trajectory stream (seed 0)
    for name in args.worlds:
        row = play_world(name, args.episodes, args.num_envs, bench)
        print(json.dumps(row), flush=True)
        if args.json:
            with open(args.json, "a") as f:
                f.write(json.dumps(row) + "\n")
    print(f"paper (Stand Still, Table II): {json.dumps(PAPER)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
