"""What a policy's explicit estimator says during the level-acceleration probe's motions.

    python scripts/level_acceleration_estimates.py --checkpoint resources/policies/lasmp_a1.pt --out DIR

Plays lasmp.motions.level_push's motions (a steady level push, its equivalent tilt, a
slow ramp to the push's final speed) to the benchmark's first R robots, as the real-motion suite
does, and records at every step the true and the estimated x_exp (v_body_b, v_plf_b) and the
alignment command the actor is given (u_aln from the estimates: v_plf_b,xy - v_body_b,xy and the
yaw-rate difference), with the trunk's posture: its tilt from the world's vertical and from the
apparent vertical, the direction of a_plf - g at the platform (a trunk that balances a rigid stance
aligns with the apparent vertical; a level push turns it by atan(1.5 / 9.81) = 0.152 rad, as the
equivalent tilt does the deck). A constant velocity is invisible to the proprioceptive history; an
acceleration is not. Writes DIR/estimates.json: per motion and per 0.5 s window, the mean over the
robots still standing of the true and estimated speeds |v_plf_b,xy| and |v_body_b,xy|, the
estimate errors, |u_aln_hat,xy| and the two tilts, and the fall times; and DIR/estimates.png.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import torch

from lasmp.algo.checkpoint import checkpoint_file
from lasmp.eval import build as eval_build
from lasmp.eval import cli
from lasmp.eval.benchmark import Benchmark
from lasmp.eval.real_motion import suite as rm
from lasmp.eval.report import atomic_write_text
from lasmp.eval.run import run_benchmark
from lasmp.io.atomic import atomic_write_with, claim_output
from lasmp.io.inputs import InputError, check_out_file
from lasmp.modules.obs_groups import GYRO_Z_COL, alignment_from_estimates
from lasmp.motions import level_push

WINDOW_S = 0.5
V_BODY, V_PLF = slice(4, 6), slice(7, 9)  # the xy columns of v_body_b and v_plf_b in x_exp
GRAVITY_W = np.array([0.0, 0.0, -9.81])


def record(args, bench: Benchmark) -> tuple[dict, dict[str, np.ndarray], float, list[str]]:
    """Play the motions to the benchmark's robots; (per-episode results, per-step arrays (T, n, ...):
    the true and estimated x_exp, u_aln_hat, the trunk's z axis and the platform's velocity in W; dt,
    the motions' names)."""
    motions = level_push.motions()
    episodes = rm.make_episodes(motions, bench.robots, args.robots_per_scenario)
    extra = rm.env_overrides(max(m.duration_s for m in motions), rm.DEFAULT_DRIVE)
    build_args = SimpleNamespace(
        batch_envs=episodes.num_episodes,
        num_trajectories=episodes.num_episodes,
        seed=args.seed,
        controller=None,
        checkpoint=args.checkpoint,
    )
    env, controller, policy, _ = eval_build.build(build_args, extra)
    if policy is None or policy.explicit_estimator is None:
        raise SystemExit("error: the checkpoint's policy has no explicit estimator to record")
    steps: dict[str, list] = {k: [] for k in ("true_x", "est_x", "est_u", "z_trunk_w", "v_plf_w")}

    def recording(obs):
        if not steps["true_x"] and not np.array_equal(
            env.episode_source.episode_of_env, np.arange(env.num_envs)
        ):
            raise RuntimeError("expected env k to play episode k")
        x_hat, _ = policy.estimates(obs)
        steps["true_x"].append(obs["priv_explicit"][:, : x_hat.shape[1]].numpy().copy())
        steps["est_x"].append(x_hat.numpy().copy())
        steps["est_u"].append(alignment_from_estimates(x_hat, obs["policy"][:, GYRO_Z_COL]).numpy().copy())
        steps["z_trunk_w"].append(env.readout.r_wb[:, :, 2].cpu().numpy().copy())
        steps["v_plf_w"].append(env.readout.v_plf_w.cpu().numpy().copy())
        return controller(obs)

    with torch.inference_mode():
        run = run_benchmark(
            env, recording, episodes, episodes.num_episodes, progress=False, shrink_tail=False
        )
    return run["episodes"], {k: np.stack(v) for k, v in steps.items()}, env.dt_s, [m.name for m in motions]


