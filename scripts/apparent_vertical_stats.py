"""How long Xi_eval's platforms push on the level: the apparent vertical away from the world's.

    python scripts/apparent_vertical_stats.py --episodes 2000 --out results/real_motion/apparent_vertical_xi_eval.json

The trained policies hold the trunk level in the world (docs/real_motion.md, "A steady level
acceleration against its equivalent tilt"). On a tilting deck the apparent vertical, the direction of
a - g at the top surface's centre, is the world's, and a level trunk balances; under a level
acceleration it is not, and they fall. This replays the platform motions of Xi_eval's first K
episodes (the platform probe of lasmp.eval.episodes: the evaluation's world, Stand Still, the whole
10 s) and measures per episode, for two angles,
- `world`: the apparent vertical from the world's vertical (what a trunk held level gets wrong),
- `deck`: the apparent vertical from the deck's normal (what a robot standing rigidly feels),
the largest angle and the longest stretch it stays beyond THRESHOLD_RAD. The same for the
level-acceleration probe's two motions, from their reference (the close drive tracks it within
1 mm). Prints a table and writes JSON.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

import numpy as np

from lasmp.eval import build as eval_build
from lasmp.eval import cli
from lasmp.eval import platform_probe as pp
from lasmp.eval.report import atomic_write_text
from lasmp.io.atomic import claim_output
from lasmp.io.inputs import InputError, check_out_file
from lasmp.motions import level_push
from lasmp.motions.motion import derivatives

THRESHOLD_RAD = 0.1  # a level acceleration of 0.98 m/s²
QUANTILES = (0.5, 0.9, 0.99)
STRETCHES_S = (0.5, 1.0, 2.0, 4.0)


def longest_stretch(over: np.ndarray) -> np.ndarray:
    """(m,) the longest run of consecutive True samples along axis 0 of (T, m)."""
    run = np.zeros(over.shape[1], dtype=int)
    longest = np.zeros_like(run)
    for row in over:
        run = np.where(row, run + 1, 0)
        longest = np.maximum(longest, run)
    return longest


def angles(up_w: np.ndarray, deck_normal_w: np.ndarray) -> dict[str, np.ndarray]:
    """(T, m) angles of the unit apparent vertical up_w from the world's and from the deck's normal."""
    return {
        "world": np.arccos(np.clip(up_w[..., 2], -1.0, 1.0)),
        "deck": np.arccos(np.clip(np.sum(up_w * deck_normal_w, axis=-1), -1.0, 1.0)),
    }


def summarize_angles(a: dict[str, np.ndarray], dt: float) -> dict[str, np.ndarray]:
    """Per motion: the largest angle and the longest stretch beyond THRESHOLD_RAD, s, of each."""
    out = {}
    for name, angle in a.items():
        out[f"{name}_max_rad"] = angle.max(axis=0)
        out[f"{name}_longest_over_s"] = longest_stretch(angle > THRESHOLD_RAD) * dt
    return out


def platform_stats(dt, r_wp, v_plf_w, omega_plf_w, mu, top_m) -> dict[str, np.ndarray]:
    """`lasmp.eval.platform_probe.probe_platform`'s stats hook: the angles of each whole platform motion."""
    g_app_w = np.einsum(
        "...ij,...j->...i", r_wp, pp.apparent_gravity_p(dt, r_wp, v_plf_w, omega_plf_w, top_m)
    )
    up_w = -g_app_w / np.linalg.norm(g_app_w, axis=-1, keepdims=True)
    return summarize_angles(angles(up_w, r_wp[..., :, 2]), dt)


