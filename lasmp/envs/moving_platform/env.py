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

from lasmp.envs import trajectories as trj
from lasmp.envs.base_env import BaseEnv, CheckFit, column_runs
from lasmp.envs.curriculum import SharedCurriculum, WaypointCurriculum
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.domain_rand import (
    Intrinsics,
    IntrinsicsWriter,
    nominal_intrinsics,
    sample_intrinsics,
)
from lasmp.envs.moving_platform.mirror import ACTIONS, ObservationMirror, nominal_com_y_m
from lasmp.envs.moving_platform.readout import SceneIndex, SceneReadout, read_scene
from lasmp.envs.moving_platform.rewards import REWARD_TERMS
from lasmp.envs.moving_platform.scene import (
    POSE_TO_JOINT,
    build_model,
    platform_actuator_ids,
    platform_gains,
    platform_top_z_m,
)
from lasmp.envs.moving_platform.state import StepState
from lasmp.envs.rewards import RewardManager
from lasmp.envs.robot import (
    OBS_DIM,
    X_IMP_DIM,
    as_slice,
    proprioception,
    screen_faults,
    step_gait_phase,
    update_rows,
)
from lasmp.envs.trajectories.device import DevicePoly


def initial_pose(u: np.ndarray, yaw_range_rad, xy_offset_max_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The trunk's initial yaw (n,) in rad and xy offset (n, 2) in m from the platform's centre, from
    three uniforms in [0, 1) per env (`u`, (n, 3)): yaw uniform in `yaw_range_rad` (lo, hi), the offset
    uniform in the disc of radius `xy_offset_max_m` (0: at the centre); the two are env.init_state's."""
    lo, hi = yaw_range_rad
    yaw = lo + (hi - lo) * u[:, 0]
    xy = np.zeros((len(u), 2))
    if xy_offset_max_m > 0:
        rho = xy_offset_max_m * np.sqrt(u[:, 1])
        angle = -np.pi + 2 * np.pi * u[:, 2]
        xy = np.stack([rho * np.cos(angle), rho * np.sin(angle)], axis=1)
    return yaw, xy


class MovingPlatformEnv(BaseEnv):
    cfg_class = MovingPlatformCfg
    # the observation groups it hands out: what a policy may read (lasmp.config.train checks it at start-up)
    OBS_GROUPS = ("policy", "history", "priv_explicit", "priv_implicit", "alignment", "critic")
    # the critic: [o, x_exp, x_imp, u_aln, p_body_p (3), phi_body_w (3)]
    CRITIC_RUNS = {"policy": OBS_DIM, "priv_explicit": 13, "priv_implicit": X_IMP_DIM, "alignment": 3}
    CRITIC_EXTRA = 6

    @classmethod
    def build_model(cls, cfg: MovingPlatformCfg):
        return build_model(cfg.platform, cfg.sim)

    def __init__(self, cfg: MovingPlatformCfg, device="cpu", check_fit: CheckFit | None = None):
        self.check_cfg_class(type(cfg))
        # the scene: the platform's nominal gains, its top, its model
        self.gains = platform_gains(cfg.platform)
        self.plf_top_m = platform_top_z_m(cfg.platform)
        model = build_model(cfg.platform, cfg.sim)
        dt_s = cfg.sim.dt_s * cfg.sim.decimation
        episode_s = cfg.trajectory.duration_s + cfg.trajectory.hold_s  # the reference holds after T
        super().__init__(
            cfg, model, 12, int(round(episode_s / dt_s)), device, index_class=SceneIndex, check_fit=check_fit
        )
        n, dev = self.num_envs, self.device
        plf_act_pos, plf_act_vel = platform_actuator_ids(model)
        self.plf_act_pos = torch.as_tensor(plf_act_pos, device=dev)
        self.plf_act_vel = torch.as_tensor(plf_act_vel, device=dev)
        self.writer = IntrinsicsWriter(self.sim, self.gains, self.plf_act_pos, self.plf_act_vel)
        self.intrinsics: Intrinsics = nominal_intrinsics(n, cfg.platform.kd_factor_ref)  # host copy
        self.x_imp = self.tensor(self.intrinsics.x_imp())  # (n, 29) on the device, rows set at reset
        # servo targets in `act`
        self.plf_act_adr = torch.as_tensor(model.actuator_actadr[plf_act_pos], device=dev)
        # the columns the step writes, as slices where they are (evenly spaced runs: faster writes)
        self._plf_pos_ctrl, self._plf_vel_ctrl, self._plf_act = (
            as_slice(ix) for ix in (self.plf_act_pos, self.plf_act_vel, self.plf_act_adr)
        )
        self.pose_to_joint = torch.as_tensor(POSE_TO_JOINT, device=dev)
        self._rows2 = torch.arange(n, device=dev).repeat(2)  # one reference evaluation for two times

        tc, cc = cfg.trajectory, cfg.curriculum
        self.traj_ranges = trj.ranges_for_split(tc.split)
        self.traj_file = trj.load(tc.file) if tc.file else None
        self._file_cursor = 0
        # a data-parallel run (torchrun) shares one curriculum across its ranks
        shared = torch.distributed.is_available() and torch.distributed.is_initialized()
        self.curriculum = (
            (SharedCurriculum if shared and torch.distributed.get_world_size() > 1 else WaypointCurriculum)(
                cc.level_min,
                cc.level_max,
                cc.promote_success_rate,
                cc.window_episodes,
                cc.replay_lower_fraction,
            )
            if cc.enabled and self.traj_file is None
            else None
        )
        # host copy (files, plots, tracking); the step evaluates `traj_dev`
        self.spline = trj.SplineSpec(tc.kind, tc.degree)  # the curve through the waypoints
        self.traj = trj.sample(
            n, self.traj_ranges, self.rng, n_waypoints=self.traj_ranges.n_waypoints_min, spline=self.spline
        )
        self.traj_dev = DevicePoly(self.traj, dev, self.dtype)
        self.traj_level = np.full(n, -1)

        rc = cfg.rewards
        self.h_des_p_m = rc.h_des_p_m(self.plf_top_m)  # desired trunk height in the platform frame
        # the terms read h_des in the platform frame
        self.rewards = RewardManager(REWARD_TERMS, rc.weights, rc.in_platform_frame(self.plf_top_m), n, dev)
        self.plf_half_xy_m = self.tensor(cfg.platform.size_m[:2]) / 2.0
        self.obs_columns = column_runs(self.CRITIC_RUNS, whole="critic")

        zeros = lambda *shape: torch.zeros((n, *shape), dtype=self.dtype, device=dev)  # noqa: E731
        self.tau_prev = zeros(12)
        self.q_dot_prev = zeros(12)
        self.contact_prev = torch.zeros((n, 4), dtype=torch.bool, device=dev)
        self.t_air_s = zeros(4)
        self.t_contact_s = zeros(4)
        self.nonfinite_obs_values = 0  # replaced by 0 in the last observation (a fault symptom)
        self.readout: SceneReadout | None = None
        # Hooks for evaluation: `episode_source.next_episodes(ids)` (host ids) -> (trajectories,
        # levels, Intrinsics, (n, 3) initial-pose uniforms) replaces the random draws at reset; `on_step(readout, collision)` sees
        # every step's state (tensors) before the finished envs are reset.
        self.episode_source = None
        self.on_step = None
        self.last_state: StepState | None = None
        self.nominal_com_y_m = nominal_com_y_m(model)
        self._obs_mirror = ObservationMirror(self.nominal_com_y_m)

    # -- the sagittal mirror (rsl_rl's symmetry augmentation: lasmp/algo/symmetry.py) ---------------
    def mirror_observations(self, obs: TensorDict) -> TensorDict:
        """The observation groups of the mirror-image states (lasmp/envs/moving_platform/mirror.py)."""
        return self._obs_mirror(obs)

    def mirror_actions(self, actions: torch.Tensor) -> torch.Tensor:
        """The actions that mirror `actions` (n, 12)."""
        return ACTIONS(actions)

    # -- control -------------------------------------------------------------------------------

    def _apply_actions(self, actions: torch.Tensor) -> None:
        self._apply_joint_targets(actions)
        ctrl = self.sim.ctrl
        # the kp servo's target (its `act`: 0 after a reset, where every trajectory starts) ramps
        # from where the last step left it, x_ref(t) up to rounding, to x_ref(t + dt); the damping
        # term tracks the reference velocity at mid-step (or damps toward rest, without velocity
        # feedforward). The target is never written: a write to the state between steps makes
        # Batch recompute the position and velocity stages that the last step already computed
        # (docs/performance.md#the-environment)
        n, dt = self.num_envs, self.dt_s
        t_s = self.episode_length_buf.to(self.dtype) * dt
        if self.cfg.platform.velocity_feedforward:
            times = torch.cat([t_s + dt, t_s + 0.5 * dt])  # one evaluation for both
            pose, vel = self.traj_dev.evaluate(times, self._rows2)
            ctrl[:, self._plf_vel_ctrl] = vel[n:, self.pose_to_joint]
        else:
            pose, _ = self.traj_dev.evaluate(t_s + dt, self._rows2[:n], velocity=False)
            ctrl[:, self._plf_vel_ctrl] = 0.0
        x_next = pose[:n, self.pose_to_joint]
        ctrl[:, self._plf_pos_ctrl] = (x_next - self.sim.act[:, self._plf_act]) / dt

    # -- evaluation ----------------------------------------------------------------------------
    def _fell(self, r: SceneReadout) -> torch.Tensor:
        tc = self.cfg.termination
        off = (torch.abs(r.p_body_p[:, :2]) > self.plf_half_xy_m + tc.footprint_margin_m).any(dim=1)
        below = r.p_body_p[:, 2] < self.plf_top_m + tc.fall_below_top_m
        return off | below

    def _evaluate(self):
        r, faulted = screen_faults(read_scene(self.sim, self.index), self.cfg.termination.max_joint_vel_rad_s)
        self.readout = r
        fell = self._fell(r)
        collision = r.body_collision | fell
        dt = self.dt_s
        contact = r.foot_contact
        gait = step_gait_phase(contact, self.contact_prev, self.t_air_s, self.t_contact_s, dt)
        f32 = torch.float32  # rewards are computed in float32 on every backend
        from_readout = (
            "p_body_p",
            "phi_body_w",
            "v_body_b",
            "omega_body_b",
            "v_plf_b",
            "omega_plf_b",
            "u_aln",
            "tau",
            "q_dot",
            "f_feet_w",
            "v_slip_p",
            "p_feet_p",
            "f_feet_p",
        )
        state = StepState(
            dt_s=dt,
            **{name: getattr(r, name).to(f32) for name in from_readout},
            action=self.action.to(f32),
            action_prev=self.action_prev.to(f32),
            tau_prev=self.tau_prev.to(f32),
            q_ddot=((r.q_dot - self.q_dot_prev) / dt).to(f32),
            contact=contact,
            touchdown=gait.touchdown,
            liftoff=gait.liftoff,
            t_air_s=gait.t_air_s.to(f32),
            t_contact_s=gait.t_contact_s.to(f32),
            t_air_running_s=self.t_air_s.to(f32, copy=True),
            at_time_limit=(self.episode_length_buf >= self.max_episode_length) & ~collision,
            collision=collision,
        )
        self.last_state = state
        reward = self.rewards.compute(state)
        self.tau_prev.copy_(r.tau)
        self.q_dot_prev.copy_(r.q_dot)
        log = {
            "Termination/body_contact": float(r.body_collision.sum()),
            "Termination/fell": float(fell.sum()),
            # the stance: the share of envs with all four feet down, and the longest open swing (s)
            "Gait/four_feet_share": float(contact.all(dim=1).to(f32).mean()),
            "Gait/longest_open_swing_s": float(self.t_air_s.max()),
            # a rate over no episode until one ends at this step (the reset's log then holds it): the
            # progress line keeps its column before the first episode ends
            "Episode/success_rate": float("nan"),
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
        return trj.sample(
            len(ids), self.traj_ranges, self.rng, n_waypoints=levels, spline=self.spline
        ), levels

    def _reset_envs(self, ids: torch.Tensor, terminated: torch.Tensor, timed_out: torch.Tensor) -> dict:
        log = {}
        finished = terminated | timed_out
        ids_h = ids.cpu().numpy()  # the host draws below are per env
        if finished.any():
            done = ids[finished]
            log = self._finished_episode_log(done)
            success = timed_out[finished].cpu().numpy()
            log["Episode/success_rate"] = float(success.mean())
            if self.curriculum is not None:
                self.curriculum.update(self.traj_level[ids_h[finished.cpu().numpy()]], success)

        n = len(ids)
        dr = self.cfg.domain_rand
        pose_u = None  # training draws the initial pose from self.rng below
        if self.episode_source is not None:
            new_traj, levels, params, pose_u = self.episode_source.next_episodes(ids_h)
        else:
            if dr.enabled:
                params = sample_intrinsics(n, self.intrinsic_ranges, self.rng)
            else:
                params = nominal_intrinsics(n, self.cfg.platform.kd_factor_ref)
            new_traj, levels = self._next_trajectories(ids_h)
        update_rows(self.intrinsics, ids_h, params)
        self.x_imp[ids] = self.tensor(params.x_imp())
        self.writer.write(ids, params)
        self.traj.replace_rows(ids_h, new_traj)
        self.traj_dev.replace_rows(ids, new_traj)
        self.traj_level[ids_h] = levels

        init = self.cfg.init_state
        # three uniforms per env (yaw, then the xy offset's radius and angle where there is one): this
        # order fixes the random stream a seed gives
        if pose_u is None:
            pose_u = np.zeros((n, 3))
            pose_u[:, 0] = self.rng.uniform(size=n)
            if init.xy_offset_max_m > 0:
                pose_u[:, 1] = self.rng.uniform(size=n)
                pose_u[:, 2] = self.rng.uniform(size=n)
        yaw, xy = initial_pose(pose_u, init.yaw_range_rad, init.xy_offset_max_m)
        qpos = self._standing_qpos(xy, self.plf_top_m, yaw)  # on the platform's top (centred at the origin)
        qpos[:, self.index.plf_qpos] = 0.0
        self._reset_physics(ids, qpos)

        for buf in (
            self.action,
            self.action_prev,
            self.tau_prev,
            self.q_dot_prev,
            self.t_air_s,
            self.t_contact_s,
        ):
            buf[ids] = 0.0
        self.contact_prev[ids] = False
        self._fresh = ids  # their history is filled with their first observation
        return log

    # -- observations --------------------------------------------------------------------------
    def _observations(self) -> TensorDict:
        # the readout of this step, with the envs reset since then read again (their new state)
        if self.readout is None or (self._fresh is not None and len(self._fresh) == self.num_envs):
            self.readout = read_scene(self.sim, self.index)
        elif self._fresh is not None:
            update_rows(self.readout, self._fresh, read_scene(self.sim, self.index, self._fresh))
        r = self.readout
        o = proprioception(r, self.action, self.q_nominal)
        critic = torch.cat(
            [
                o,
                r.foot_contact.to(self.dtype),
                r.v_body_b,
                r.v_plf_b,
                r.omega_plf_b,
                self.x_imp,
                r.u_aln,
                r.p_body_p,
                r.phi_body_w,
            ],
            dim=1,
        )
        return self._package_observations(critic, self.obs_columns)

    # -- checkpoint state ----------------------------------------------------------------------
    TASK_STATE = (
        "tau_prev",
        "q_dot_prev",
        "contact_prev",
        "t_air_s",
        "t_contact_s",
        "traj",
        "traj_dev",
        "traj_level",
        "_file_cursor",
        "intrinsics",
        "x_imp",
        "rewards",
        "readout",
        "last_state",
    )
    RUN_STATE_CLASSES = (StepState, SceneReadout)

    def _task_state(self) -> dict:
        return {"curriculum": self.curriculum.state_dict() if self.curriculum is not None else None}

    def _load_task_state(self, d: dict) -> None:
        if self.curriculum is not None and d.get("curriculum") is not None:
            self.curriculum.load_state_dict(d["curriculum"])