def tilts(z_trunk_w: np.ndarray, v_plf_w: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(T, n) angles, rad, of the trunk's z axis from the world's vertical and from the apparent
    vertical a_plf - g (a_plf: the platform's velocity differenced over the steps)."""
    a = np.gradient(v_plf_w, dt, axis=0)
    up = a - GRAVITY_W
    up /= np.linalg.norm(up, axis=-1, keepdims=True)
    world = np.arccos(np.clip(z_trunk_w[..., 2], -1.0, 1.0))
    apparent = np.arccos(np.clip(np.sum(z_trunk_w * up, axis=-1), -1.0, 1.0))
    return world, apparent


def summarize(per_episode, arrays: dict[str, np.ndarray], dt, names, robots) -> dict:
    true_x, est_x, est_u = arrays["true_x"], arrays["est_x"], arrays["est_u"]
    tilt_world, tilt_apparent = tilts(arrays["z_trunk_w"], arrays["v_plf_w"], dt)
    steps = np.nan_to_num(per_episode["steps"]).astype(int)
    fell = per_episode["collision"] > 0.5
    n_window = int(round(WINDOW_S / dt))
    out = {"window_s": WINDOW_S, "motions": {}}
    for i, name in enumerate(names):
        rows = np.arange(i * robots, (i + 1) * robots)
        standing = np.arange(true_x.shape[0])[:, None] < steps[rows][None, :]  # (T, R)
        series = {
            "v_plf_true": np.linalg.norm(true_x[:, rows, V_PLF], axis=-1),
            "v_plf_est": np.linalg.norm(est_x[:, rows, V_PLF], axis=-1),
            "v_body_true": np.linalg.norm(true_x[:, rows, V_BODY], axis=-1),
            "v_body_est": np.linalg.norm(est_x[:, rows, V_BODY], axis=-1),
            "v_plf_error": np.linalg.norm(est_x[:, rows, V_PLF] - true_x[:, rows, V_PLF], axis=-1),
            "u_aln_true": np.linalg.norm(true_x[:, rows, V_PLF] - true_x[:, rows, V_BODY], axis=-1),
            "u_aln_est": np.linalg.norm(est_u[:, rows, :2], axis=-1),
            "tilt_world_rad": tilt_world[:, rows],
            "tilt_from_apparent_vertical_rad": tilt_apparent[:, rows],
        }
        windows = []
        for start in range(0, true_x.shape[0], n_window):
            sel = standing[start : start + n_window]
            if not sel.any():
                break
            w = {"t_s": round((start + n_window / 2) * dt, 3), "robots_standing": int(sel[-1].sum())}
            w.update({k: float(v[start : start + n_window][sel].mean()) for k, v in series.items()})
            windows.append(w)
        out["motions"][name] = {
            "falls": int(fell[rows].sum()),
            "fall_times_s": sorted(float(x) for x in per_episode["collision_time_s"][rows][fell[rows]]),
            "windows": windows,
        }
    return out


def plot(summary: dict, path: Path) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plot", file=sys.stderr)
        return
    names = list(summary["motions"])
    fig, axes = plt.subplots(1, len(names), figsize=(5 * len(names), 3.6), sharey=True)
    for ax, name in zip(np.atleast_1d(axes), names, strict=True):
        m = summary["motions"][name]
        t = [w["t_s"] for w in m["windows"]]
        for key, style in (
            ("v_plf_true", "k-"),
            ("v_plf_est", "C0-"),
            ("u_aln_true", "k:"),
            ("u_aln_est", "C3-"),
        ):
            ax.plot(t, [w[key] for w in m["windows"]], style, label=key)
        for ft in m["fall_times_s"]:
            ax.axvline(ft, color="C1", alpha=0.3, lw=1)
        ax.set_title(f"{name}: {m['falls']} falls")
        ax.set_xlabel("t (s)")
    np.atleast_1d(axes)[0].set_ylabel("m/s (mean over the robots standing)")
    np.atleast_1d(axes)[0].legend(fontsize=8)
    fig.tight_layout()
    atomic_write_with(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--checkpoint", required=True, help="a LAS-MP checkpoint with an explicit estimator")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--benchmark", type=Path, default=eval_build.DEFAULT_BENCHMARK)
    p.add_argument("--robots-per-scenario", type=int, default=rm.DEFAULT_ROBOTS_PER_SCENARIO)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--force", action="store_true", help="overwrite DIR/estimates.json and DIR/estimates.png")
    args = p.parse_args(argv)
    torch.set_num_threads(1)  # as evaluate.py: more threads contend with the physics thread pool
    target, figure = args.out / "estimates.json", args.out / "estimates.png"
    claims = contextlib.ExitStack()
    try:  # the files named, before the minutes of play
        check_out_file(target, suffixes=(".json",), force=True, option="--out")
        args.checkpoint = checkpoint_file(args.checkpoint)
        bench = eval_build.load_or_make_benchmark(args.benchmark)
        # both files claimed last (create-exclusive): one already there is refused without --force
        for path in (target, figure):
            claims.enter_context(claim_output(path, force=args.force, option="--out"))
    except (*cli.INPUT_ERRORS, InputError, OSError) as err:
        claims.close()
        p.error(str(err))
    with claims:  # a claim not written (a failed play, no matplotlib) is removed
        per_episode, arrays, dt, names = record(args, bench)
        summary = {"checkpoint": str(args.checkpoint), "robots_per_scenario": args.robots_per_scenario}
        summary.update(summarize(per_episode, arrays, dt, names, args.robots_per_scenario))
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(target, json.dumps(summary, indent=1))
        plot(summary, figure)
        for name, m in summary["motions"].items():
            print(f"{name}: {m['falls']} falls")
            for w in m["windows"][::2]:
                print(
                    f"  t {w['t_s']:5.2f} s  standing {w['robots_standing']:3d}  |v_plf| true {w['v_plf_true']:5.2f} "
                    f"est {w['v_plf_est']:5.2f}  |u_aln| true {w['u_aln_true']:5.2f} est {w['u_aln_est']:5.2f}  "
                    f"tilt: world {w['tilt_world_rad']:5.3f} apparent {w['tilt_from_apparent_vertical_rad']:5.3f}"
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
