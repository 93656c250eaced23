"""The real-motion suite: named scenarios, their episodes, the platform drive they run on, and results.

Scenarios (:data:`SCENARIOS`): ship decks in four sea states (WMO codes 3-6), a city bus
(stop-and-go, emergency brake), a train (curve, straight), a lift (up, down, emergency stop) and an
aircraft in light, moderate and severe turbulence, each a :class:`~lasmp.motions.motion.Motion` of
:data:`~lasmp.motions.motion.DEFAULT_DURATION_S` from its generator in :mod:`lasmp.motions` with
seed 0 (one realisation per scenario, the same for every controller).

Episodes (:class:`SuiteEpisodes`): every scenario is played with the first R robots of Xi_eval
(default R = 64, testing intrinsics): episode k plays scenario k // R with robot k % R. So every
controller meets the same (scenario, robot) pairs, as on the benchmark, and each pair starts at the
heading of its own draws (:meth:`SuiteEpisodes.initial_pose_draws`), whichever scenarios run.

The platform drive (:data:`PLATFORM_DRIVES`). The suite asks whether a policy survives the motion
a real vehicle makes, so by default (``close``) the platform follows its reference closely: a 4 Hz
drive (omega_n = 25.13 rad/s at gain factor 1) with velocity feedforward, on an 800 kg platform.
The paper's world (``paper``, the env's defaults) drives the platform through a soft position servo,
which filters much of a vehicle's motion away. How closely each follows the scenarios:
docs/real_motion.md#the-platform-drive; every result records it per scenario (``platform_tracking``).
Episodes last the scenarios' duration, not the training episodes' 10 s.
"""

from __future__ import annotations

import importlib
import json
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lasmp.envs import trajectories as trj
from lasmp.envs.moving_platform.domain_rand import Intrinsics
from lasmp.eval.benchmark import episode_draws
from lasmp.eval.metrics import ALL_METRICS, EPISODE_KEY, METRICS, summarize
from lasmp.eval.report import inputs_line
from lasmp.motions.motion import Motion, derivatives, to_trajectories

SUITE_NAME = "real_motion"
DEFAULT_ROBOTS_PER_SCENARIO = 64
NUM_BATCHES = 8  # per scenario: mean +- std over 8 consecutive batches of robots
POSE_STREAM = 3  # the first entry of each episode's key for its initial pose (Xi_eval's are [seed, 2, k])


def _variant(module: str, function: str, variant: str) -> Callable[[], Motion]:
    """`lasmp.motions.<module>.<function>(variant)`, imported when the scenario is built."""

    def make() -> Motion:
        return getattr(importlib.import_module(f"lasmp.motions.{module}"), function)(variant)

    return make


SCENARIOS: dict[str, Callable[[], Motion]] = {
    "ship_sea_state_3": _variant("ship", "ship_deck", "sea_state_3"),
    "ship_sea_state_4": _variant("ship", "ship_deck", "sea_state_4"),
    "ship_sea_state_5": _variant("ship", "ship_deck", "sea_state_5"),
    "ship_sea_state_6": _variant("ship", "ship_deck", "sea_state_6"),
    "bus_stop_and_go": _variant("bus", "city_bus", "stop_and_go"),
    "bus_emergency_brake": _variant("bus", "city_bus", "emergency_brake"),
    "train_curve": _variant("rail", "train", "curve"),
    "train_straight": _variant("rail", "train", "straight"),
    "lift_up": _variant("lift", "lift", "up"),
    "lift_down": _variant("lift", "lift", "down"),
    "lift_emergency_stop": _variant("lift", "lift", "emergency_stop"),
    "aircraft_light": _variant("aircraft", "aircraft", "light"),
    "aircraft_moderate": _variant("aircraft", "aircraft", "moderate"),
    "aircraft_severe": _variant("aircraft", "aircraft", "severe"),
}

# env.platform overrides per drive (docs/real_motion.md, "The platform drive")
PLATFORM_DRIVES: dict[str, dict] = {
    "close": {"omega_n_rad_s": 25.13, "velocity_feedforward": True, "mass_kg": 800.0},
    "paper": {},
}
DEFAULT_DRIVE = "close"


