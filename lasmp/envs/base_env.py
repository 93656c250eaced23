"""The shared step loop of every lasmp task, on rsl_rl's `VecEnv` contract.

`step(actions)` = check actions -> `_apply_actions` -> physics (the backend's `step`, decimation
substeps) -> `_evaluate` (rewards, terminations, time-outs, from the new state) -> reset the
finished envs -> `_observations` (for reset envs: their first observation). Faulted envs
(flagged by the physics: MuJoCo errors, warnings, non-finite state; or by the task's
`_evaluate`: e.g. runaway joints, see `lasmp.envs.robot.screen_faults`) are terminated, get
reward 0, are reset alone, and are counted in `extras["log"]["/faults/count"]`. A last guard
replaces any non-finite observation value by 0 (the task's `_observations` does it) and counts
it, so that no NaN ever reaches a policy.

`extras["time_outs"]` flags episodes that ended at the time limit (a truncation, to be
bootstrapped), `extras["log"]` holds per-episode reward terms and task metrics.

Every task drives the A1 (`lasmp.envs.robot`), so the robot's part of a step and of a reset is
written here once: `_apply_joint_targets` (the actions as joint position targets) and
`_standing_qpos` / `_reset_physics` (a robot standing at its nominal stance, at rest); a task adds
its world's part (the platform's drive, pushes).

Device: every per-step quantity is a torch tensor on the env's device (the physics backend's,
`lasmp.envs.backends`); only the ids of the envs to reset and the logged numbers come to the
host. Random draws at reset (trajectories, intrinsics, initial yaw) are made on the host with
the env's numpy generator and sent to the device.
"""

from __future__ import annotations

import warnings
from abc import abstractmethod
from collections.abc import Callable

import mujoco
import numpy as np
import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from lasmp.config.base import BaseEnvCfg
from lasmp.envs.backends import make_backend
from lasmp.envs.robot import OBS_DIM, RobotIndex, as_slice
from lasmp.envs.rotations import yaw_quat
from lasmp.io.plainstate import PlainStateError, pack, unpack
from lasmp.robots import a1

# called by an env with its model and its observation groups' widths (`BaseEnv.observation_widths`)
# before its envs' data are allocated: it raises to refuse what cannot fit (lasmp.cli.build.make_env)
CheckFit = Callable[[mujoco.MjModel, dict[str, int]], None]


