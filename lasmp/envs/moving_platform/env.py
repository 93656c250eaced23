"""The LAS-MP task: an A1 keeps its balance on a platform tracking a 6-DoF trajectory.

Observation groups (TensorDict, float32):
- `policy`        o (44): [accelerometer_b (3), gyro_b (3), roll & pitch (2), q - q_nominal (12),
                  q_dot (12), a_{t-1} (12)]. q is centred at the nominal stance (ours, as legged_gym).
- `history`       o^H (H, 44): [o_{t-1}, ..., o_{t-H}], newest first; filled with o_0 at reset.
- `priv_explicit` x_exp (13): [foot contacts (4), v_body_b (3), v_plf_b (3), omega_plf_b (3)].
- `priv_implicit` x_imp (29): [trunk mass, CoM shift (3), foot friction, Kp (12), Kd (12)].
- `alignment`     u_aln (3): [v_plf_b,xy - v_body_b,xy, omega_plf_b,z - omega_body_b,z].
- `critic`        (95): [o, x_exp, x_imp, u_aln, p_body_p (3), phi_body_w (3)].
`v_plf_b` is the velocity of the platform point under the trunk origin (ours): a robot that
rides the platform rigidly then has u_aln = 0 even while the platform turns.
"""

from __future__ import annotations

import numpy as np
import torch
from tensordict import TensorDict

from lasmp.config import build_env_cfg
from lasmp.envs import trajectories as trj
from lasmp.envs.backends.cpu import CpuBatchSim
from lasmp.envs.base_env import BaseEnv, to_tensor
from lasmp.envs.curriculum import WaypointCurriculum
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.domain_rand import (
    Intrinsics,
    IntrinsicsWriter,
    nominal_intrinsics,
    sample_intrinsics,
)
from lasmp.envs.moving_platform.readout import Readout, ReadoutIndex, read
from lasmp.envs.moving_platform.rewards import RewardManager, RewardParams
from lasmp.envs.moving_platform.state import StepState
from lasmp.envs.robot import proprioception, screen_faults, update_rows
from lasmp.envs.rotations import yaw_quat
from lasmp.envs.scene import PLATFORM_JOINTS, POSE_TO_JOINT, build_model, platform_gains, platform_top_z_m
from lasmp.robots import a1


