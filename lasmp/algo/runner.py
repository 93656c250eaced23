"""Training runner: rsl_rl's `OnPolicyRunner` with complete, atomic, checked checkpoints (see
`lasmp.algo.checkpoint`), a fault guard and safe interruption.

- Divergence: the learner's update raises `FloatingPointError` on a non-finite loss or parameter
  (`PPOROA`'s guard), and `save` refuses to write a non-finite checkpoint, so the last good one stays.
- The loop (`_learn_loop`) is rsl_rl's `OnPolicyRunner.learn`, step for step (the same calls in the
  same order, so a seeded run repeats its curve), with the runner's own steps in it: after every
  env-step of a rollout `_after_env_step` (the fault guard; a stop asked for abandons the rollout),
  after every iteration's log `_after_iteration` (validation; a stop saves and raises), then the
  checkpoint schedule. The logger only logs.
- Stopping early (a signal, physics faults): lasmp/algo/stopping.py; validation: lasmp/algo/validating.py.
- Disk: after each save into the run directory the newest `keep_full` full checkpoints stay, older
  ones become policy checkpoints (`keep_newest_full`), and a line names them.
- Console (`lasmp.algo.console`): one line per network instead of rsl_rl's printout of every layer,
  then one progress line per iteration.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import torch
from rsl_rl.utils import check_nan

from lasmp.algo import distributed as dp
from lasmp.algo.checkpoint import (
    CHECKPOINT_FORMAT,
    CheckpointError,
    atomic_torch_save,
    check_compatible,
    check_finite,
    keep_newest_full,
    not_fitting,
    obs_layout,
    read_checkpoint,
    refuse_policy_only,
    rng_state,
    set_rng_state,
)
from lasmp.algo.console import OneLineLogger, network_line, without_network_printout
from lasmp.algo.stopping import INTERRUPT_SIGNALS, RolloutAbandoned, StoppingMixin, TrainingInterrupted
from lasmp.algo.validating import ValidatingMixin
from lasmp.compat.rsl_rl import OnPolicyRunnerCompat


def _array_bytes(obj, seen: set[int] | None = None) -> int:
    """The bytes of the tensors and numpy arrays in a nested structure of dicts, lists and tuples;
    a tensor storage shared by several entries counts once, as torch.save writes it once."""
    seen = set() if seen is None else seen
    if isinstance(obj, torch.Tensor):
        storage = obj.untyped_storage()
        if storage.data_ptr() in seen:
            return 0
        seen.add(storage.data_ptr())
        return storage.nbytes()
    if isinstance(obj, np.ndarray):
        return obj.nbytes
    if isinstance(obj, dict):
        return sum(_array_bytes(v, seen) for v in obj.values())
    if isinstance(obj, (list, tuple)):
        return sum(_array_bytes(v, seen) for v in obj)
    return 0


class LasmpRunner(StoppingMixin, ValidatingMixin, OnPolicyRunnerCompat):
    """`OnPolicyRunner` + checkpoints with config, layout, env and random state; fault guard;
    checkpoint on SIGINT / SIGTERM."""

    def __init__(
        self,
        env,
        train_cfg: dict,
        log_dir: str | None,
        device: str = "cpu",
        full_config: dict | None = None,
        max_fault_fraction: float = 0.5,
        keep_full: int = 2,
        validator=None,
        validation_interval: int = 0,
    ):
        """`validator(iteration, actor_state_dict, obs_layout, num_actions)` -> a score with `key()`
        (lower is better) and plain fields; called every `validation_interval` iterations (0: never)."""
        with without_network_printout(lambda: getattr(self, "alg", None)):
            super().__init__(env, train_cfg, log_dir=log_dir, device=device)
        if self.gpu_global_rank == 0:
            obs = env.get_observations()
            print(network_line("actor", self.alg.get_policy(), obs), flush=True)
            print(network_line("critic", self.alg.critic, obs), flush=True)
        self.full_config = full_config or {}
        self.max_fault_fraction = max_fault_fraction
        self.keep_full = keep_full
        self._faults_before = 0  # env.fault_count when the iteration under way began
        self.logger = OneLineLogger(
            log_dir=log_dir,
            cfg=self.cfg,
            env_cfg=env.cfg,
            num_envs=env.num_envs,
            is_distributed=self.is_distributed,
            gpu_world_size=self.gpu_world_size,
            gpu_global_rank=self.gpu_global_rank,
            device=self.device,
        )
        self._final_iteration = -1  # the last iteration of the current learn()
        self._other_ranks: list | None = None  # rank 0: the other ranks' running state for the next save
        self._signal: int | None = None
        self._under_way = 0  # the iteration whose rollout or update is under way
        self._rollout_steps = 0  # the env-steps of its rollout so far
        self._abandoned: dict | None = None  # while saving at a rollout's stop: which rollout, how far
        self.validator = validator
        self.validation_interval = validation_interval if validator is not None else 0
        self.validation_history: list[dict] = []  # every score of the run, resumes included
        self.validation_best: dict | None = None  # the best score so far (its record)
        self._wall_before_s = 0.0  # the run's training seconds before this command (from its checkpoint)
        self._learn_start_s: float | None = None

    # -- data-parallel training (lasmp.algo.distributed) -------------------------------------------
    def configure_ranks(self) -> None:
        """rsl_rl's multi-GPU setup without its NCCL-and-CUDA assumption: gloo on a CPU, NCCL on CUDA."""
        ranks = dp.ranks_from_env()
        self.gpu_world_size, self.gpu_global_rank, self.gpu_local_rank = (
            ranks.world_size,
            ranks.rank,
            ranks.local_rank,
        )
        self.is_distributed = ranks.distributed
        self.cfg["multi_gpu"] = (
            {"global_rank": ranks.rank, "local_rank": ranks.local_rank, "world_size": ranks.world_size}
            if ranks.distributed
            else None
        )
        if ranks.distributed:
            self.device = dp.rank_device(self.device, ranks)
            dp.setup(ranks, self.device)

    def _share_iteration_end(self, it: int) -> int | None:
        """Every rank at the end of iteration `it`: one curriculum, one decision to stop (returned: the
        signal, or None), and, before a save, the other ranks' running state on rank 0."""
        if hasattr(getattr(self.env, "curriculum", None), "sync"):
            self.env.curriculum.sync()
        stop = self._agreed_signal()
        saving = stop is not None or it == self._final_iteration or it % self.cfg["save_interval"] == 0
        if saving:
            mine = {"run": self.env.state_dict()["run"], "rng_state": rng_state(self.env.rng)}
            gathered = dp.gather_to_main(mine)
            self._other_ranks = gathered[1:] if gathered is not None else None
        return stop

    def _agreed_signal(self) -> int | None:
        """The signal any rank has received, the same answer on every rank. The handler's own record
        is only read, never overwritten: a signal that lands while this rank waits in the collective
        (after it has given 0) is counted at the next iteration's end, by every rank at once, instead
        of being lost (torchrun would then kill the job without a checkpoint 30 s later)."""
        return dp.any_rank(self._signal or 0, self.device) or None

    def _this_ranks_state(self, data: dict, run: bool) -> dict:
        """A resume in a job of K ranks: rank k's envs' running state and random state from the
        checkpoint (rank 0's are its own; the others' are under `other_ranks`)."""
        others = data.get("other_ranks") or []
        if not run:
            return data
        if len(others) != self.gpu_world_size - 1:
            raise CheckpointError(
                f"{data.get('path', 'the checkpoint')} holds the running state of {len(others) + 1} process(es), "
                f"this job has {self.gpu_world_size}: give resume_drop_env_state=true to start every env's "
                "episode anew (the resume is then not exact)"
            )
        if self.gpu_global_rank == 0:
            return data
        mine = others[self.gpu_global_rank - 1]
        return {
            **data,
            "env_state": {**data["env_state"], "run": mine["run"]},
            "rng_state": mine["rng_state"],
            "episode_log_state": None,
        }

    def _after_iteration(self, it: int) -> None:
        self._under_way, self._rollout_steps = it + 1, 0
        self._faults_before = getattr(self.env, "fault_count", 0)  # the next rollout's faults count from here
        if self._signal is None:  # a stop asked for saves at once, without a validation first
            self._validate_if_due(it)
        stop = self._share_iteration_end(it) if self.is_distributed else self._signal
        if stop is None:
            return
        path = None
        if self.logger.log_dir is not None:
            path = str(Path(self.logger.log_dir) / f"model_{it}.pt")
            self.save(path)
            self.logger.stop_logging_writer()
        raise TrainingInterrupted(stop, it, path)

    def learn(self, num_learning_iterations: int, init_at_random_ep_len: bool = False) -> None:
        """The training loop (`_learn_loop`); SIGINT / SIGTERM (main thread only) end it after the current iteration with a
        checkpoint and `TrainingInterrupted`."""
        previous = {}
        if threading.current_thread() is threading.main_thread():
            previous = {s: signal.signal(s, self._on_signal) for s in INTERRUPT_SIGNALS}
        self._signal = None
        self._under_way, self._rollout_steps = self.current_learning_iteration, 0
        self._learn_start_s = time.perf_counter()
        self._final_iteration = self.current_learning_iteration + num_learning_iterations - 1
        self._faults_before = getattr(self.env, "fault_count", 0)
        try:
            try:
                self._learn_loop(num_learning_iterations, init_at_random_ep_len)
            except RolloutAbandoned:
                self._stop_in_rollout()
        except BaseException:
            if self.is_distributed and previous:
                # this rank ends (stopped, or a peer lost): torchrun's agent, seeing a rank gone,
                # sends the others SIGTERM within a fraction of a second; ignored from here, so that
                # the rank's one-line report (train.main) is said whole and it exits with its own code
                previous = dict.fromkeys(previous, signal.SIG_IGN)
            raise
        finally:
            for s, handler in previous.items():
                signal.signal(s, handler)
            self._wall_before_s, self._learn_start_s = self.wall_s(), None

    def _learn_loop(self, num_learning_iterations: int, init_at_random_ep_len: bool) -> None:
        """rsl_rl's `OnPolicyRunner.learn` (the module's docstring), with the runner's steps named.
        Not supported here: rsl_rl's RND (the intrinsic rewards it logs)."""
        if init_at_random_ep_len:
            self.env.episode_length_buf = torch.randint_like(
                self.env.episode_length_buf, high=int(self.env.max_episode_length)
            )
        obs = self.env.get_observations().to(self.device)
        self.alg.train_mode()
        if self.is_distributed:
            print(f"Synchronizing parameters for rank {self.gpu_global_rank}...")
            self.alg.broadcast_parameters()
        self.logger.init_logging_writer()
        start_it = self.current_learning_iteration
        total_it = start_it + num_learning_iterations
        for it in range(start_it, total_it):
            start = time.time()
            with torch.inference_mode():
                for _ in range(self.cfg["num_steps_per_env"]):
                    actions = self.alg.act(obs)
                    obs, rewards, dones, extras = self.env.step(actions.to(self.env.device))
                    if self.cfg.get("check_for_nan", True):
                        check_nan(obs, rewards, dones)
                    obs, rewards, dones = obs.to(self.device), rewards.to(self.device), dones.to(self.device)
                    self.alg.process_env_step(obs, rewards, dones, extras)
                    self.logger.process_env_step(rewards, dones, extras, None)
                    self._after_env_step()
                stop = time.time()
                collect_time, start = stop - start, stop
                self.alg.compute_returns(obs)
            loss_dict = self.alg.update()
            learn_time = time.time() - start
            self.current_learning_iteration = it
            try:
                self.logger.log(
                    it=it,
                    start_it=start_it,
                    total_it=total_it,
                    collect_time=collect_time,
                    learn_time=learn_time,
                    loss_dict=loss_dict,
                    learning_rate=self.alg.learning_rate,
                    action_std=self.alg.get_policy().output_std,
                    rnd_weight=None,
                )
            finally:  # a stop asked for is honoured even if the log failed
                self._after_iteration(it)
            if self.logger.writer is not None and it % self.cfg["save_interval"] == 0:
                self.save(os.path.join(self.logger.log_dir, f"model_{it}.pt"))
        if self.logger.writer is not None:
            self.save(os.path.join(self.logger.log_dir, f"model_{self.current_learning_iteration}.pt"))
            self.logger.stop_logging_writer()

    # -- checkpoints -------------------------------------------------------------------------------
    def save(self, path: str, infos: dict | None = None) -> None:
        """Write the checkpoint to `path` (atomically); any failure of the write is an AtomicWriteError
        naming `path` (`atomic_torch_save`)."""
        atomic_torch_save(self.checkpoint_data(infos, path), path)
        run_dir = self.logger.log_dir
        if run_dir is not None and Path(path).parent.resolve() == Path(run_dir).resolve():
            self._keep_newest_full(run_dir)

    def checkpoint_size(self) -> int:
        """A lower bound of the bytes of a checkpoint of this run: the arrays it would hold now
        (tensors, each storage once, and numpy arrays: almost all of the file). Before the
        optimizers' first step their moments do not exist yet, so the first checkpoint's file is
        larger (by up to two copies of the trained parameters). Counted, not serialized: cheap, and
        independent of the writer."""
        return _array_bytes(self.checkpoint_data(None, None))

    def checkpoint_data(self, infos: dict | None, path: str | None, run_state: bool = True) -> dict:
        """What a checkpoint holds; a non-finite network or optimizer state is refused (FloatingPointError
        naming `path`, where given), so that the last good checkpoint stays. Without `run_state` the
        envs' running state is left out (a policy checkpoint drops it anyway)."""
        data = self.alg.save()
        if path is not None:
            check_finite(data, f"refusing to save {path}")
        data.update(
            format=CHECKPOINT_FORMAT,
            iter=self.current_learning_iteration,
            infos=infos,
            config=self.full_config,
            obs_layout=obs_layout(self.env.get_observations()),
            num_actions=self.env.num_actions,
            env_state=self.env.state_dict(run=run_state),
            rng_state=rng_state(self.env.rng),
            episode_log_state=self.logger.episode_log_state(),
            validation={
                "history": self.validation_history,
                "best": self.validation_best,
                "wall_s": self.wall_s(),
            },
        )
        if self._abandoned:  # saved at a rollout's stop: a resume says it is not exact
            data["abandoned_rollout"] = dict(self._abandoned)
        if self.is_distributed:  # every rank's envs, so that a resume of the job continues each of them
            data["other_ranks"] = self._other_ranks
            data["world_size"] = self.gpu_world_size
        return data

    def _keep_newest_full(self, run_dir: str) -> None:
        """The newest `keep_full` full checkpoints of the run stay; older ones become policy
        checkpoints, named in one line (never silently)."""
        converted, left = keep_newest_full(run_dir, self.keep_full)
        if converted or left:
            said = [f"kept as policy checkpoints: {', '.join(converted)}"] if converted else []
            said += [f"left as they were: {'; '.join(left)}"] if left else []
            print(f"checkpoints (runner.keep_full={self.keep_full}): {'; '.join(said)}", flush=True)

    def load(
        self,
        path: str | dict,
        load_cfg: dict | None = None,
        strict: bool = True,
        map_location: str | None = None,
    ):
        """Load a checkpoint: a path, or a `read_checkpoint` result (a tool reads its file once)."""
        data = path if isinstance(path, dict) else read_checkpoint(path, map_location or self.device)
        check_compatible(data, self.env)
        if load_cfg is None or load_cfg.get("optimizer", True):
            refuse_policy_only(data)
        run_wanted = load_cfg is None or load_cfg.get("env_run_state", True)
        if self.is_distributed or data.get("other_ranks"):
            data = self._this_ranks_state(data, run_wanted and bool((data.get("env_state") or {}).get("run")))
        where = data.get("path", "the checkpoint")
        # a file that passed read_checkpoint may still not fit: its errors as CheckpointError, naming it
        with not_fitting(f"{where} does not fit this policy and learner"):
            iteration = self.alg.load(data, load_cfg, strict)  # the learner goes on from the checkpoint's too
        if iteration:
            self.current_learning_iteration = int(data["iter"]) + 1  # the saved iteration is complete
        if data.get("env_state"):  # the running state only to resume training in an env of the same size
            run = load_cfg is None or load_cfg.get("env_run_state", True)
            with not_fitting(f"{where}: the envs' running state does not fit this env"):
                restored = self.env.load_state_dict(data["env_state"], run=run)
                if restored and data.get("episode_log_state"):
                    self.logger.load_episode_log_state(data["episode_log_state"])
        if data.get("validation"):  # older checkpoints lack it: the scores start afresh
            saved = data["validation"]
            self.validation_history = list(saved["history"])
            self.validation_best = saved["best"]
            self._wall_before_s = float(saved["wall_s"])
        if data.get("rng_state"):  # older checkpoints lack it: the streams then restart from the seed
            with not_fitting(f"{where}: its random state cannot be restored"):
                set_rng_state(data["rng_state"], self.env.rng)
        return data.get("infos")