def scenario_names(names: list[str] | None = None) -> list[str]:
    """`names` checked against the suite (all scenarios when None)."""
    if names is None:
        return list(SCENARIOS)
    unknown = [n for n in names if n not in SCENARIOS]
    if unknown:
        raise ValueError(f"unknown scenario(s) {unknown}; valid: {list(SCENARIOS)}")
    if not names:
        raise ValueError("no scenario selected")
    return list(names)


def build_motions(names: list[str] | None = None) -> list[Motion]:
    """The suite's motions (all, or the named ones), in suite order."""
    motions = []
    for name in scenario_names(names):
        m = SCENARIOS[name]()
        m.name = name
        motions.append(m)
    return motions


@dataclass
class SuiteEpisodes:
    """Scenario x robot episodes: episode k plays scenario k // R with robot k % R."""

    trajectories: trj.PiecewisePoly  # one row per scenario
    robots: Intrinsics  # R robots
    names: list[str]

    @property
    def robots_per_scenario(self) -> int:
        return int(self.robots.trunk_mass_kg.shape[0])

    @property
    def num_episodes(self) -> int:
        return len(self.names) * self.robots_per_scenario

    def pairing(self, episodes) -> tuple[np.ndarray, np.ndarray]:
        k = np.asarray(episodes, dtype=np.int64)
        if k.size and (k.min() < 0 or k.max() >= self.num_episodes):
            raise IndexError(f"episode indices must be in 0..{self.num_episodes - 1}")
        return k // self.robots_per_scenario, k % self.robots_per_scenario

    def initial_pose_draws(self, episodes) -> np.ndarray:
        """(n, 3) uniforms from which episodes k start: each from a generator keyed by its scenario's
        name (CRC-32) and its robot, so a scenario run alone starts as it does in the full suite."""
        scenario, robot = self.pairing(episodes)
        keys = [
            [POSE_STREAM, zlib.crc32(self.names[s].encode()), int(r)]
            for s, r in zip(scenario, robot, strict=True)
        ]
        return episode_draws(keys)

    def scenario_slice(self, i: int) -> slice:
        r = self.robots_per_scenario
        return slice(i * r, (i + 1) * r)


def make_episodes(motions: list[Motion], bench_robots: Intrinsics, robots_per_scenario: int) -> SuiteEpisodes:
    """The suite's episodes with the benchmark's first `robots_per_scenario` robots."""
    available = int(bench_robots.trunk_mass_kg.shape[0])
    if not 1 <= robots_per_scenario <= available:
        raise ValueError(f"robots per scenario must be in [1, {available}], got {robots_per_scenario}")
    robots = Intrinsics(**{k: v[:robots_per_scenario] for k, v in vars(bench_robots).items()})
    return SuiteEpisodes(to_trajectories(motions), robots, [m.name for m in motions])


def env_overrides(duration_s: float, drive: str) -> dict:
    """env overrides for the suite: its episode length and platform drive."""
    if drive not in PLATFORM_DRIVES:
        raise ValueError(f"unknown platform drive {drive!r}; valid: {list(PLATFORM_DRIVES)}")
    return {"trajectory": {"duration_s": duration_s, "hold_s": 0.0}, "platform": dict(PLATFORM_DRIVES[drive])}


def per_scenario(episodes: SuiteEpisodes, per_episode: dict[str, np.ndarray]) -> dict[str, dict]:
    """Each scenario's five metrics (mean +- std over NUM_BATCHES batches of its robots)."""
    out = {}
    for i, name in enumerate(episodes.names):
        sl = episodes.scenario_slice(i)
        out[name] = {
            "metrics": summarize({k: v[sl] for k, v in per_episode.items()}, NUM_BATCHES),
            "num_episodes": episodes.robots_per_scenario,
            "mean_episode_steps": float(np.mean(per_episode["steps"][sl])),
        }
    return out


