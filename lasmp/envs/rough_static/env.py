"""The R-S baseline task: an A1 follows random velocity commands on static rough terrain.

Trained with random pushes and the robot part of the moving-platform domain randomization,
never on a moving platform; the benchmark runs it with a zero command. Same step loop
(`BaseEnv`), robot layer (`lasmp.envs.robot`: readout, intrinsics, o, fault screening),
conventions and observation names as `MovingPlatformEnv`, so the same actor consumes it.

Observation groups (TensorDict, float32):
- `policy`        o (44): [accelerometer_b (3), gyro_b (3), roll & pitch (2), q - q_nominal (12),
                  q_dot (12), a_{t-1} (12)].
- `history`       o^H (H, 44): past observations, newest first; filled with o_0 at reset.
- `priv_explicit` x_exp (13): [foot contacts (4), v_body_b (3), 6 zeros (static ground: the
                  "platform" velocities of the moving-platform task are 0)].
- `priv_implicit` x_imp (29): [trunk mass, CoM shift (3), foot friction, Kp (12), Kd (12)].
- `command`       (3): [v_x (m/s), v_y (m/s), w_z (rad/s)], body frame.
- `critic`        (93): [o, x_exp, x_imp, command, trunk height above the ground under it (1),
                  roll, pitch, yaw (3)].

Commands are resampled every `commands.resample_s` and at reset; a share
`zero_command_fraction` is exactly zero. Pushes add a random horizontal velocity
(|dv| uniform in [0, max_mps], uniform direction) to the trunk every U(interval_s) seconds,
at the start of a step, before physics. Episodes end on a fall (trunk/hip/thigh/calf contact
or |roll|, |pitch| > max_tilt_rad), or at `episode_length_s` (a truncation).
"""

from __future__ import annotations

import numpy as np
import torch
from tensordict import TensorDict

from lasmp.config import build_env_cfg
from lasmp.envs.backends.cpu import CpuBatchSim
from lasmp.envs.base_env import BaseEnv, to_tensor
from lasmp.envs.moving_platform.domain_rand import Intrinsics, nominal_intrinsics, sample_intrinsics
from lasmp.envs.moving_platform.rewards import RewardManager
from lasmp.envs.robot import (
    RobotIndex,
    RobotIntrinsicsWriter,
    RobotReadout,
    proprioception,
    read_robot,
    screen_faults,
    update_rows,
)
from lasmp.envs.rotations import yaw_quat
from lasmp.envs.rough_static import rewards as rw
from lasmp.envs.rough_static.cfg import RoughStaticCfg
from lasmp.envs.rough_static.terrain import build_model
from lasmp.robots import a1

SPAWN_FOOTPRINT_M = 0.4  # half-side of the square under the robot searched for the highest ground