class BaseEnv(VecEnv):
    cfg_class: type[BaseEnvCfg] = BaseEnvCfg  # the task's env config schema
    OBS_GROUPS: tuple[str, ...] = ()  # the observation groups the task's env hands out
    # the critic's columns, run by run: each of these groups is one run of them (`column_runs`), then
    # CRITIC_EXTRA columns the critic alone reads
    CRITIC_RUNS: dict[str, int] = {}
    CRITIC_EXTRA = 0

    @classmethod
    def build_model(cls, cfg):
        """The task's MuJoCo model of `cfg` (a task builds its scene)."""
        raise NotImplementedError

    @classmethod
    def observation_widths(cls, cfg) -> dict[str, int]:
        """Each observation group's floats per env, as the env of `cfg` hands them out: what a memory
        estimate counts without building an env (tests check them against a built env's)."""
        widths = {**cls.CRITIC_RUNS, "critic": sum(cls.CRITIC_RUNS.values()) + cls.CRITIC_EXTRA}
        return {**widths, "history": cfg.observations.history_length * OBS_DIM}

    @classmethod
    def check_cfg_class(cls, given: type) -> None:
        """Refuse a config of any class (`given`) but the task's config dataclass: an env takes a config
        validated once, where it was built (`lasmp.config.base.build_env_cfg`,
        `lasmp.config.train.to_train_cfg`), never a dict."""
        if not issubclass(given, cls.cfg_class):
            name = cls.cfg_class.__name__
            raise TypeError(
                f"{cls.__name__} takes a validated {name}, got a {given.__name__}: build one with "
                f"lasmp.config.base.build_env_cfg(overrides, schema={name})"
            )

    def __init__(
        self,
        cfg: BaseEnvCfg,
        model,
        num_actions: int,
        max_episode_length: int,
        device="cpu",
        index_class: type[RobotIndex] = RobotIndex,
        check_fit: CheckFit | None = None,
    ):
        if check_fit is not None:  # the model is built; the envs' data are not allocated yet
            check_fit(model, self.observation_widths(cfg))
        self.cfg = cfg
        self.sim = make_backend(cfg.backend, model, cfg.num_envs, cfg.sim, device)
        self.num_envs = cfg.num_envs
        self.num_actions = num_actions
        self.max_episode_length = max_episode_length
        self.device = torch.device(device)
        self.dtype = self.sim.dtype  # of the physics quantities (float64 on the CPU backend)
        self.dt_s = cfg.sim.dt_s * cfg.sim.decimation
        self.rng = np.random.default_rng(cfg.seed)
        dr = cfg.domain_rand  # the table of ranges an env's intrinsics are drawn from at reset
        self.intrinsic_ranges = dr.train if dr.split == "train" else dr.test
        # the A1: its addresses in the model (`index_class`: the robot's, or a task's extension with its
        # world's), its nominal stance, and the actions a_t and a_{t-1}
        self.index = index_class(model, self.device)
        self.q_nominal = self.tensor(a1.Q_NOMINAL_RAD)
        self.qpos0 = self.tensor(model.qpos0)
        self.trunk_height_m = a1.nominal_trunk_height_m(model)
        self._robot_ctrl = as_slice(self.index.joint_act)  # the columns a step writes (a slice: faster)
        self.action = torch.zeros((self.num_envs, num_actions), dtype=self.dtype, device=self.device)
        self.action_prev = torch.zeros_like(self.action)
        self.episode_length_buf = torch.zeros(self.num_envs, dtype=torch.long, device=self.device)
        self.fault_count = 0  # faulted envs since construction
        self._obs: TensorDict | None = None
        self.nonfinite_obs_values = 0
        # o^H: past observations, newest first; envs in `_fresh` (just reset) get theirs filled with o_0
        self.history = torch.zeros(
            self.num_envs, cfg.observations.history_length, OBS_DIM, device=self.device
        )
        # the next history is written into one of two spare buffers in turn, so that no buffer is
        # allocated per step and the one handed out stays as it is through the next step too (rsl_rl
        # copies a step's observations into its storage only after the following env step)
        self._history_spares = [torch.zeros_like(self.history) for _ in range(2)]
        self._fresh: torch.Tensor | None = None  # ids of the envs reset since the last observation
        # evaluation hook: when set (a long tensor of env ids), only these envs' physics advance (the
        # idle envs at the tail of an evaluation); the others keep their state, their outputs are ignored
        self.stepped_envs: torch.Tensor | None = None

    # what a checkpoint carries for an exact resume, besides the physics: the per-env buffers the step
    # loop reads (a task lists its own in TASK_STATE)
    RUN_STATE = (
        "episode_length_buf",
        "history",
        "_obs",
        "_fresh",
        "fault_count",
        "nonfinite_obs_values",
        "action",
        "action_prev",
    )
    TASK_STATE: tuple[str, ...] = ()
    # dataclasses of the running state that a fresh env may not hold yet (None): the only classes a
    # checkpoint's running state may build (`lasmp.io.plainstate`)
    RUN_STATE_CLASSES: tuple[type, ...] = ()
    # 3: plain data (`lasmp.io.plainstate`), loadable without unpickling; 2: pickled objects; 1: numpy
    RUN_STATE_FORMAT = 3

    def state_dict(self, run: bool = True) -> dict:
        """The task's persistent state (e.g. the curriculum) and, with `run`, the running state of
        every env (physics, buffers, trajectories, intrinsics): enough for a resume that continues
        bit for bit, together with the random states the checkpoint saves."""
        d = self._task_state()
        if run:
            names = self.RUN_STATE + self.TASK_STATE
            d["run"] = {
                "format": self.RUN_STATE_FORMAT,
                "backend": self.cfg.backend,
                "num_envs": self.num_envs,
                "sim": pack(self.sim.get_state()),
                "attrs": pack({k: getattr(self, k) for k in names}),
            }
        return d

    def load_state_dict(self, d: dict, run: bool = True) -> bool:
        """Restore `state_dict` output; the running state only with `run` and a saved one (older
        checkpoints and policy checkpoints carry the task state alone). True if the running state was
        restored (the episodes go on), False if every env starts a new episode."""
        self._load_task_state(d)
        saved = d.get("run")
        if run and saved is not None:
            if saved["num_envs"] != self.num_envs:
                raise ValueError(
                    f"saved running state is for {saved['num_envs']} envs, this env has {self.num_envs}"
                )
            made_by = (saved.get("format", 1), saved.get("backend", "cpu"))
            if made_by != (self.RUN_STATE_FORMAT, self.cfg.backend):
                warnings.warn(
                    f"the checkpoint's running state was saved by another env (format {made_by[0]}, "
                    f"backend {made_by[1]}; this one: {self.RUN_STATE_FORMAT}, {self.cfg.backend}): "
                    "it is not restored, every env starts a new episode (the resume is not exact)",
                    stacklevel=2,
                )
                return False
            live = {k: getattr(self, k) for k in self.RUN_STATE + self.TASK_STATE}
            saved_attrs = saved["attrs"]
            if set(saved_attrs) != set(live):
                raise PlainStateError(
                    f"saved running state holds {sorted(saved_attrs)}, this env {sorted(live)}"
                )
            # checked before any change
            attrs = unpack(saved_attrs, live, self.device, "running state", self.RUN_STATE_CLASSES)
            self.sim.set_state(unpack(saved["sim"], name="physics state"))
            for key, value in attrs.items():
                setattr(self, key, value)
            return True
        return False

    def _task_state(self) -> dict:
        return {}

    def _load_task_state(self, d: dict) -> None:
        pass

    def tensor(self, x) -> torch.Tensor:
        """A host array (or number) as a new tensor of the physics dtype on the env's device (a copy:
        never a view of the host memory)."""
        return torch.tensor(np.asarray(x), dtype=self.dtype, device=self.device)

    # -- the task fills these ----------------------------------------------------------------
    @abstractmethod
    def _apply_actions(self, actions: torch.Tensor) -> None:
        """Write controls for the coming policy step (actions: (n, num_actions), physics dtype, clipped)."""

    @abstractmethod
    def _evaluate(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, dict]:
        """After physics: (reward (n,), terminated (n,) bool, faulted (n,) bool, log dict): the envs
        the task finds diverged, on top of those the physics flagged; all faulted envs are terminated."""

    @abstractmethod
    def _reset_envs(self, ids: torch.Tensor, terminated: torch.Tensor, timed_out: torch.Tensor) -> dict:
        """Reset envs `ids` (long tensor; with why their episodes ended); return log entries of the
        finished episodes."""

    @abstractmethod
    def _observations(self) -> TensorDict:
        """Observation groups of all envs (tensors on self.device, float32), every value finite:
        build the arrays and hand them to `_package_observations`."""

    # -- the robot's part of a step and of a reset ----------------------------------------------
    def _apply_joint_targets(self, actions: torch.Tensor) -> None:
        """The robot's half of `_apply_actions`: a_t becomes a_{t-1}, `actions` become a_t, and the
        joints' position actuators take the targets q_nominal + action_scale * a_t."""
        self.action_prev.copy_(self.action)
        self.action.copy_(actions)
        self.sim.ctrl[:, self._robot_ctrl] = self.q_nominal + self.cfg.control.action_scale * actions

    def _standing_qpos(self, xy_w: np.ndarray, ground_z_m, yaw_rad: np.ndarray) -> torch.Tensor:
        """(n, nq) positions of n robots standing at q_nominal: the trunk origin above `xy_w` (n, 2),
        at the nominal stance's height over `ground_z_m` (a number, or (n,)) plus
        `init_state.foot_clearance_m` (the feet touch, never inside the ground), heading `yaw_rad` (n,);
        the rest is the model's qpos0, where a task sets its world's part."""
        ix, clearance_m = self.index, self.cfg.init_state.foot_clearance_m
        qpos = self.qpos0.repeat(len(xy_w), 1)
        qpos[:, ix.root_qpos : ix.root_qpos + 2] = self.tensor(xy_w)
        qpos[:, ix.root_qpos + 2] = self.tensor(ground_z_m + self.trunk_height_m + clearance_m)
        qpos[:, ix.root_qpos + 3 : ix.root_qpos + 7] = yaw_quat(self.tensor(yaw_rad))
        qpos[:, ix.joint_qpos] = self.q_nominal
        return qpos

    def _reset_physics(self, ids: torch.Tensor, qpos: torch.Tensor) -> None:
        """Envs `ids` start anew at `qpos`, at rest, their joints' targets at q_nominal (every other
        control 0); the model's constants are recomputed (the intrinsics were just written)."""
        n, m = len(ids), self.sim.model
        ctrl = torch.zeros((n, m.nu), dtype=self.dtype, device=self.device)
        ctrl[:, self.index.joint_act] = self.q_nominal
        qvel = torch.zeros((n, m.nv), dtype=self.dtype, device=self.device)
        self.sim.reset(ids, qpos, qvel, ctrl, set_const=True)

    # -- the contract --------------------------------------------------------------------------
    def reset(self) -> tuple[TensorDict, dict]:
        ids = torch.arange(self.num_envs, device=self.device)
        none = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)
        self._reset_envs(ids, none, none)
        self.episode_length_buf.zero_()
        self._obs = self._guarded_observations({})
        return self._obs, {}

    def get_observations(self) -> TensorDict:
        if self._obs is None:
            self.reset()
        return self._obs

    def step(self, actions: torch.Tensor) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        if actions.shape != (self.num_envs, self.num_actions):
            raise ValueError(
                f"actions must have shape {(self.num_envs, self.num_actions)}, got {tuple(actions.shape)}"
            )
        a = actions.detach().to(self.device, self.dtype)
        if not torch.isfinite(a).all():
            bad = torch.nonzero(~torch.isfinite(a).all(dim=1)).flatten()
            raise ValueError(f"actions contain NaN/inf in envs {bad[:10].tolist()}: the policy diverged")
        clip = self.cfg.control.action_clip
        self._apply_actions(torch.clamp(a, -clip, clip))
        sim_faulted = self.sim.step(self.cfg.sim.decimation, self.stepped_envs)
        self.episode_length_buf += 1
        reward, terminated, task_faulted, log = self._evaluate()
        faulted = sim_faulted | task_faulted
        reward = reward.masked_fill(faulted, 0.0)
        terminated = terminated | faulted
        timed_out = (self.episode_length_buf >= self.max_episode_length) & ~terminated
        done = terminated | timed_out
        ids = torch.nonzero(done).flatten()
        n_faulted = int(faulted.sum())
        self.fault_count += n_faulted
        log["/faults/count"] = float(n_faulted)
        if len(ids):
            log.update(self._reset_envs(ids, terminated[ids], timed_out[ids]))
            self.episode_length_buf[ids] = 0
        self._obs = self._guarded_observations(log)
        return self._obs, reward, done, {"time_outs": timed_out, "log": log}

    def _finished_episode_log(self, done: torch.Tensor) -> dict:
        """Per-term reward sums (`self.rewards`, a RewardManager) and mean length of the episodes of
        envs `done`, which end now; their reward sums are zeroed."""
        log = {f"Episode_Reward/{k}": v for k, v in self.rewards.reset(done).items()}
        log["Episode/length_s"] = float(self.episode_length_buf[done].float().mean()) * self.dt_s
        return log

    def _package_observations(self, full: torch.Tensor, groups: dict[str, slice]) -> TensorDict:
        """The TensorDict of the observation groups and `history`, float32, from `full` (n, k): one
        array of which every group, `policy` (o) included, is a run of columns (`groups`: name ->
        slice, see `column_runs`; the critic's group is usually all of it). Non-finite values are
        replaced by 0 and counted (`nonfinite_obs_values`, each value of `full` once), every value
        is clipped to +-observations.clip. The groups are column views of one new float32 array:
        one check, one clip and one conversion for all of them."""
        # fast path, one host sync: a sum is finite when every value is (or so huge that it overflows:
        # then the exact count below says 0)
        bad = 0 if bool(torch.isfinite(full.sum())) else int((~torch.isfinite(full)).sum())
        self.nonfinite_obs_values = bad
        if bad:
            full = torch.nan_to_num(full, nan=0.0, posinf=0.0, neginf=0.0)
        clip = self.cfg.observations.clip
        # clipped after the conversion, in place: the same values (rounding to float32 keeps the order,
        # and the bounds round as the clipped values would), one pass over the wide float64 array less
        full_t = full.to(torch.float32).clamp_(-clip, clip)
        tensors = {key: full_t[:, cols] for key, cols in groups.items()}
        o_t = tensors["policy"]
        history = self.history
        if self._fresh is not None:
            history[self._fresh] = o_t[self._fresh].unsqueeze(1)
            self._fresh = None
        # the next step's history starts with this o
        spare = self._history_spares.pop(0)
        spare[:, 0] = o_t
        spare[:, 1:] = history[:, :-1]
        self._history_spares.append(history)
        self.history = spare
        tensors["history"] = history
        return TensorDict(tensors, batch_size=[self.num_envs], device=self.device)

    def _guarded_observations(self, log: dict) -> TensorDict:
        obs = self._observations()
        log["/faults/nonfinite_obs_values"] = float(self.nonfinite_obs_values)
        return obs


def column_runs(widths: dict[str, int], whole: str) -> dict[str, slice]:
    """{name: slice} of consecutive column runs of the given widths, in order, and `whole`: every
    column (the group the others are parts of)."""
    runs, start = {}, 0
    for name, width in widths.items():
        runs[name] = slice(start, start + width)
        start += width
    runs[whole] = slice(None)
    return runs
