"""Training runner: rsl_rl's `OnPolicyRunner` with complete, atomic, checked checkpoints.

A checkpoint holds all networks (with their normalizers), both optimizers, the iteration to
run next, the resolved config, the observation layout and action size, and the env's
curriculum state. It is written to a temporary file in the same directory and renamed over
the target, so an interrupted save never leaves a truncated checkpoint behind. Loading checks
the file and the observation layout and says what is wrong.
"""

from __future__ import annotations

import datetime
import re
import statistics
from pathlib import Path

import torch
from rsl_rl.runners import OnPolicyRunner
from rsl_rl.utils.logger import Logger

from lasmp.atomic import atomic_open

CHECKPOINT_FORMAT = "lasmp-checkpoint-v1"


class CheckpointError(ValueError):
    """A checkpoint is missing, unreadable or does not fit this run; the message says why."""


def obs_layout(obs) -> dict[str, list[int]]:
    """Per-group shapes of one env's observation (batch dimension dropped)."""
    return {key: list(value.shape[1:]) for key, value in obs.items()}


def latest_checkpoint(run_dir: str | Path) -> Path:
    """The `model_<N>.pt` of `run_dir` with the largest N (numerically: model_10 after model_9)."""
    run_dir = Path(run_dir)
    found = []
    for path in run_dir.glob("model_*.pt"):
        m = re.fullmatch(r"model_(\d+)\.pt", path.name)
        if m:
            found.append((int(m.group(1)), path))
    if not found:
        raise CheckpointError(f"no checkpoint model_<N>.pt in {run_dir}")
    return max(found)[1]


def read_checkpoint(path: str | Path, map_location: str = "cpu") -> dict:
    """Load and sanity-check a checkpoint file (a run directory means its latest checkpoint)."""
    path = Path(path)
    if path.is_dir():
        path = latest_checkpoint(path)
    if not path.exists():
        raise CheckpointError(f"checkpoint {path} does not exist")
    try:
        data = torch.load(path, map_location=map_location, weights_only=False)
    except Exception as err:  # truncated zip, not a torch file, ...
        raise CheckpointError(
            f"checkpoint {path} is unreadable (truncated or not a checkpoint): {err}"
        ) from err
    if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"{path} is not a lasmp checkpoint (no format '{CHECKPOINT_FORMAT}')")
    for key in ("actor_state_dict", "critic_state_dict", "config", "obs_layout", "num_actions", "iter"):
        if key not in data:
            raise CheckpointError(f"checkpoint {path} lacks '{key}'")
    data["path"] = str(path)
    return data


def atomic_torch_save(obj, path: str | Path) -> None:
    with atomic_open(path) as f:
        torch.save(obj, f)


class OneLineLogger(Logger):
    """TensorBoard scalars as rsl_rl's logger writes them, but one terminal line per iteration."""

    def log(self, it, start_it, total_it, collect_time, learn_time, loss_dict, learning_rate, action_std, rnd_weight,
            **_) -> None:  # fmt: skip
        if self.writer is None:
            return
        steps = self.cfg["num_steps_per_env"] * self.num_envs
        self.tot_timesteps += steps
        self.tot_time += collect_time + learn_time
        extras: dict[str, float] = {}
        for key in dict.fromkeys(k for ep in self.ep_extras for k in ep):
            values = [float(ep[key]) for ep in self.ep_extras if key in ep]
            values = [v for v in values if v == v]  # nan: a rate over an empty window
            if values:
                extras[key] = statistics.fmean(values)
                self.writer.add_scalar(key, extras[key], it)
        self.ep_extras.clear()
        for key, value in loss_dict.items():
            self.writer.add_scalar(key if "/" in key else f"Loss/{key}", value, it)
        self.writer.add_scalar("Loss/learning_rate", learning_rate, it)
        self.writer.add_scalar("Policy/mean_std", action_std.mean().item(), it)
        fps = steps / (collect_time + learn_time)
        self.writer.add_scalar("Perf/total_fps", fps, it)
        self.writer.add_scalar("Perf/collection_time", collect_time, it)
        self.writer.add_scalar("Perf/learning_time", learn_time, it)
        reward = statistics.fmean(self.rewbuffer) if self.rewbuffer else float("nan")
        if self.rewbuffer:
            self.writer.add_scalar("Train/mean_reward", reward, it)
            self.writer.add_scalar("Train/mean_episode_length", statistics.fmean(self.lenbuffer), it)
        done = it + 1 - start_it
        eta = datetime.timedelta(seconds=int(self.tot_time / done * (total_it - start_it - done)))
        fields = [f"it {it + 1}/{total_it}", f"{fps:,.0f} steps/s", f"reward {reward:8.2f}"]
        for key, label, fmt in (
            ("Episode/success_rate", "success", ".2f"),
            ("Curriculum/level", "level", ".0f"),
        ):
            if key in extras:
                fields.append(f"{label} {extras[key]:{fmt}}")
        if "roa_exp" in loss_dict:
            fields.append(f"L_exp {loss_dict['roa_exp']:.4f}")
        print(" | ".join(fields + [f"ETA {eta}"]), flush=True)


class LasmpRunner(OnPolicyRunner):
    """`OnPolicyRunner` + checkpoints with config, layout and env state; exact resume."""

    def __init__(
        self, env, train_cfg: dict, log_dir: str | None, device: str = "cpu", full_config: dict | None = None
    ):
        super().__init__(env, train_cfg, log_dir=log_dir, device=device)
        self.full_config = full_config or {}
        self.logger = OneLineLogger(
            log_dir=log_dir, cfg=self.cfg, env_cfg=env.cfg, num_envs=env.num_envs, is_distributed=False,
            gpu_world_size=1, gpu_global_rank=0, device=device,
        )  # fmt: skip

    def save(self, path: str, infos: dict | None = None) -> None:
        data = self.alg.save()
        data.update(
            format=CHECKPOINT_FORMAT,
            iter=self.current_learning_iteration,
            infos=infos,
            config=self.full_config,
            obs_layout=obs_layout(self.env.get_observations()),
            num_actions=self.env.num_actions,
            env_state=self.env.state_dict(),
        )
        atomic_torch_save(data, path)

    def load(
        self, path: str, load_cfg: dict | None = None, strict: bool = True, map_location: str | None = None
    ):
        data = read_checkpoint(path, map_location or self.device)
        check_compatible(data, self.env)
        self.alg.load(data, load_cfg, strict)
        if load_cfg is None or load_cfg.get("iteration", True):
            self.current_learning_iteration = int(data["iter"]) + 1  # the saved iteration is complete
        if data.get("env_state"):
            self.env.load_state_dict(data["env_state"])
        return data.get("infos")


def check_compatible(data: dict, env) -> None:
    """Refuse a checkpoint whose observation layout or action size differs from the env's."""
    have = obs_layout(env.get_observations())
    want = data["obs_layout"]
    for group in sorted(set(have) | set(want)):
        if have.get(group) != want.get(group):
            raise CheckpointError(
                f"checkpoint {data.get('path', '')} was trained with observation group '{group}' of shape "
                f"{want.get(group)}, but this env gives {have.get(group)}"
            )
    if int(data["num_actions"]) != env.num_actions:
        raise CheckpointError(f"checkpoint has {data['num_actions']} actions, the env {env.num_actions}")