def probe_motion_stats(dt: float) -> dict[str, dict[str, float]]:
    """The same numbers for the level-acceleration probe's motions (lasmp.motions.level_push), from
    their reference."""
    out = {}
    for m in level_push.motions():
        _, a = derivatives(m)
        step = max(1, int(round(dt / float(m.t_s[1] - m.t_s[0]))))
        up_w = a[::step, :3] - pp.G_W
        up_w /= np.linalg.norm(up_w, axis=-1, keepdims=True)
        roll, pitch = m.pose[::step, 3], m.pose[::step, 4]
        # the deck's normal for a roll-pitch pose (ZYX, no yaw in these motions): R_y(pitch) R_x(roll) e_z
        normal = np.stack(
            [np.sin(pitch) * np.cos(roll), -np.sin(roll), np.cos(pitch) * np.cos(roll)], axis=-1
        )
        values = summarize_angles(angles(up_w[:, None], normal[:, None]), dt)
        out[m.name] = {k: float(v[0]) for k, v in values.items()}
    return out


def table(xi: dict[str, np.ndarray], probe: dict[str, dict[str, float]]) -> str:
    lines = [
        f"| angle (beyond {THRESHOLD_RAD} rad) | largest: median / 90 % / 99 % | longest stretch, s: median / 90 % / 99 % | "
        + " | ".join(f"episodes ≥ {s} s" for s in STRETCHES_S)
        + " | "
        + " | ".join(probe)
        + " |",
        "|---|---|---|" + "---|" * (len(STRETCHES_S) + len(probe)),
    ]
    for name in ("world", "deck"):
        biggest = np.nanquantile(xi[f"{name}_max_rad"], QUANTILES)
        longest = xi[f"{name}_longest_over_s"]
        stretch = np.nanquantile(longest, QUANTILES)
        shares = [float(np.nanmean(longest >= s)) for s in STRETCHES_S]
        cells = [
            " / ".join(f"{x:.3f}" for x in biggest),
            " / ".join(f"{x:.2f}" for x in stretch),
            *[f"{x:.3f}" for x in shares],
            *[f"{p[f'{name}_max_rad']:.3f} rad, {p[f'{name}_longest_over_s']:.2f} s" for p in probe.values()],
        ]
        lines.append(f"| apparent vertical from the {name}'s | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--episodes", type=int, default=2000, help="Xi_eval's first K episodes")
    p.add_argument("--benchmark", type=Path, default=eval_build.DEFAULT_BENCHMARK)
    p.add_argument("--batch-envs", type=int, default=1024)
    p.add_argument("--out", type=Path, required=True, help="the JSON to write")
    p.add_argument("--force", action="store_true", help="overwrite --out")
    args = p.parse_args(argv)
    claims = contextlib.ExitStack()
    try:  # the files named, before the minutes of replay
        check_out_file(args.out, suffixes=(".json",), force=True, option="--out")
        bench = eval_build.load_or_make_benchmark(args.benchmark)
        # claimed last (create-exclusive): a file already there is refused without --force
        claims.enter_context(claim_output(args.out, force=args.force, option="--out"))
    except (*cli.INPUT_ERRORS, InputError, OSError) as err:
        p.error(str(err))
    with claims:  # the claim is removed if the replay fails
        if not 1 <= args.episodes <= bench.num_trajectories:
            p.error(f"--episodes must be in [1, {bench.num_trajectories}], got {args.episodes}")
        from lasmp.config.base import build_env_cfg
        from lasmp.envs.moving_platform.cfg import MovingPlatformCfg

        env_cfg = build_env_cfg(eval_build.eval_env_overrides(args.batch_envs, 0), schema=MovingPlatformCfg)
        xi = pp.probe_platform(env_cfg, bench, args.episodes, args.batch_envs, stats=platform_stats)
        probe = probe_motion_stats(env_cfg.sim.dt_s * env_cfg.sim.decimation)
        text = table(xi, probe)
        print(text)
        result = {
            "benchmark": str(args.benchmark),
            "episodes": args.episodes,
            "threshold_rad": THRESHOLD_RAD,
            "xi_eval": {k: [None if np.isnan(x) else float(x) for x in v] for k, v in xi.items()},
            "probe_motions": probe,
            "table": text,
        }
        args.out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.out, json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
