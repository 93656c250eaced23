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

from lasmp.envs.base_env import BaseEnv, CheckFit, column_runs
from lasmp.envs.rewards import RewardManager
from lasmp.envs.robot import (
    OBS_DIM,
    X_IMP_DIM,
    RobotIntrinsics,
    RobotIntrinsicsWriter,
    RobotReadout,
    nominal_robot_intrinsics,
    proprioception,
    read_robot,
    sample_robot_intrinsics,
    screen_faults,
    step_gait_phase,
    update_rows,
)
from lasmp.envs.rough_static import rewards as rw
from lasmp.envs.rough_static.cfg import RoughStaticCfg
from lasmp.envs.rough_static.scene import build_model
from lasmp.envs.rough_static.state import StepState

SPAWN_FOOTPRINT_M = 0.4  # half-side of the square under the robot searched for the highest ground


class RoughStaticEnv(BaseEnv):
    cfg_class = RoughStaticCfg
    # the observation groups it hands out: what a policy may read (lasmp.config.train checks it at start-up)
    OBS_GROUPS = ("policy", "history", "priv_explicit", "priv_implicit", "command", "critic")
    # the critic: [o, x_exp, x_imp, command, height (1), phi_body_w (3)]
    CRITIC_RUNS = {"policy": OBS_DIM, "priv_explicit": 13, "priv_implicit": X_IMP_DIM, "command": 3}
    CRITIC_EXTRA = 4

    @classmethod
    def build_model(cls, cfg: RoughStaticCfg):
        return build_model(cfg.terrain, cfg.sim)[0]

    def __init__(self, cfg: RoughStaticCfg, device="cpu", check_fit: CheckFit | None = None):
        self.check_cfg_class(type(cfg))
        model, self.terrain = build_model(cfg.terrain, cfg.sim)
        dt_s = cfg.sim.dt_s * cfg.sim.decimation
        super().__init__(cfg, model, 12, int(round(cfg.episode_length_s / dt_s)), device, check_fit=check_fit)
        n, dev = self.num_envs, self.device
        self.writer = RobotIntrinsicsWriter(self.sim)
        self.intrinsics: RobotIntrinsics = nominal_robot_intrinsics(n)
        self.x_imp = self.tensor(self.intrinsics.x_imp())  # (n, 29) on the device, rows set at reset
        self.obs_columns = column_runs(self.CRITIC_RUNS, whole="critic")
        self.rewards = RewardManager(rw.REWARD_TERMS, cfg.rewards.weights, cfg.rewards, n, device=dev)

        zeros = lambda *shape: torch.zeros((n, *shape), dtype=self.dtype, device=dev)  # noqa: E731
        self.command = zeros(3)
        self.command_time_left_s = zeros()
        self.push_time_left_s = zeros()
        # envs pushed at the start of the last step
        self.pushed = torch.zeros(n, dtype=torch.bool, device=dev)
        self.push_dv_mps = zeros(2)  # their added world-frame xy velocity
        self.q_dot_prev = zeros(12)
        self.contact_prev = torch.zeros((n, 4), dtype=torch.bool, device=dev)
        self.t_air_s = zeros(4)
        self.readout: RobotReadout | None = None
        self.last_state: StepState | None = None

    # -- commands and pushes -------------------------------------------------------------------
    def sample_commands(self, n: int) -> np.ndarray:
        """(n, 3) new commands, drawn on the host."""
        c = self.cfg.commands
        cmd = np.stack(
            [self.rng.uniform(*r, size=n) for r in (c.lin_vel_x_mps, c.lin_vel_y_mps, c.ang_vel_z_rad_s)],
            axis=1,
        )
        cmd[self.rng.random(n) < c.zero_command_fraction] = 0.0
        return cmd

    def _resample_commands(self, ids: torch.Tensor) -> None:
        self.command[ids] = self.tensor(self.sample_commands(len(ids)))
        self.command_time_left_s[ids] = self.cfg.commands.resample_s

    def push(self, ids: torch.Tensor) -> torch.Tensor:
        """Add a random horizontal velocity to the trunks of envs `ids`; return it (len(ids), 2), m/s."""
        pc = self.cfg.pushes
        angle = self.rng.uniform(-np.pi, np.pi, size=len(ids))
        speed = self.rng.uniform(0.0, pc.max_mps, size=len(ids))
        dv = self.tensor(speed[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1))
        # the free joint's linear velocity is in the world frame
        root_qvel = self.index.root_qvel
        self.sim.qvel[ids, root_qvel : root_qvel + 2] += dv
        self.sim.forward(ids)  # derived quantities follow the new state
        self.push_time_left_s[ids] = self.tensor(self.rng.uniform(*pc.interval_s, size=len(ids)))
        return dv

    # -- control -------------------------------------------------------------------------------
    def _apply_actions(self, actions: torch.Tensor) -> None:
        self._apply_joint_targets(actions)
        self.pushed.fill_(False)
        if self.cfg.pushes.enabled:
            due = torch.nonzero(self.push_time_left_s <= 0.0).flatten()
            if len(due):
                self.push_dv_mps[due] = self.push(due)
                self.pushed[due] = True
            self.push_time_left_s -= self.dt_s

    # -- evaluation ----------------------------------------------------------------------------
    def _evaluate(self):
        r, faulted = screen_faults(read_robot(self.sim, self.index), self.cfg.termination.max_joint_vel_rad_s)
        self.readout = r
        tilted = (torch.abs(r.phi_body_w[:, :2]) > self.cfg.termination.max_tilt_rad).any(dim=1)
        fell = r.body_collision | tilted
        dt = self.dt_s
        gait = step_gait_phase(r.foot_contact, self.contact_prev, self.t_air_s, None, dt)
        f32 = torch.float32  # rewards are computed in float32 on every backend
        state = StepState(
            dt_s=dt,
            v_body_b=r.v_body_b.to(f32),
            omega_body_b=r.omega_body_b.to(f32),
            command=self.command.to(f32),
            gravity_b=r.gravity_b.to(f32),
            q_dev=(r.q - self.q_nominal).to(f32),
            tau=r.tau.to(f32),
            q_ddot=((r.q_dot - self.q_dot_prev) / dt).to(f32),
            action=self.action.to(f32),
            action_prev=self.action_prev.to(f32),
            collision=r.body_collision.clone(),
            touchdown=gait.touchdown,
            t_air_s=gait.t_air_s.to(f32),
        )
        self.last_state = state
        reward = self.rewards.compute(state)
        self.q_dot_prev.copy_(r.q_dot)
        # commands run on their own clock; they are resampled after the reward used the old one
        self.command_time_left_s -= dt
        due = torch.nonzero(self.command_time_left_s <= 1e-9).flatten()
        if len(due):
            self._resample_commands(due)
        log = {
            "Termination/body_contact": float(r.body_collision.sum()),
            "Termination/tilt": float(tilted.sum()),
            # a rate over no episode until one ends at this step (the reset's log then holds it): the
            # progress line keeps its column before the first episode ends
            "Episode/success_rate": float("nan"),
        }
        return reward, fell, faulted, log

    # -- resets --------------------------------------------------------------------------------
    def _reset_envs(self, ids: torch.Tensor, terminated: torch.Tensor, timed_out: torch.Tensor) -> dict:
        log = {}
        finished = terminated | timed_out
        if finished.any():
            log = self._finished_episode_log(ids[finished])
            # the share of the ended episodes that reached the time limit (the moving platform's tag)
            log["Episode/success_rate"] = float(timed_out[finished].double().mean())
        n = len(ids)
        ids_h = ids.cpu().numpy()  # the host draws below are per env
        dr = self.cfg.domain_rand
        if dr.enabled:
            params = sample_robot_intrinsics(n, self.intrinsic_ranges, self.rng)
            if self.cfg.study_rng_stream:  # unused draws: the stream of the study's R-S seeds (cfg.py)
                self.rng.uniform(size=(n, 12))
        else:
            params = nominal_robot_intrinsics(n)
        update_rows(self.intrinsics, ids_h, params)
        self.x_imp[ids] = self.tensor(params.x_imp())
        self.writer.write(ids, params)

        tc = self.cfg.terrain
        half = np.array([self.terrain.half_x_m, self.terrain.half_y_m]) - tc.spawn_margin_m
        xy = self.rng.uniform(-half, half, size=(n, 2))
        yaw = self.rng.uniform(*self.cfg.init_state.yaw_range_rad, size=n)
        ground = self.terrain.max_height_near(xy, SPAWN_FOOTPRINT_M)
        self._reset_physics(ids, self._standing_qpos(xy, ground, yaw))

        self._resample_commands(ids)
        self.push_time_left_s[ids] = self.tensor(self.rng.uniform(*self.cfg.pushes.interval_s, size=n))
        for buf in (self.action, self.action_prev, self.q_dot_prev, self.t_air_s):
            buf[ids] = 0.0
        self.contact_prev[ids] = False
        self._fresh = ids
        return log

    # -- observations --------------------------------------------------------------------------
    def _observations(self) -> TensorDict:
        if self.readout is None or self._fresh is not None:
            self.readout = read_robot(self.sim, self.index)  # reset envs: their new state (one pass)
        r = self.readout
        o = proprioception(r, self.action, self.q_nominal)
        # x_exp: a still ground
        static = torch.zeros((self.num_envs, 6), dtype=self.dtype, device=self.device)
        height = r.p_body_w[:, 2] - self.terrain.height_at(r.p_body_w[:, :2])
        critic = torch.cat(
            [
                o,
                r.foot_contact.to(self.dtype),
                r.v_body_b,
                static,
                self.x_imp,
                self.command,
                height[:, None],
                r.phi_body_w,
            ],
            dim=1,
        )
        return self._package_observations(critic, self.obs_columns)

    # -- checkpoint state (nothing: no curriculum) ---------------------------------------------
    TASK_STATE = (
        "command",
        "command_time_left_s",
        "push_time_left_s",
        "pushed",
        "push_dv_mps",
        "q_dot_prev",
        "contact_prev",
        "t_air_s",
        "intrinsics",
        "x_imp",
        "rewards",
        "readout",
        "last_state",
    )
    RUN_STATE_CLASSES = (StepState, RobotReadout)
