"""A physics bound on what any controller can do: the platform probe behind `episodes.csv.gz`'s
feasibility columns (`PROBE_COLUMNS` of `lasmp.eval.episodes`).

The platform probe. Each episode's platform motion is played in full (T), whatever the evaluated
controller did: the evaluation's world (the same env config) with Stand Still in an env whose
episodes never end before T (`_FullLengthEnv`; the 100 t platform does not feel the 12 kg robot, so
its motion is the evaluated episode's, and the same for every method). From that actual motion:
- `platform_tilt_max_rad`: the largest angle between the platform's z axis and the world's;
- `platform_acc_max_mps2`: the largest |a| of the platform's centre (finite differences of its
  velocity at the policy rate);
- the feasibility flag `forced`. At the centre point s of the top surface, the apparent gravity in
  the platform frame is g_app_p = R_wp^T (g_w - a_s), with a_s the point's acceleration: the time
  derivative of v_s = v_plf + omega x (R_wp [0, 0, top]), so the rotational terms (alpha x r and
  omega x (omega x r)) are in it. A Coulomb block (a point, friction mu = the episode's foot
  friction) starts at rest at the centre and slides on the surface under g_app_p's tangential part,
  with normal load -g_app_p,z. The episode is `forced` when the block ends up more than SLIDE_LIMIT_M
  from the centre (the platform's half-width: at the edge, a robot that slides like the block has
  fallen) or loses contact (normal load <= 0: the platform drops away faster than g). (ours) The
  block feels the field at the centre wherever it is, and no Coriolis force: a bound on the scale of
  the platform, not a model of the robot, which can step, brace and lean.
"""

from __future__ import annotations

import copy
import sys
import time
from dataclasses import dataclass

import numpy as np
import torch

from lasmp.eval.episodes import PROBE_COLUMNS
from lasmp.eval.run import BenchmarkSource

G_W = np.array([0.0, 0.0, -9.81])  # gravity in W, m/s^2 (MuJoCo's default)
SLIDE_LIMIT_M = 1.0  # block offset from the centre that counts as forced: the 2 m platform's half-width
BLOCK_SUBSTEPS = 4  # block integration steps per policy step (5 ms at the policy's 20 ms)


def apparent_gravity_p(
    dt_s: float, r_wp: np.ndarray, v_plf_w: np.ndarray, omega_plf_w: np.ndarray, top_m: float
) -> np.ndarray:
    """(T, m, 3) apparent gravity g - a_s at the top surface's centre s, in the platform frame, m/s^2,
    from a motion sampled every dt_s: r_wp (T, m, 3, 3), v_plf_w and omega_plf_w (T, m, 3) of the
    platform's centre (its CoM)."""
    lever_w = top_m * r_wp[..., :, 2]  # centre -> top centre, W
    v_top_w = v_plf_w + np.cross(omega_plf_w, lever_w)
    a_top_w = np.gradient(v_top_w, dt_s, axis=0) if len(v_top_w) > 1 else np.zeros_like(v_top_w)
    return np.einsum("...ji,...j->...i", r_wp, G_W - a_top_w)


@dataclass
class BlockResult:
    offset_max_m: np.ndarray  # (m,) largest distance of the block from the centre
    contact_lost: np.ndarray  # (m,) bool, the normal load went <= 0 at some sample
    forced: np.ndarray  # (m,) bool, offset beyond the limit or contact lost
    forced_time_s: np.ndarray  # (m,) when it first was (NaN where never)


def slide_block(
    g_app_p: np.ndarray,
    dt_s: float,
    mu: np.ndarray,
    limit_m: float = SLIDE_LIMIT_M,
    substeps: int = BLOCK_SUBSTEPS,
) -> BlockResult:
    """A Coulomb block (per unit mass) from rest at the centre under g_app_p (T, m, 3) sampled every
    dt_s (linear in between); friction coefficient mu (m,).

    Each substep h takes the tangential push (u' = u + h g_xy), then friction's impulse, at most
    mu N h against the motion: the block stops where that is enough (static friction holds it),
    so it never chatters around zero speed."""
    g = np.asarray(g_app_p, dtype=float)
    steps, m = g.shape[0], g.shape[1]
    mu = np.broadcast_to(np.asarray(mu, dtype=float), (m,))
    h = dt_s / substeps
    x, u = np.zeros((m, 2)), np.zeros((m, 2))
    offset_max = np.zeros(m)
    lost = -g[0, :, 2] <= 0.0
    forced_time = np.where(lost, 0.0, np.nan)
    for k in range(1, steps):
        for j in range(1, substeps + 1):
            w = j / substeps
            gk = (1.0 - w) * g[k - 1] + w * g[k]
            normal = -gk[:, 2]
            lost_now = normal <= 0.0
            u_trial = u + h * gk[:, :2]
            speed = np.linalg.norm(u_trial, axis=1)
            cap = mu * np.maximum(normal, 0.0) * h
            with np.errstate(invalid="ignore", divide="ignore"):
                scale = np.where(speed > cap, 1.0 - cap / speed, 0.0)
            live = ~(lost | lost_now)  # a block that left the surface stays where it left
            u = np.where(live[:, None], u_trial * scale[:, None], 0.0)
            x = x + h * u
            offset = np.linalg.norm(x, axis=1)
            offset_max = np.maximum(offset_max, offset)
            t = (k - 1 + w) * dt_s
            newly = np.isnan(forced_time) & (lost_now | (offset > limit_m))
            forced_time = np.where(newly, t, forced_time)
            lost |= lost_now
    forced = ~np.isnan(forced_time)
    return BlockResult(offset_max, lost, forced, forced_time)