def suite_result(method, episodes, motions, run, tracking, drive, benchmark, inputs) -> dict:
    """The suite's metrics.json, as evaluate.py's: the method, its inputs (`inputs`: the seed and
    the SHA-256 of the robots' benchmark file and of the checkpoint), then per scenario and overall
    (`run`: `run_benchmark`'s), the platform's tracking and the reference motions."""
    per_episode = run["episodes"]
    result = {
        "method": method,
        "suite": SUITE_NAME,
        "benchmark_robots": str(benchmark),
        **inputs,
        "robots_per_scenario": episodes.robots_per_scenario,
        "duration_s": max(m.duration_s for m in motions),
        "platform_drive": drive,
        "platform_drive_overrides": PLATFORM_DRIVES[drive],
        "num_episodes": episodes.num_episodes,
        "scenarios": per_scenario(episodes, per_episode),
        "overall": summarize(per_episode, len(episodes.names)),
        "platform_tracking": tracking,
        "reference_motion": {m.name: motion_summary(m) for m in motions},
        "wall_time_s": run["wall_time_s"],
    }
    if "estimator" in run:
        result["estimator"] = run["estimator"]
    return result


EPISODE_COLUMNS = (
    "episode",
    "scenario",
    "robot",
    "initial_yaw_rad",  # the trunk's heading at the start, from the vehicle's forward axis (world x)
    "collision",
    "collision_time_s",
    "collision_cause",
    "steps",
    *(EPISODE_KEY[m] for m in ALL_METRICS if m != "collision_rate"),
)


def episode_table(episodes: SuiteEpisodes, per_episode: dict[str, np.ndarray], init) -> dict[str, np.ndarray]:
    """EPISODE_COLUMNS -> arrays, one row per (scenario, robot) episode (`run_benchmark`'s episodes);
    `init`: the env's init_state, which maps each episode's pose draws to its heading."""
    from lasmp.envs.moving_platform.env import initial_pose

    k = np.arange(episodes.num_episodes)
    scenario, robot = episodes.pairing(k)
    yaw, _ = initial_pose(episodes.initial_pose_draws(k), init.yaw_range_rad, init.xy_offset_max_m)
    table = {
        "episode": k,
        "scenario": np.array(episodes.names)[scenario],
        "robot": robot,
        "initial_yaw_rad": yaw,
    }
    return table | {c: per_episode[c] for c in EPISODE_COLUMNS if c not in table}


def motion_summary(m: Motion) -> dict[str, float]:
    """Peaks and RMS of a motion's reference: linear acceleration, angular rate, excursions."""
    v, a = derivatives(m)
    acc = np.linalg.norm(a[:, :3], axis=1)
    rate = trj.angular_rate(m.pose, v)
    return {
        "acc_rms_mps2": float(np.sqrt(np.mean(acc**2))),
        "acc_max_mps2": float(acc.max()),
        "angular_rate_rms_rad_s": float(np.sqrt(np.mean(rate**2))),
        "angular_rate_max_rad_s": float(rate.max()),
        "travel_m": float(np.linalg.norm(m.pose[-1, :3])),
        "z_range_m": float(np.ptp(m.pose[:, 2])),
        "tilt_max_rad": float(np.abs(m.pose[:, 3:5]).max()),
    }


LABELS = {
    "collision_rate": "collision",
    "height_violation_rate": "height viol.",
    "position_deviation_m": "pos. dev. (m)",
    "rotation_deviation_rad": "rot. dev. (rad)",
    "power_w": "power (W)",
}


def markdown(result: dict) -> str:
    """The suite's table: scenarios x the five metrics (mean +- std), and the platform's tracking."""
    lines = [
        f"# {result['method']} on the real-motion suite",
        "",
        f"{result['robots_per_scenario']} benchmark robots per scenario, {result['duration_s']:.0f}-s episodes, "
        f"platform drive `{result['platform_drive']}`; mean ± std over {NUM_BATCHES} batches of robots "
        "(the last row: over scenarios).",
        "",
        "| scenario | " + " | ".join(LABELS[k] for k in METRICS) + " |",
        "|---|" + "---|" * len(METRICS),
    ]
    for name, s in result["scenarios"].items():
        cells = [f"{s['metrics'][k]['mean']:.3f} ± {s['metrics'][k]['std']:.3f}" for k in METRICS]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    o = result["overall"]
    lines.append(
        "| **all** | " + " | ".join(f"{o[k]['mean']:.3f} ± {o[k]['std']:.3f}" for k in METRICS) + " |"
    )
    tracking = result.get("platform_tracking")
    if tracking:
        lines += [
            "",
            "## How the platform followed each scenario (Stand Still, robot 0)",
            "",
            "| scenario | reference RMS acc. (m/s²) | platform RMS acc. (m/s²) | RMS error (m) | RMS error (rad) |",
            "|---|---|---|---|---|",
        ]
        for name, t in tracking.items():
            lines.append(
                f"| {name} | {t['reference_acc_rms_mps2']:.3f} | {t['platform_acc_rms_mps2']:.3f} | "
                f"{t['translation_error_rms_m']:.4f} | {t['rotation_error_rms_rad']:.4f} |"
            )
    lines += ["", *inputs_line(result), f"Wall time: {result['wall_time_s']:.1f} s.", ""]
    return "\n".join(lines)


