"""Is friction isotropic (docs/world.md, The robot)? The tilt at which a block and the standing A1 start to slide on a
slowly tilting platform, per downhill direction and contact setting, against atan(mu).

World: the moving-platform world of `lasmp/envs/moving_platform/scene.py` (its options, default solref/solimp, the
platform's box, the feet's priority-1 friction), built by its own builder. Block runs delete the
robot and add a 12 kg block on four 0.02 m sphere feet like the A1's (condim 3), 0.2 m apart, its
axes the platform's; robot runs keep the A1, facing +x, under its own position servos (PD to
q_nominal, Kp 40, Kd 1: the env with zero actions), with the feet's friction set to mu. The
platform's PD follows a tilt about a horizontal axis at `--rate-deg-s` (0.5), chosen so that the
downhill direction lies at the given azimuth from the platform's x axis (0 = the robot's forward,
90 = its left); the tilt reported is the platform's own.

Robot stance: "dropped" = set down at the nominal stance and settled 1 s with friction, as the env
spawns it (the legs sag under the weight with the feet held: with no-slip, lateral forces of
about 0.25 N per N of load stay locked in the feet; without, the feet creep them away);
"relaxed" = settled 1.5 s on frictionless feet first (condim 1), then 1 s with friction, so that
the ramp starts without locked-in forces.

Onset of sliding: within the last `WINDOW_S` (1 s) the block, or every one of the robot's four
feet (the whole robot, not one unloaded foot: `first_foot_slip_deg` reports that), has moved more
than `--onset-mm` (5 mm) along the platform's surface (platform frame). Slower creep does not count
as onset; its speed at 0.9 atan(mu) is reported. A Coulomb block needs ~0.7 s past atan(mu) to
cover 5 mm at 0.5 deg/s, so onsets read ~0.3 deg (~1 %) late. A robot run ends as toppled instead
if a foot leaves the surface for 0.1 s or the trunk leans 0.3 rad from the platform's normal first.
At onset, `friction_usage` = sum |f_t| / (mu sum f_n) over the block's or feet's contacts (1 = every
contact on the boundary of an isotropic cone of slope mu) and `holding_usage` its uphill share.

The protocol's pieces live in bench/slide_protocol.py; its `fixed_tilt_slip` is the coarse form that
tests/test_friction_cone.py runs (fixed tilts, see there).

Step cost: single-model `mj_step` time of the robot world (relaxed stance, foot friction 1, the
platform tilted 10 deg), settings interleaved in one run, as a ratio to the "pyramidal" setting
(impratio 1, no noslip); `--env-envs N` adds the moving-platform env (Stand Still, its default
randomization and trajectories, N envs on `mujoco.batch`), timed the same way.

    python bench/friction_cone.py --json
    python bench/friction_cone.py --settings pyramidal,elliptic --directions 0,45 --json
    python bench/friction_cone.py --env-envs 1024 --json
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import sys
import time

import lasmp  # noqa: F401  (first: it sets the OpenMP spin that torch reads when it loads)

# isort: split
import mujoco
import numpy as np

# the protocol's pieces, beside this script (python puts a script's own directory on the path)
from slide_protocol import (
    BLOCK_HALF_SPAN_M,
    BLOCK_MASS_KG,
    DIRECTIONS_DEG,
    ENV_WARMUP_STEPS,
    RELAX_S,
    SETTINGS,
    SETTLE_S,
    PlatformDrive,
    robot_model,
    robot_stance,
    sim_cfg,
    slide_onset,
)

from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.robots import a1


def step_cost(settings: list[str], steps: int, rounds: int) -> dict:
    """Single-model mj_step time of the robot world (relaxed stance, foot friction 1, the platform
    tilted 10 deg), settings interleaved per round; `contacts` = mean contacts while timed (4 = standing)."""
    runs = {}
    for s in settings:
        model = robot_model(sim_cfg(s), 1.0)
        data = mujoco.MjData(model)
        robot_stance(model, data)
        feet = [model.geom(f).id for f in a1.FOOT_NAMES]
        drive = PlatformDrive(model, math.radians(30.0))
        theta, dt = math.radians(10.0), model.opt.timestep
        model.geom_condim[feet] = 1
        for _ in range(int(RELAX_S / dt)):
            mujoco.mj_step(model, data)
        model.geom_condim[feet] = 3
        for k in range(400):  # tilt to 10 deg over 2 s, then hold
            drive.apply(data, theta * min(1.0, k / 400), theta * min(1.0, (k + 1) / 400), dt)
            mujoco.mj_step(model, data)
        drive.apply(data, theta, theta, dt)
        runs[s] = (model, data, [], [])
    snapshots = {s: copy.copy(data) for s, (_, data, _, _) in runs.items()}
    for _ in range(rounds):
        for s, (model, data, times, contacts) in runs.items():
            mujoco.mj_copyData(data, model, snapshots[s])  # every round from the same state (creep)
            start = time.perf_counter()
            for _ in range(steps):
                mujoco.mj_step(model, data)
            times.append((time.perf_counter() - start) / steps)
            contacts.append(data.ncon)
    ref = np.median(runs[settings[0]][2])
    return {
        s: {
            "us_per_step": 1e6 * float(np.median(times)),
            "ratio": float(np.median(times) / ref),
            "contacts": float(np.mean(contacts)),
        }
        for s, (_, _, times, contacts) in runs.items()
    }


def env_cost(settings: list[str], num_envs: int, steps: int, rounds: int) -> dict:
    """Moving-platform env policy steps (Stand Still), settings interleaved per round."""
    import torch

    from lasmp.config.base import build_env_cfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    envs = {}
    for s in settings:
        cone, impratio, noslip = SETTINGS[s]
        sim = {"cone": cone, "impratio": impratio, "noslip_iterations": noslip}
        env = MovingPlatformEnv(build_env_cfg({"num_envs": num_envs, "sim": sim}, schema=MovingPlatformCfg))
        env.reset()
        envs[s] = (env, [], [])
    actions = torch.zeros(num_envs, 12)
    for env, _, _ in envs.values():  # past the first drop onto the platform
        for _ in range(ENV_WARMUP_STEPS):
            env.step(actions)
    for _ in range(rounds):
        for env, times, physics in envs.values():
            start, physics_s = time.perf_counter(), env.sim.step_time_s
            for _ in range(steps):
                env.step(actions)
            times.append((time.perf_counter() - start) / steps)
            physics.append((env.sim.step_time_s - physics_s) / steps)
    ref, ref_physics = np.median(envs[settings[0]][1]), np.median(envs[settings[0]][2])
    return {
        s: {
            "ms_per_policy_step": 1e3 * float(np.median(times)),
            "ratio": float(np.median(times) / ref),
            "physics_ratio": float(np.median(physics) / ref_physics),
        }
        for s, (_, times, physics) in envs.items()
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--settings", default=",".join(SETTINGS), help=f"comma list of {list(SETTINGS)}")
    ap.add_argument(
        "--directions", default=",".join(str(d) for d in DIRECTIONS_DEG), help="downhill azimuths, deg"
    )
    ap.add_argument("--block-mu", default="0.5,1.0", help="comma list of block frictions")
    ap.add_argument("--robot-mu", default="0.3", help="comma list of foot frictions ('' = no robot runs)")
    ap.add_argument("--robot-stance", default="relaxed,dropped", help="comma list of relaxed | dropped")
    ap.add_argument("--rate-deg-s", type=float, default=0.5)
    ap.add_argument("--onset-mm", type=float, default=5.0)
    ap.add_argument("--cost-steps", type=int, default=2000, help="mj_step calls per setting and round")
    ap.add_argument("--cost-rounds", type=int, default=7)
    ap.add_argument("--env-envs", type=int, default=0, help="also time the env on this many envs (0 = no)")
    ap.add_argument("--env-steps", type=int, default=20, help="env policy steps per setting and round")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    settings = args.settings.split(",")
    unknown = [s for s in settings if s not in SETTINGS]
    if unknown:
        ap.error(f"unknown settings {unknown}; known: {list(SETTINGS)}")
    if settings[0] != "pyramidal":
        settings.insert(0, "pyramidal")  # the cost reference
    directions = [float(d) for d in args.directions.split(",")]
    cases = [("block", float(mu), "") for mu in args.block_mu.split(",") if mu]
    cases += [
        ("robot", float(mu), st)
        for mu in args.robot_mu.split(",")
        if mu
        for st in args.robot_stance.split(",")
    ]
    rows = []
    for s in settings:
        for what, mu, stance in cases:
            for az in directions:
                row = slide_onset(s, what, mu, az, args.rate_deg_s, args.onset_mm, stance or "relaxed")
                rows.append(row)
                if not args.json:
                    onset = "--" if row["onset_deg"] is None else f"{row['onset_deg']:.2f}"
                    ratio = "--" if row["ratio_to_atan_mu"] is None else f"{row['ratio_to_atan_mu']:.3f}"
                    creep = row["creep_mm_s_at_0.9_atan_mu"]
                    print(
                        f"{s:20s} {what:5s} {stance:7s} mu {mu:.2f} az {az:5.1f}: {row['event']:7s} at {onset} deg"
                        f" (atan mu {row['atan_mu_deg']:.2f}, ratio {ratio}; creep at 0.9 atan mu"
                        f" {'--' if creep is None else f'{creep:.2f}'} mm/s)",
                        flush=True,
                    )
    out = {
        "protocol": {
            "rate_deg_s": args.rate_deg_s,
            "onset_mm": args.onset_mm,
            "settle_s": SETTLE_S,
            "block_mass_kg": BLOCK_MASS_KG,
            "block_half_span_m": BLOCK_HALF_SPAN_M,
        },
        "settings": {
            s: dict(zip(("cone", "impratio", "noslip_iterations"), SETTINGS[s], strict=True))
            for s in settings
        },
        "cases": rows,
        "worst_ratio": {
            s: {
                f"{what} {stance} mu {mu}".replace("  ", " "): _worst(
                    [
                        r
                        for r in rows
                        if r["setting"] == s
                        and r["what"] == what
                        and r["mu"] == mu
                        and r.get("stance", "") == stance
                    ]
                )
                for what, mu, stance in cases
            }
            for s in settings
        },
        "step_cost_mj_step": step_cost(settings, args.cost_steps, args.cost_rounds),
    }
    if args.env_envs:
        out["step_cost_env"] = env_cost(settings, args.env_envs, args.env_steps, args.cost_rounds)
    if args.json:
        print(json.dumps(out))
    else:
        for key in ("worst_ratio", "step_cost_mj_step", "step_cost_env"):
            if key in out:
                print(key, json.dumps(out[key], indent=1))
    return 0


def _worst(rows: list[dict]) -> float | None:
    """The ratio onset / atan mu farthest from 1 (None if any run did not slide)."""
    ratios = [r["ratio_to_atan_mu"] for r in rows]
    if not ratios or any(r is None for r in ratios):
        return None
    return max(ratios, key=lambda r: abs(r - 1.0))


if __name__ == "__main__":
    sys.exit(main())
