"""Where a policy's world tilt comes from: a posture held, a sway about it, or the deck's tilt followed.

    python scripts/tilt_probe.py CHECKPOINT [--episodes 128] [--benchmark benchmarks/xi_eval.npz] [--json out.json [--force]]

evaluate.py's rotation deviation (world tilt) is, per episode, the mean angle between the trunk's z
axis at the start and at each step, in the trunk's heading frame (lasmp.eval.metrics). This plays
Xi_eval's first episodes, one per env, as evaluate.py plays them, and splits that angle into
- lean: the angle between the start's z axis and the episode's mean z axis (a posture held);
- swing: the mean angle between the episode's mean z axis and each step's (a sway about it);
- the lean's signed pitch (+ nose down) and roll (+ right side down) parts;
- the swing's gain on the deck's tilt: the least-squares slope of the trunk z axis' horizontal part
  on the deck's (the platform's z axis in the same heading frame), each about its episode's mean,
  pooled over every counted step: 1 sways with the deck, 0 holds its posture, below 0 leans against it;
- the swing's share below 0.5 Hz: the power of its pitch part in the episodes that run to the
  time-out (a slow sway, or a jitter).
Each figure averages over episodes, their steps before a collision counted as the metric counts them.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from lasmp.algo.checkpoint import checkpoint_file  # noqa: E402
from lasmp.envs.robot import as_numpy  # noqa: E402
from lasmp.eval.benchmark import Benchmark  # noqa: E402
from lasmp.eval.build import DEFAULT_BENCHMARK, build, load_or_make_benchmark  # noqa: E402
from lasmp.eval.cli import INPUT_ERRORS  # noqa: E402
from lasmp.eval.metrics import angle_between, in_heading, z_axis_h  # noqa: E402
from lasmp.eval.run import BenchmarkSource  # noqa: E402
from lasmp.io.atomic import atomic_open, claim_output  # noqa: E402
from lasmp.io.inputs import InputError, check_out_file, int_arg  # noqa: E402

SLOW_HZ = 0.5


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _pitch_roll(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (pitch, roll) of a z axis in a heading frame: pitch + nose down (z toward +x), roll + right
    side down (z toward -y)."""
    return np.arctan2(z[..., 0], z[..., 2]), np.arctan2(-z[..., 1], z[..., 2])


def _ratio(a: float, b: float) -> float:
    return float(a / b) if b > 0 else float("nan")


def _about_mean(v: np.ndarray, counted: np.ndarray) -> np.ndarray:
    """v (T, n, k) less each episode's mean over its counted steps (0 on the uncounted ones)."""
    w = counted[..., None]
    return np.where(w, v - (w * v).sum(axis=0) / w.sum(axis=0), 0.0)


def _mean_angle(a: np.ndarray, z: np.ndarray, counted: np.ndarray) -> np.ndarray:
    """(n,) per episode, the mean over its counted steps of the angle between a (n, 3) and z (T, n, 3)."""
    angles = angle_between(np.broadcast_to(a, z.shape).reshape(-1, 3), z.reshape(-1, 3)).reshape(
        counted.shape
    )
    return (counted * angles).sum(axis=0) / counted.sum(axis=0)


def tilt_split(
    z0: np.ndarray, z: np.ndarray, zp0: np.ndarray, zp: np.ndarray, counted: np.ndarray, dt_s: float
) -> dict:
    """The split (module docstring) from the trunk's z axis at the start z0 (n, 3) and per step z
    (T, n, 3), the deck's zp0 and zp likewise, all in the trunk's heading frame, and the steps the
    metric counts, counted (T, n). Per-episode arrays (NaN for an episode with no counted step) and
    the pooled gain and slow share."""
    w = counted[..., None].astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_z = _unit((w * z).sum(axis=0) / counted.sum(axis=0)[:, None])
        tilt, swing = _mean_angle(z0, z, counted), _mean_angle(mean_z, z, counted)
    lean = angle_between(z0, mean_z)
    (p0, r0), (p, r) = _pitch_roll(z0), _pitch_roll(mean_z)
    # the sway about each episode's mean against the deck's about its own: a lean held is not a gain
    with np.errstate(invalid="ignore", divide="ignore"):
        d, e = (_about_mean(z[..., :2], counted), _about_mean(zp[..., :2], counted))
    gain = _ratio((w * d * e).sum(), (w * e * e).sum())  # NaN for a deck that never tilts
    full = counted.all(axis=0)  # the episodes that ran to the time-out
    pitch = _pitch_roll(z[:, full])[0]
    power = np.abs(np.fft.rfft(pitch - pitch.mean(axis=0), axis=0)) ** 2
    f_hz = np.fft.rfftfreq(len(z), dt_s)
    slow = _ratio(power[(f_hz > 0) & (f_hz < SLOW_HZ)].sum(), power[f_hz > 0].sum())  # NaN: no sway
    return {
        "tilt": tilt,
        "lean": lean,
        "swing": swing,
        "lean_pitch": p - p0,
        "lean_roll": r - r0,
        "gain_on_deck_tilt": gain,
        "slow_share": slow,
        "episodes_to_time_out": int(full.sum()),
    }