class RoughStaticEnv(BaseEnv):
    def __init__(self, cfg: RoughStaticCfg | dict | None = None, device="cpu"):
        if not isinstance(cfg, RoughStaticCfg):
            cfg = build_env_cfg(cfg, schema=RoughStaticCfg)
        else:
            cfg.validate()
        model, self.terrain = build_model(cfg.terrain, cfg.sim)
        sim = CpuBatchSim(model, cfg.num_envs, cfg.sim.num_threads)
        dt_s = cfg.sim.dt_s * cfg.sim.decimation
        super().__init__(cfg, sim, 12, int(round(cfg.episode_length_s / dt_s)), device)
        n = self.num_envs
        self.index = RobotIndex(model)
        self.writer = RobotIntrinsicsWriter(sim)
        self.intrinsics: Intrinsics = nominal_intrinsics(n, cfg.domain_rand.train.platform_kd_factor[0])
        self.q_nominal = np.asarray(a1.Q_NOMINAL_RAD)
        self.trunk_height_m = a1.nominal_trunk_height_m(model)
        rc = cfg.rewards
        self.rewards = RewardManager(
            rc.weights,
            rw.RoughRewardParams(rc.tracking_sigma, rc.air_time_target_s),
            n,
            registry=rw.REWARD_TERMS,
        )

        self.command = np.zeros((n, 3))
        self.command_time_left_s = np.zeros(n)
        self.push_time_left_s = np.zeros(n)
        self.pushed = np.zeros(n, dtype=bool)  # envs pushed at the start of the last step
        self.push_dv_mps = np.zeros((n, 2))  # their added world-frame xy velocity
        self.action = np.zeros((n, 12))
        self.action_prev = np.zeros((n, 12))
        self.q_dot_prev = np.zeros((n, 12))
        self.contact_prev = np.zeros((n, 4), dtype=bool)
        self.t_air_s = np.zeros((n, 4))
        self.readout: RobotReadout | None = None
        self.last_state: rw.RoughStepState | None = None

    # -- commands and pushes -------------------------------------------------------------------
    def sample_commands(self, n: int) -> np.ndarray:
        c = self.cfg.commands
        cmd = np.stack(
            [self.rng.uniform(*r, size=n) for r in (c.lin_vel_x_mps, c.lin_vel_y_mps, c.ang_vel_z_rad_s)],
            axis=1,
        )
        cmd[self.rng.random(n) < c.zero_command_fraction] = 0.0
        return cmd

    def _resample_commands(self, ids: np.ndarray) -> None:
        self.command[ids] = self.sample_commands(len(ids))
        self.command_time_left_s[ids] = self.cfg.commands.resample_s

    def push(self, ids: np.ndarray) -> np.ndarray:
        """Add a random horizontal velocity to the trunks of envs `ids`; return it (len(ids), 2), m/s."""
        pc = self.cfg.pushes
        angle = self.rng.uniform(-np.pi, np.pi, size=len(ids))
        speed = self.rng.uniform(0.0, pc.max_mps, size=len(ids))
        dv = speed[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)
        # the free joint's linear velocity is in the world frame
        root_qvel = self.index.root_qvel
        self.sim.qvel[ids, root_qvel : root_qvel + 2] += dv
        self.sim.batch.forward(ids)  # derived quantities follow the new state
        self.push_time_left_s[ids] = self.rng.uniform(*pc.interval_s, size=len(ids))
        return dv

    # -- control -------------------------------------------------------------------------------
    def _apply_actions(self, actions: np.ndarray) -> None:
        self.action_prev[:] = self.action
        self.action[:] = actions
        self.sim.ctrl[:, self.index.joint_act] = self.q_nominal + self.cfg.control.action_scale * actions
        self.pushed[:] = False
        if self.cfg.pushes.enabled:
            due = np.flatnonzero(self.push_time_left_s <= 0.0)
            if len(due):
                self.push_dv_mps[due] = self.push(due)
                self.pushed[due] = True
            self.push_time_left_s -= self.dt_s

    # -- evaluation ----------------------------------------------------------------------------
    def _evaluate(self):
        r, faulted = screen_faults(read_robot(self.sim, self.index), self.cfg.termination.max_joint_vel_rad_s)
        self.readout = r
        tilted = (np.abs(r.phi_body_w[:, :2]) > self.cfg.termination.max_tilt_rad).any(axis=1)
        fell = r.body_collision | tilted
        dt = self.dt_s
        contact = r.foot_contact
        touchdown = contact & ~self.contact_prev
        self.t_air_s += dt * ~contact
        t_air_ended = np.where(touchdown, self.t_air_s, 0.0)
        self.t_air_s[contact] = 0.0
        self.contact_prev = contact
        dev = self.device
        state = rw.RoughStepState(
            dt_s=dt,
            v_body_b=to_tensor(r.v_body_b, dev),
            omega_body_b=to_tensor(r.omega_body_b, dev),
            command=to_tensor(self.command, dev),
            gravity_b=to_tensor(r.gravity_b, dev),
            q_dev=to_tensor(r.q - self.q_nominal, dev),
            tau=to_tensor(r.tau, dev),
            q_ddot=to_tensor((r.q_dot - self.q_dot_prev) / dt, dev),
            action=to_tensor(self.action, dev),
            action_prev=to_tensor(self.action_prev, dev),
            body_contact=torch.from_numpy(r.body_collision.copy()),
            touchdown=torch.from_numpy(touchdown),
            t_air_s=to_tensor(t_air_ended, dev),
        )
        self.last_state = state
        reward = self.rewards.compute(state)
        self.q_dot_prev[:] = r.q_dot
        # commands run on their own clock; they are resampled after the reward used the old one
        self.command_time_left_s -= dt
        due = np.flatnonzero(self.command_time_left_s <= 1e-9)
        if len(due):
            self._resample_commands(due)
        log = {
            "Termination/body_contact": float(r.body_collision.sum()),
            "Termination/tilt": float(tilted.sum()),
        }
        return reward, fell, faulted, log

    # -- resets --------------------------------------------------------------------------------
    def _reset_envs(self, ids: np.ndarray, terminated: np.ndarray, timed_out: np.ndarray) -> dict:
        log = {}
        finished = terminated | timed_out
        if finished.any():
            log = self._finished_episode_log(ids[finished])
            log["Episode/timeout_rate"] = float(timed_out[finished].mean())
        n = len(ids)
        dr = self.cfg.domain_rand
        if dr.enabled:
            params = sample_intrinsics(n, dr.ranges, self.rng)
        else:
            params = nominal_intrinsics(n, dr.train.platform_kd_factor[0])
        update_rows(self.intrinsics, ids, params)
        self.writer.write(ids, params)

        tc = self.cfg.terrain
        half = np.array([self.terrain.half_x_m, self.terrain.half_y_m]) - tc.spawn_margin_m
        xy = self.rng.uniform(-half, half, size=(n, 2))
        yaw = self.rng.uniform(*self.cfg.init_state.yaw_range_rad, size=n)
        ground = self.terrain.max_height_near(xy, SPAWN_FOOTPRINT_M)
        m = self.sim.model
        qpos = np.tile(m.qpos0, (n, 1))
        ix = self.index
        qpos[:, ix.root_qpos : ix.root_qpos + 2] = xy
        qpos[:, ix.root_qpos + 2] = ground + self.trunk_height_m + self.cfg.init_state.foot_clearance_m
        qpos[:, ix.root_qpos + 3 : ix.root_qpos + 7] = yaw_quat(yaw)
        qpos[:, ix.joint_qpos] = self.q_nominal
        ctrl = np.zeros((n, m.nu))
        ctrl[:, ix.joint_act] = self.q_nominal
        self.sim.reset(ids, qpos, np.zeros((n, m.nv)), ctrl, set_const=True)

        self._resample_commands(ids)
        self.push_time_left_s[ids] = self.rng.uniform(*self.cfg.pushes.interval_s, size=n)
        self.action[ids] = 0.0
        self.action_prev[ids] = 0.0
        self.q_dot_prev[ids] = 0.0
        self.contact_prev[ids] = False
        self.t_air_s[ids] = 0.0
        self._fresh = ids
        return log

    # -- observations --------------------------------------------------------------------------
    def _observations(self) -> TensorDict:
        if self.readout is None or self._fresh is not None:
            self.readout = read_robot(self.sim, self.index)  # reset envs: their new state (one pass)
        r = self.readout
        n = self.num_envs
        o = proprioception(r, self.action)
        x_exp = np.concatenate([r.foot_contact, r.v_body_b, np.zeros((n, 6))], axis=1)
        x_imp = self.intrinsics.x_imp()
        height = r.p_body_w[:, 2] - self.terrain.height_at(r.p_body_w[:, :2])
        critic = np.concatenate([o, x_exp, x_imp, self.command, height[:, None], r.phi_body_w], axis=1)
        groups = {"priv_explicit": x_exp, "priv_implicit": x_imp, "command": self.command, "critic": critic}
        return self._package_observations(o, groups)

    # -- checkpoint state (nothing: no curriculum) ---------------------------------------------
    TASK_STATE = ("command", "command_time_left_s", "push_time_left_s", "pushed", "push_dv_mps", "action",
                  "action_prev", "q_dot_prev", "contact_prev", "t_air_s", "intrinsics", "rewards", "readout",
                  "last_state")  # fmt: skip