def platform_tracking(episodes: SuiteEpisodes, env_overrides_: dict) -> dict[str, dict[str, float]]:
    """How the platform follows each scenario in the suite's world: Stand Still with robot 0, one env
    per scenario, until its first episode ends. RMS of the translational acceleration (second
    differences of the positions at the policy rate) of the platform and of its reference, and RMS
    tracking errors (translation m, rotation rad as the norm of the three joint angles)."""
    from lasmp.config.base import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv
    from lasmp.eval.run import BenchmarkSource
    from lasmp.eval.tracking import record_platform

    one_robot = SuiteEpisodes(
        episodes.trajectories,
        Intrinsics(**{k: v[:1] for k, v in vars(episodes.robots).items()}),
        episodes.names,
    )
    n = len(episodes.names)
    env = MovingPlatformEnv(build_env_cfg({**env_overrides_, "num_envs": n}, schema=MovingPlatformCfg))
    env.episode_source = BenchmarkSource(one_robot, n, n)
    env.reset()
    rec = record_platform(env)
    live = rec["live"]
    out = {}
    for i, name in enumerate(episodes.names):
        last = int(np.flatnonzero(live[:, i])[-1])  # recorded steps 0..last
        q, ref = rec["q"][: last + 1, i], rec["ref"][: last + 1, i]
        err = q - ref

        def acc_rms(x):
            a = np.diff(x[:, :3], n=2, axis=0) / env.dt_s**2
            return float(np.sqrt(np.mean(np.sum(a**2, axis=1)))) if len(a) else float("nan")

        out[name] = {
            "recorded_s": last * env.dt_s,
            "reference_acc_rms_mps2": acc_rms(ref),
            "platform_acc_rms_mps2": acc_rms(q),
            "translation_error_rms_m": float(np.sqrt(np.mean(np.sum(err[:, :3] ** 2, axis=1)))),
            "rotation_error_rms_rad": float(np.sqrt(np.mean(np.sum(err[:, 3:] ** 2, axis=1)))),
        }
    env.episode_source = None
    return out


def comparison_table(result_dirs: list, labels: list[str] | None = None) -> str:
    """Markdown: scenarios x controllers, each cell "collision rate / position deviation (m)", from
    the `metrics.json` of suite results (all of the same scenarios)."""
    results = [json.loads((Path(d) / "metrics.json").read_text()) for d in result_dirs]
    labels = labels or [Path(d).name for d in result_dirs]
    if len(labels) != len(results):
        raise ValueError(f"{len(labels)} labels for {len(results)} results")
    for r, d in zip(results, result_dirs, strict=True):
        if r.get("suite") != SUITE_NAME:
            raise ValueError(f"{d}: not a real-motion suite result")
    names = list(results[0]["scenarios"])
    if any(list(r["scenarios"]) != names for r in results):
        raise ValueError("the results cover different scenarios")

    def cell(m: dict) -> str:
        return f"{m['collision_rate']['mean']:.2f} / {m['position_deviation_m']['mean']:.3f}"

    lines = ["| scenario | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
    lines += [
        f"| {n} | " + " | ".join(cell(r["scenarios"][n]["metrics"]) for r in results) + " |" for n in names
    ]
    lines.append("| **all** | " + " | ".join(cell(r["overall"]) for r in results) + " |")
    return "\n".join(lines)