def play(checkpoint: Path, episodes: int, bench: Benchmark) -> tuple[dict, float]:
    """Play the benchmark's first `episodes` (one per env, the policy of the checkpoint file,
    deterministic) and record the arrays tilt_split takes; (those arrays, the policy step in s)."""
    args = argparse.Namespace(
        batch_envs=episodes, num_trajectories=episodes, seed=0, controller=None, checkpoint=checkpoint
    )
    env, controller, _, _ = build(args, checkpoint=checkpoint)
    env.episode_source = BenchmarkSource(bench, episodes, episodes)
    step: dict = {}

    def capture(readout, collision):
        r = as_numpy(readout)
        step.update(r_wb=r.r_wb, r_wp=r.r_wp, collision=collision.cpu().numpy())

    env.on_step = capture
    obs, _ = env.reset()
    r0 = as_numpy(env.readout)
    z0, zp0 = z_axis_h(r0.r_wb), in_heading(r0.r_wp[:, :, 2], r0.r_wb)
    running = np.ones(episodes, bool)
    z, zp, counted = [], [], []
    with torch.inference_mode():
        while running.any():
            obs, _, done, _ = env.step(controller(obs))
            z.append(z_axis_h(step["r_wb"]))
            zp.append(in_heading(step["r_wp"][:, :, 2], step["r_wb"]))
            counted.append(running & ~step["collision"])
            running &= ~done.cpu().numpy()
    env.on_step = None
    return {
        "z0": z0,
        "z": np.array(z),
        "zp0": zp0,
        "zp": np.array(zp),
        "counted": np.array(counted),
    }, env.dt_s


def summary(split: dict) -> dict:
    """The means over episodes (NaN-free: an episode with no counted step is left out)."""
    out = {k: float(np.nanmean(v)) for k, v in split.items() if isinstance(v, np.ndarray)}
    out["abs_lean_pitch"] = float(np.nanmean(np.abs(split["lean_pitch"])))
    out["abs_lean_roll"] = float(np.nanmean(np.abs(split["lean_roll"])))
    return out | {k: v for k, v in split.items() if not isinstance(v, np.ndarray)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("checkpoint", type=Path)
    p.add_argument("--episodes", type=int_arg(1, 10_000), default=128)
    p.add_argument("--benchmark", type=Path, default=DEFAULT_BENCHMARK)
    p.add_argument("--json", type=Path, help="write the figures here too")
    p.add_argument("--force", action="store_true", help="overwrite --json if it exists")
    args = p.parse_args(argv)
    claims = contextlib.ExitStack()
    try:  # the files named, before the minutes of play
        checkpoint = checkpoint_file(args.checkpoint)
        if args.json:
            check_out_file(args.json, suffixes=(".json",), force=True, option="--json")
        bench = load_or_make_benchmark(args.benchmark)
        if args.json:  # claimed last (create-exclusive): a file already there is refused without --force
            claims.enter_context(claim_output(args.json, force=args.force, option="--json"))
    except (*INPUT_ERRORS, InputError, OSError) as err:
        p.error(str(err))
    with claims:  # the claim is removed if the play fails
        arrays, dt_s = play(checkpoint, args.episodes, bench)
        figures = summary(tilt_split(**arrays, dt_s=dt_s))
        for k, v in figures.items():
            print(f"{k:22s} {v:.4f}" if isinstance(v, float) else f"{k:22s} {v}")
        if args.json:
            with atomic_open(args.json, "w") as f:
                json.dump(
                    {"checkpoint": str(args.checkpoint), "episodes": args.episodes, **figures}, f, indent=1
                )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