def motion_stats(dt_s: float, r_wp, v_plf_w, omega_plf_w, mu, top_m: float) -> dict[str, np.ndarray]:
    """The probe columns (PROBE_COLUMNS) of m platform motions (T, m, ...) sampled every dt_s."""
    tilt = np.arccos(np.clip(r_wp[..., 2, 2], -1.0, 1.0))
    acc = np.gradient(v_plf_w, dt_s, axis=0) if len(v_plf_w) > 1 else np.zeros_like(v_plf_w)
    block = slide_block(apparent_gravity_p(dt_s, r_wp, v_plf_w, omega_plf_w, top_m), dt_s, mu)
    return {
        "platform_tilt_max_rad": tilt.max(axis=0),
        "platform_acc_max_mps2": np.linalg.norm(acc, axis=2).max(axis=0),
        "block_offset_max_m": block.offset_max_m,
        "block_contact_lost": block.contact_lost.astype(float),
        "forced": block.forced.astype(float),
        "forced_time_s": block.forced_time_s,
    }


def count_forced(probe: dict[str, np.ndarray]) -> int:
    """Episodes the probe found forced (those without a probe value are not counted)."""
    return int(np.nansum(probe["forced"]))


# -- the probe ---------------------------------------------------------------------------------


def _full_length_env_class():
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    class _FullLengthEnv(MovingPlatformEnv):
        """No collision or fall ends an episode (faults still do): the platform plays its whole trajectory."""

        def _evaluate(self):
            reward, collision, faulted, log = super()._evaluate()
            return reward, torch.zeros_like(collision), faulted, log

    return _FullLengthEnv


def probe_platform(
    env_cfg, bench, num_episodes: int, num_envs: int, progress: bool = True, stats=None
) -> dict[str, np.ndarray]:
    """The probe columns of benchmark episodes 0..num_episodes-1 (module docstring), in the world of
    `env_cfg` (a MovingPlatformCfg: the evaluation env's; its num_envs is replaced). An episode cut
    short by a fault has its probe columns NaN. `stats`: what to compute from each whole motion,
    called as `motion_stats` is (the default) and returning per-episode arrays under its own keys
    (scripts/apparent_vertical_stats.py measures other things of the same motions)."""
    stats = stats or motion_stats

    cfg = copy.deepcopy(env_cfg)
    cfg.num_envs = min(num_envs, num_episodes)
    env = _full_length_env_class()(cfg)
    n, horizon, dt = env.num_envs, env.max_episode_length, env.dt_s
    source = BenchmarkSource(bench, num_episodes, n)
    env.episode_source = source
    out: dict[str, np.ndarray] = {}
    buf = {
        "r_wp": np.zeros((horizon + 1, n, 3, 3)),
        "v": np.zeros((horizon + 1, n, 3)),
        "omega": np.zeros((horizon + 1, n, 3)),
    }
    length = np.zeros(n, dtype=int)  # samples recorded of each env's episode

    def record(readout, rows=None):
        rows = np.arange(n) if rows is None else rows
        k = length[rows]
        ok = k <= horizon
        rows, k = rows[ok], k[ok]
        buf["r_wp"][k, rows] = readout.r_wp[rows].cpu().numpy()
        buf["v"][k, rows] = readout.v_plf_w[rows].cpu().numpy()
        buf["omega"][k, rows] = readout.omega_plf_w[rows].cpu().numpy()
        length[rows] += 1

    env.on_step = lambda readout, collision: record(readout)
    env.reset()
    record(env.readout)
    done_count, zeros, last_print = 0, torch.zeros(n, env.num_actions), 0.0
    with torch.inference_mode():
        while done_count < num_episodes:
            ep = source.episode_of_env.copy()
            if source.next_episode >= num_episodes:  # the fillers stop costing physics
                env.stepped_envs = torch.as_tensor(np.flatnonzero(ep >= 0), device=env.device)
            _, _, done, extras = env.step(zeros)
            done = done.cpu().numpy()
            ended = np.flatnonzero(done & (ep >= 0))
            whole = ended[extras["time_outs"].cpu().numpy()[ended]]  # the others faulted: no probe
            if len(whole):
                mu = bench.robots.foot_friction[bench.pairing(ep[whole])[1]]
                values = stats(
                    dt, buf["r_wp"][:, whole], buf["v"][:, whole], buf["omega"][:, whole], mu, env.plf_top_m
                )
                for key, value in values.items():
                    out.setdefault(key, np.full(num_episodes, np.nan))[ep[whole]] = value
            done_count += len(ended)
            restarted = np.flatnonzero(done)
            length[restarted] = 0
            if len(restarted):
                record(env.readout, restarted)
            now = time.perf_counter()
            if progress and (now - last_print > 2.0 or done_count == num_episodes):
                last_print = now
                print(
                    f"\rplatform probe: {done_count}/{num_episodes} episodes",
                    end="",
                    file=sys.stderr,
                    flush=True,
                )
    if progress:
        print(file=sys.stderr)
    env.on_step = env.episode_source = env.stepped_envs = None
    if stats is motion_stats:  # every column, NaN where no episode was whole
        out = {k: out.get(k, np.full(num_episodes, np.nan)) for k in PROBE_COLUMNS}
    return out


# -- the table ---------------------------------------------------------------------------------