class MovingPlatformEnv(BaseEnv):
    def __init__(self, cfg: MovingPlatformCfg | dict | None = None, device="cpu"):
        if not isinstance(cfg, MovingPlatformCfg):
            cfg = build_env_cfg(cfg, schema=MovingPlatformCfg)
        else:
            cfg.validate()
        model = build_model(cfg.platform, cfg.sim)
        sim = CpuBatchSim(model, cfg.num_envs, cfg.sim.num_threads)
        dt_s = cfg.sim.dt_s * cfg.sim.decimation
        super().__init__(cfg, sim, 12, int(round(cfg.trajectory.duration_s / dt_s)), device)
        n = self.num_envs
        self.index = ReadoutIndex(model)
        self.gains = platform_gains(cfg.platform)
        self.writer = IntrinsicsWriter(sim, self.gains)
        self.intrinsics: Intrinsics = nominal_intrinsics(n, cfg.platform.kd_factor_ref)
        self.q_nominal = np.asarray(a1.Q_NOMINAL_RAD)
        self.trunk_height_m = a1.nominal_trunk_height_m(model)
        self.plf_act_pos = np.array([model.actuator(f"{j}_pos").id for j in PLATFORM_JOINTS])
        self.plf_act_vel = np.array([model.actuator(f"{j}_vel").id for j in PLATFORM_JOINTS])
        self.plf_act_adr = model.actuator_actadr[self.plf_act_pos]  # servo targets in `act`
        self.robot_act = self.index.joint_act

        tc, cc = cfg.trajectory, cfg.curriculum
        self.traj_ranges = trj.ranges_for_split(tc.split)
        self.traj_file = trj.load(tc.file) if tc.file else None
        self._file_cursor = 0
        self.curriculum = (
            WaypointCurriculum(
                cc.level_min,
                cc.level_max,
                cc.promote_success_rate,
                cc.window_episodes,
                cc.replay_lower_fraction,
            )
            if cc.enabled and self.traj_file is None
            else None
        )
        self.traj = trj.sample(
            n, self.traj_ranges, self.rng, n_waypoints=self.traj_ranges.n_waypoints_min, spline=tc.spline
        )
        self.traj_level = np.full(n, -1)

        rc = cfg.rewards
        self.plf_top_m = platform_top_z_m(cfg.platform)
        self.h_des_p_m = rc.h_des_p_m(self.plf_top_m)  # desired trunk height in the platform frame
        params = RewardParams(
            rc.sigma_center_m, rc.sigma_alignment, rc.sigma_level_rad, rc.sigma_height_m, self.h_des_p_m,
            rc.f_tol_n, rc.t_swing_des_s, rc.t_contact_des_s,
        )  # fmt: skip
        self.rewards = RewardManager(rc.weights, params, n)
        self.plf_half_xy_m = np.array(cfg.platform.size_m[:2]) / 2.0

        self.action = np.zeros((n, 12))
        self.action_prev = np.zeros((n, 12))
        self.tau_prev = np.zeros((n, 12))
        self.q_dot_prev = np.zeros((n, 12))
        self.contact_prev = np.zeros((n, 4), dtype=bool)
        self.t_air_s = np.zeros((n, 4))
        self.t_contact_s = np.zeros((n, 4))
        self.nonfinite_obs_values = 0  # replaced by 0 in the last observation (a fault symptom)
        self.readout: Readout | None = None
        # Hooks for evaluation: `episode_source.next_episodes(ids)` -> (trajectories, levels,
        # Intrinsics) replaces the random draws at reset; `on_step(readout, collision)` sees every
        # step's state before the finished envs are reset.
        self.episode_source = None
        self.on_step = None
        self.last_state: StepState | None = None

    # -- control -------------------------------------------------------------------------------

    def _apply_actions(self, actions: np.ndarray) -> None:
        self.action_prev[:] = self.action
        self.action[:] = actions
        ctrl = self.sim.ctrl
        ctrl[:, self.robot_act] = self.q_nominal + self.cfg.control.action_scale * actions
        # the kp servo's target starts at x_ref(t) and ramps to x_ref(t + dt) within the step;
        # the damping term tracks the reference velocity at mid-step (or damps toward rest, without
        # velocity feedforward)
        n = self.num_envs
        t_s = self.episode_length_buf.numpy() * self.dt_s
        times = np.concatenate([t_s, t_s + self.dt_s, t_s + 0.5 * self.dt_s])  # one evaluation for all three
        pose, vel, _ = self.traj.evaluate(times, np.tile(np.arange(n), 3))
        x_now, x_next = pose[:n, POSE_TO_JOINT], pose[n : 2 * n, POSE_TO_JOINT]
        v_mid = vel[2 * n :, POSE_TO_JOINT]
        self.sim.act[:, self.plf_act_adr] = x_now
        ctrl[:, self.plf_act_pos] = (x_next - x_now) / self.dt_s
        ctrl[:, self.plf_act_vel] = v_mid if self.cfg.platform.velocity_feedforward else 0.0

    # -- evaluation ----------------------------------------------------------------------------
    def _fell(self, r: Readout) -> np.ndarray:
        tc = self.cfg.termination
        off = (np.abs(r.p_body_p[:, :2]) > self.plf_half_xy_m + tc.footprint_margin_m).any(axis=1)
        below = r.p_body_p[:, 2] < self.plf_top_m + tc.fall_below_top_m
        return off | below

    def _evaluate(self):
        r, faulted = screen_faults(read(self.sim, self.index), self.cfg.termination.max_joint_vel_rad_s)
        self.readout = r
        fell = self._fell(r)
        collision = r.body_collision | fell
        dt = self.dt_s
        contact = r.foot_contact
        touchdown = contact & ~self.contact_prev
        liftoff = ~contact & self.contact_prev
        self.t_air_s += dt * ~contact
        self.t_contact_s += dt * contact
        t_air_ended = np.where(touchdown, self.t_air_s, 0.0)
        t_contact_ended = np.where(liftoff, self.t_contact_s, 0.0)
        self.t_air_s[contact] = 0.0
        self.t_contact_s[~contact] = 0.0
        self.contact_prev = contact
        dev = self.device
        state = StepState(
            dt_s=dt,
            p_body_p=to_tensor(r.p_body_p, dev),
            phi_body_w=to_tensor(r.phi_body_w, dev),
            v_body_b=to_tensor(r.v_body_b, dev),
            omega_body_b=to_tensor(r.omega_body_b, dev),
            v_plf_b=to_tensor(r.v_plf_b, dev),
            omega_plf_b=to_tensor(r.omega_plf_b, dev),
            u_aln=to_tensor(r.u_aln, dev),
            action=to_tensor(self.action, dev),
            action_prev=to_tensor(self.action_prev, dev),
            tau=to_tensor(r.tau, dev),
            tau_prev=to_tensor(self.tau_prev, dev),
            q_dot=to_tensor(r.q_dot, dev),
            q_ddot=to_tensor((r.q_dot - self.q_dot_prev) / dt, dev),
            f_feet_w=to_tensor(r.f_feet_w, dev),
            contact=torch.from_numpy(contact),
            touchdown=torch.from_numpy(touchdown),
            liftoff=torch.from_numpy(liftoff),
            t_air_s=to_tensor(t_air_ended, dev),
            t_contact_s=to_tensor(t_contact_ended, dev),
            v_slip_p=to_tensor(r.v_slip_p, dev),
            collision=torch.from_numpy(collision),
        )
        self.last_state = state
        reward = self.rewards.compute(state)
        self.tau_prev[:] = r.tau
        self.q_dot_prev[:] = r.q_dot
        log = {
            "Termination/body_contact": float(r.body_collision.sum()),
            "Termination/fell": float(fell.sum()),
        }
        if self.on_step is not None:
            self.on_step(r, collision)
        if self.curriculum is not None:  # every step, so each iteration logs the level
            log["Curriculum/level"] = float(self.curriculum.level)
            log["Curriculum/success_rate"] = self.curriculum.success_rate
        return reward, collision, faulted, log

    # -- resets --------------------------------------------------------------------------------
    def _next_trajectories(self, ids: np.ndarray) -> tuple[trj.PiecewisePoly, np.ndarray]:
        if self.traj_file is not None:  # replay the file's rows in order, wrapping around
            rows = (self._file_cursor + np.arange(len(ids))) % len(self.traj_file)
            self._file_cursor = int((self._file_cursor + len(ids)) % len(self.traj_file))
            new = self.traj_file.subset(rows)
            return new, new.n_waypoints
        if self.curriculum is not None:
            levels = self.curriculum.sample_levels(len(ids), self.rng)
        else:
            r = self.traj_ranges
            levels = self.rng.integers(r.n_waypoints_min, r.n_waypoints_max + 1, size=len(ids))
        spline = self.cfg.trajectory.spline
        return trj.sample(len(ids), self.traj_ranges, self.rng, n_waypoints=levels, spline=spline), levels

    def _reset_envs(self, ids: np.ndarray, terminated: np.ndarray, timed_out: np.ndarray) -> dict:
        log = {}
        finished = terminated | timed_out
        if finished.any():
            done = ids[finished]
            log = self._finished_episode_log(done)
            success = timed_out[finished]
            log["Episode/success_rate"] = float(success.mean())
            if self.curriculum is not None:
                self.curriculum.update(self.traj_level[done], success)

        n = len(ids)
        dr = self.cfg.domain_rand
        if self.episode_source is not None:
            new_traj, levels, params = self.episode_source.next_episodes(ids)
        else:
            if dr.enabled:
                params = sample_intrinsics(n, dr.ranges, self.rng)
            else:
                params = nominal_intrinsics(n, self.cfg.platform.kd_factor_ref)
            new_traj, levels = self._next_trajectories(ids)
        update_rows(self.intrinsics, ids, params)
        self.writer.write(ids, params)
        self.traj.replace_rows(ids, new_traj)
        self.traj_level[ids] = levels

        m = self.sim.model
        qpos = np.tile(m.qpos0, (n, 1))
        ix = self.index
        yaw = self.rng.uniform(*self.cfg.init_state.yaw_range_rad, size=n)
        init = self.cfg.init_state
        qpos[:, ix.root_qpos : ix.root_qpos + 2] = 0.0  # the platform's centre
        qpos[:, ix.root_qpos + 2] = self.plf_top_m + self.trunk_height_m + init.foot_clearance_m
        if init.xy_offset_max_m > 0:  # uniform in the disc
            rho = init.xy_offset_max_m * np.sqrt(self.rng.uniform(size=n))
            angle = self.rng.uniform(-np.pi, np.pi, size=n)
            qpos[:, ix.root_qpos] = rho * np.cos(angle)
            qpos[:, ix.root_qpos + 1] = rho * np.sin(angle)
        qpos[:, ix.root_qpos + 3 : ix.root_qpos + 7] = yaw_quat(yaw)
        qpos[:, ix.joint_qpos] = self.q_nominal
        qpos[:, ix.plf_qpos] = 0.0
        ctrl = np.zeros((n, m.nu))
        ctrl[:, self.robot_act] = self.q_nominal
        self.sim.reset(ids, qpos, np.zeros((n, m.nv)), ctrl, set_const=True)

        self.action[ids] = 0.0
        self.action_prev[ids] = 0.0
        self.tau_prev[ids] = 0.0
        self.q_dot_prev[ids] = 0.0
        self.contact_prev[ids] = False
        self.t_air_s[ids] = 0.0
        self.t_contact_s[ids] = 0.0
        self._fresh = ids  # their history is filled with their first observation
        return log

    # -- observations --------------------------------------------------------------------------
    def _observations(self) -> TensorDict:
        # the readout of this step, with the envs reset since then read again (their new state)
        if self.readout is None or (self._fresh is not None and len(self._fresh) == self.num_envs):
            self.readout = read(self.sim, self.index)
        elif self._fresh is not None:
            update_rows(self.readout, self._fresh, read(self.sim, self.index, self._fresh))
        r = self.readout
        o = proprioception(r, self.action)
        x_exp = np.concatenate([r.foot_contact, r.v_body_b, r.v_plf_b, r.omega_plf_b], axis=1)
        x_imp = self.intrinsics.x_imp()
        critic = np.concatenate([o, x_exp, x_imp, r.u_aln, r.p_body_p, r.phi_body_w], axis=1)
        groups = {"priv_explicit": x_exp, "priv_implicit": x_imp, "alignment": r.u_aln, "critic": critic}
        return self._package_observations(o, groups)

    # -- checkpoint state ----------------------------------------------------------------------
    TASK_STATE = ("action", "action_prev", "tau_prev", "q_dot_prev", "contact_prev", "t_air_s", "t_contact_s",
                  "traj", "traj_level", "_file_cursor", "intrinsics", "rewards", "readout", "last_state")  # fmt: skip

    def _task_state(self) -> dict:
        return {"curriculum": self.curriculum.state_dict() if self.curriculum is not None else None}

    def _load_task_state(self, d: dict) -> None:
        if self.curriculum is not None and d.get("curriculum") is not None:
            self.curriculum.load_state_dict(d["curriculum"])
