"""PPO with Regularized Online Adaptation, an extension of rsl_rl's `PPO`
(docs/method.md#learning-ppo-with-regularized-online-adaptation-lasmpalgo).

`update()` first runs rsl_rl's PPO update unchanged (actor backbone, implicit encoder, action
std and critic; the estimators get no PPO gradient). It then makes one pass over the same
rollout (rsl_rl's `storage.clear()` only rewinds the write cursor, so the data are still there)
with the adaptation losses of `LasmpActor.roa_losses`:

    L_exp = ||x_exp_hat - x_exp||^2
    L_imp = ||l_imp_hat - sg[l_imp]||^2  +  lambda * ||sg[l_imp_hat] - l_imp||^2,  lambda = 0.2

Our choices where the paper leaves them open (docs/method.md#our-readings-and-departures-in-one-table):
the estimators have their own Adam optimizer (`estimator_learning_rate`); the encoder's
regularization term (the second of L_imp) steps the encoder through PPO's optimizer, in a step of
its own in which no other parameter has a gradient; lambda is constant (no ramp).

The learner counts its iterations (`iteration`: the one whose rollout and update come next; an
update completes it, `load` of a checkpoint continues after the checkpoint's). Rollouts act with
privileged inputs, except that from iteration `estimate_rollout_start` on, every
`estimate_rollout_every`-th iteration (rollout and PPO update alike) acts on the estimators'
detached outputs, as at deployment: the policy then learns to live with estimation errors
(`acts_on_estimates`; the learner sets the actor's `act_on_estimates` for each iteration). Its
PPO update reuses the estimates the rollout acted on, kept at each step (`act`): PPO's epochs
change neither the estimators nor the normalizer, so they are what the policy saw, bit for bit.

The entropy bonus may fall linearly to 0 over the first `entropy_decay_iterations` iterations (ours;
0: constant, as in rsl_rl); the learner sets `entropy_coef` for each iteration, so a resumed run
continues the schedule where its checkpoint left it.

Divergence guard: a non-finite loss, parameter or optimizer state after an update raises
`FloatingPointError` naming it, before the iteration counts as done (the runner then saves nothing).
"""

from __future__ import annotations

import contextlib
import copy
import math
from collections.abc import Iterator
from itertools import chain

import torch
import torch.nn as nn
from rsl_rl.algorithms import PPO
from rsl_rl.storage import RolloutStorage
from rsl_rl.utils import reduce_gradients_in_buckets
from tensordict import TensorDict

from lasmp.algo.checkpoint import check_finite
from lasmp.algo.precision import resolve_precision
from lasmp.algo.symmetry import MirrorAugmentation, mirror_augment, supports_mirror
from lasmp.modules.obs_groups import GROUP_DETACHED_ESTIMATES, GROUP_HISTORY


class RoaRolloutStorage(RolloutStorage):
    """rsl_rl's rollout storage with a PPO pass over a view of the rollout (`ppo_pass`): PPOROA's
    update hands rsl_rl's PPO only the observation groups it reads, and on the estimates the very
    estimates its rollout acted on, without copying the rollout."""

    _ppo_pass = False  # inside `ppo_pass`

    @classmethod
    def like(cls, storage: RolloutStorage) -> RoaRolloutStorage:
        """An empty storage of `storage`'s kind and shapes (rsl_rl's `construct_algorithm` builds a
        plain one and hands it to the learner)."""
        return cls(
            storage.training_type,
            storage.num_envs,
            storage.num_transitions_per_env,
            storage.observations[0],
            storage.actions_shape,
            storage.device,
        )

    @contextlib.contextmanager
    def ppo_pass(self, observations: TensorDict) -> Iterator[None]:
        """Inside: `observations` stand for the stored ones (rsl_rl's PPO update reads them for its
        mini-batches and its normalizer update), and `mini_batch_generator` gathers each mini-batch
        once for all epochs."""
        stored = self.observations
        self.observations, self._ppo_pass = observations, True
        try:
            yield
        finally:
            self.observations, self._ppo_pass = stored, False

    def mini_batch_generator(self, num_mini_batches: int, num_epochs: int = 8):
        """rsl_rl's mini-batches; in a PPO pass each gathered from the rollout once. rsl_rl's
        generator draws one permutation for all epochs, so every epoch visits the same mini-batches
        in the same order (`tests/test_train_mini_batches.py` checks that of the installed rsl_rl): the same
        values, gathered once. A fresh `Batch` per epoch, since PPO may reassign a batch's fields
        (per-mini-batch advantage normalization)."""
        if not self._ppo_pass:
            yield from super().mini_batch_generator(num_mini_batches, num_epochs)
            return
        gathered = list(super().mini_batch_generator(num_mini_batches, 1))
        for _ in range(num_epochs):
            for batch in gathered:
                yield copy.copy(batch)


class PPOROA(PPO):
    def __init__(
        self,
        actor,
        critic,
        storage,
        roa_lambda: float = 0.2,
        estimator_learning_rate: float = 1e-3,
        estimator_epochs: int = 1,
        estimate_rollout_every: int = 0,
        estimate_rollout_start: int = 0,
        entropy_decay_iterations: int = 0,
        precision: str = "auto",
        use_mixed_precision: bool | None = None,
        fused_adam: bool | None = None,
        compile_mlps: bool | None = None,
        symmetry_cfg: dict | None = None,
        bootstrap_time_outs: bool = True,
        **kwargs,
    ) -> None:
        device = kwargs.get("device", "cpu")
        symmetry_cfg = self._symmetry_cfg(symmetry_cfg)
        plan = resolve_precision(precision, device, use_mixed_precision, fused_adam, compile_mlps)
        self.learner_precision = plan
        super().__init__(
            actor,
            critic,
            RoaRolloutStorage.like(storage),
            use_mixed_precision=plan.bf16_autocast,
            symmetry_cfg=None,  # ours below: rsl_rl's, without its second forward pass for a logged loss
            **kwargs,
        )
        self.symmetry = MirrorAugmentation(**symmetry_cfg) if symmetry_cfg else None
        self._fused = plan.fused_adam
        if plan.fused_adam:  # the same Adam in one fused kernel; on a CPU PyTorch otherwise loops per tensor
            self.optimizer = torch.optim.Adam(
                chain(self.actor.parameters(), self.critic.parameters()), lr=self.learning_rate, fused=True
            )
        # auto: the compiler is checked, the networks compiled and the line printed when training starts
        self._learner_started, self._compiled = False, False
        if compile_mlps:  # forced: compiled now, as the switch always did
            self._compile_networks()
        # the settings' ranges are checked once, by the training config (AlgoCfg.BOUNDS, `lasmp.config.checks.check_config`)
        self.roa_lambda = roa_lambda
        self.bootstrap_time_outs = bootstrap_time_outs
        self.estimator_epochs = estimator_epochs
        self.estimate_rollout_every = estimate_rollout_every
        self.estimate_rollout_start = estimate_rollout_start
        self.initial_entropy_coef = self.entropy_coef
        self.entropy_decay_iterations = entropy_decay_iterations
        self._estimator_params = list(actor.estimator_parameters())
        self.estimator_optimizer = torch.optim.Adam(
            self._estimator_params, lr=estimator_learning_rate, fused=True if plan.fused_adam else None
        )
        # (T, N, k): the estimates each rollout step acted on, and how many steps of this rollout hold them
        self._rollout_estimates: torch.Tensor | None = None
        self._estimate_steps = 0
        # the estimates of each mini-batch's mirrored samples in this update's PPO pass: (the mini-batch's
        # observations, the estimates), computed in its first epoch and reused in the others
        self._mirrored_estimates: dict[int, tuple[TensorDict, torch.Tensor]] = {}
        self.iteration = 0

    def process_env_step(self, obs, rewards, dones, extras) -> None:
        """rsl_rl's record of one env-step; without `bootstrap_time_outs` it does not see the time-outs,
        so a time limit ends the return like a fall (the env still reports them to the logger)."""
        if not self.bootstrap_time_outs:
            extras = {k: v for k, v in extras.items() if k != "time_outs"}
        super().process_env_step(obs, rewards, dones, extras)

    def _symmetry_cfg(self, cfg: dict | None) -> dict | None:
        """rsl_rl's symmetry config from ours (`algo.symmetry_cfg`, with the env rsl_rl put in it): None
        when neither augmentation nor mirror loss is on, else with our augmentation function."""
        cfg = dict(cfg or {})
        env = cfg.pop("env", None)
        if not (cfg.get("use_data_augmentation") or cfg.get("use_mirror_loss")):
            return None
        if not supports_mirror(env):
            raise ValueError(
                f"algorithm.symmetry_cfg needs an env with mirror maps, got {type(env).__name__}"
            )
        return {**cfg, "env": env, "data_augmentation_func": self._mirror_batch}

    def _mirror_batch(self, env, obs=None, actions=None):
        """`mirror_augment`, and for an iteration on the estimates the estimates of the mirrored
        samples: those of the estimators on the mirrored history (a latent has no mirror map).

        PPO's epochs meet the same mini-batches (`RoaRolloutStorage.ppo_pass` gathers each once) and
        change neither the estimators nor the normalizer, so a mini-batch's mirrored estimates are the
        same in every epoch: they are computed in its first and reused, bit for bit (five epochs ran
        the estimators five times over each mirrored mini-batch, most of an update on the estimates)."""
        estimates = None
        if obs is not None and GROUP_DETACHED_ESTIMATES in obs.keys():
            batch_obs = obs
            estimates = obs[GROUP_DETACHED_ESTIMATES]
            obs = obs.exclude(GROUP_DETACHED_ESTIMATES)
        obs, actions = mirror_augment(env, obs, actions)
        if estimates is not None:
            seen = self._mirrored_estimates.get(id(batch_obs))
            if seen is None or seen[0] is not batch_obs:
                mirrored = self.get_policy().detached_estimates(obs[len(estimates) :]).to(estimates.dtype)
                seen = self._mirrored_estimates[id(batch_obs)] = (batch_obs, mirrored)
            obs[GROUP_DETACHED_ESTIMATES] = torch.cat([estimates, seen[1]])
        return obs, actions

    def acts_on_estimates(self, iteration: int) -> bool:
        """Whether iteration `iteration` (its rollout and PPO update) acts on the estimates: from
        `estimate_rollout_start` on, every `estimate_rollout_every`-th (0: never)."""
        every, start = self.estimate_rollout_every, self.estimate_rollout_start
        return every > 0 and iteration >= start and (iteration - start) % every == 0

    def entropy_coef_at(self, iteration: int) -> float:
        """The entropy bonus of iteration `iteration`'s update: `entropy_coef`, falling linearly to 0 at
        iteration `entropy_decay_iterations` and 0 after it (0 decay iterations: constant)."""
        decay = self.entropy_decay_iterations
        if decay == 0:
            return self.initial_entropy_coef
        return self.initial_entropy_coef * max(0.0, 1.0 - iteration / decay)

    @property
    def iteration(self) -> int:
        """The iteration whose rollout and update come next (0-based; `update` completes it)."""
        return self._iteration

    @iteration.setter
    def iteration(self, iteration: int) -> None:
        """Go on at iteration `iteration`: its rollout and update act as the schedule says."""
        self._iteration = int(iteration)
        self.get_policy().act_on_estimates = self.acts_on_estimates(self._iteration)
        self.entropy_coef = self.entropy_coef_at(self._iteration)

    def start_learner(self) -> None:
        """Once, when training starts (the first `act` or `update`, so that loading a policy to play or
        evaluate compiles nothing): check the compiler, compile the networks, print what runs."""
        if self._learner_started:
            return
        self._learner_started = True
        plan = self.learner_precision
        plan.check_compiler(self.device)
        if plan.compile_mlps:
            self._compile_networks()
        if self.gpu_global_rank == 0:  # one line per job
            print(plan.line(), flush=True)

    def _compile_networks(self) -> None:
        """torch.compile in place: the parameters and their state-dict names stay as they are."""
        if not self._compiled:
            for net in (self.actor.mlp, self.critic.mlp, self.actor.encoder.mlp, *self.actor.estimators()):
                net.compile()
            self._compiled = True

    def act(self, obs):
        """rsl_rl's `act`; on the estimates, also keeps the estimates the actor acted on for the update."""
        self.start_learner()
        self.actor.last_detached_estimates = None
        actions = super().act(obs)
        estimates = self.actor.last_detached_estimates
        if estimates is not None and self.storage.step < self.storage.num_transitions_per_env:
            shape = (self.storage.num_transitions_per_env, *estimates.shape)
            if self._rollout_estimates is None or self._rollout_estimates.shape != shape:
                self._rollout_estimates = estimates.new_empty(shape)
            self._rollout_estimates[self.storage.step] = estimates
            self._estimate_steps += 1
        return actions

    def update(self) -> dict[str, float]:
        self.start_learner()
        on_estimates = self.actor.act_on_estimates
        stored = self.storage.observations
        # PPO's mini-batches gather only what the actor and critic read (a view: nothing is copied)
        read = stored.exclude(*self._unread_by_ppo(on_estimates))
        if on_estimates:  # the rollout's own estimates, not new ones per mini-batch and epoch
            read[GROUP_DETACHED_ESTIMATES] = self._estimates_of_rollout(stored)
        self._estimate_steps = 0
        try:
            with self.storage.ppo_pass(read):
                loss_dict = super().update()
        finally:
            self._mirrored_estimates.clear()
        loss_dict.update(self.update_roa())
        loss_dict["Policy/acts_on_estimates"] = float(on_estimates)
        loss_dict["Policy/entropy_coef"] = self.entropy_coef
        self._check_diverged(loss_dict)
        self.iteration += 1
        return loss_dict

    def _check_diverged(self, loss_dict: dict[str, float]) -> None:
        """The divergence guard: FloatingPointError for a non-finite loss, parameter or optimizer state."""
        bad = {k: v for k, v in loss_dict.items() if not math.isfinite(float(v))}
        if bad:
            raise FloatingPointError(
                f"non-finite loss after the update of iteration {self.iteration}: {bad}. "
                "Training diverged; lower algo.learning_rate or check the rewards. The last saved checkpoint "
                "is intact (none is written from a diverged state)."
            )
        check_finite(self.save(), "parameters after the update (training diverged)")

    def _estimates_of_rollout(self, stored) -> torch.Tensor:
        """(T, N, k) estimates for the stored rollout: those its steps acted on, when every step kept
        them; else (a rollout not collected by `act` on the estimates) computed from its observations."""
        if self._estimate_steps == self.storage.num_transitions_per_env:
            return self._rollout_estimates
        flat = self._in_precision(self.actor.detached_estimates, stored.flatten(0, 1))
        return flat.view(*stored.batch_size, -1)

    def _unread_by_ppo(self, on_estimates: bool) -> list[str]:
        """Observation groups PPO's update does not read: the history, unless the actor takes it
        as an input (on the estimates it acts on `GROUP_DETACHED_ESTIMATES` instead)."""
        critic_groups = set(self.critic.obs_groups)
        mirrors_estimates = on_estimates and self.symmetry is not None  # from the mirrored history
        if (
            mirrors_estimates
            or self.actor.reads_history(estimates_cached=on_estimates)
            or GROUP_HISTORY in critic_groups
        ):
            return []
        return [GROUP_HISTORY]

    def _in_precision(self, fn, *args):
        """fn(*args) under the bfloat16 autocast of rsl_rl's PPO update when `use_mixed_precision`."""
        device_type = torch.device(self.device).type
        with torch.amp.autocast(
            device_type=device_type, enabled=self.use_mixed_precision, dtype=torch.bfloat16
        ):
            return fn(*args)

    def update_roa(self) -> dict[str, float]:
        """One ROA pass over the stored rollout; returns the mean losses, and the mean estimation
        errors of its mini-batches, each measured before its own optimizer step."""
        sums: dict[str, torch.Tensor] = {}
        count = 0
        for batch in self.storage.mini_batch_generator(self.num_mini_batches, self.estimator_epochs):
            losses, errors = self._in_precision(self.actor.roa_losses, batch.observations, self.roa_lambda)
            total = sum(losses.values())
            self.optimizer.zero_grad()
            self.estimator_optimizer.zero_grad()
            total.backward()
            # data-parallel: every rank steps the same, averaged gradients (as PPO's pass)
            if self.is_multi_gpu:
                reduce_gradients_in_buckets(
                    self.actor.parameters(), self.gpu_world_size, self.grad_reduce_bucket_mb
                )
            nn.utils.clip_grad_norm_(self._estimator_params, self.max_grad_norm)
            self.estimator_optimizer.step()
            # PPO's optimizer steps only what the λ term reaches: the encoder
            for p in self._estimator_params:
                p.grad = None
            self.optimizer.step()
            logged = {f"roa_{k}": v.detach() for k, v in losses.items()}
            logged.update({f"Estimator/{k}": v for k, v in errors.items()})
            for key, value in logged.items():
                sums[key] = sums.get(key, 0.0) + value.float()
            count += 1
        return {key: float(value) / max(count, 1) for key, value in sums.items()}

    def save(self) -> dict:
        saved = super().save()
        saved["estimator_optimizer_state_dict"] = self.estimator_optimizer.state_dict()
        saved["learner_precision"] = self.learner_precision.record()  # what ran; the config: what was asked
        return saved

    def load(self, loaded_dict: dict, load_cfg: dict | None, strict: bool) -> bool:
        """rsl_rl's `load`, and the estimators' optimizer; with the iteration (rsl_rl's answer), the
        learner continues after the checkpoint's iteration `iter` (the last completed one), and so
        does the estimate schedule."""
        load_iteration = super().load(loaded_dict, load_cfg, strict)
        if (
            load_cfg is None or load_cfg.get("optimizer")
        ) and "estimator_optimizer_state_dict" in loaded_dict:
            self.estimator_optimizer.load_state_dict(loaded_dict["estimator_optimizer_state_dict"])
        for opt in (self.optimizer, self.estimator_optimizer):
            self._keep_own_kernel(opt)
        if load_iteration:
            self.iteration = int(loaded_dict["iter"]) + 1
        return load_iteration

    def _keep_own_kernel(self, opt: torch.optim.Optimizer) -> None:
        """A loaded state dict brings its run's Adam kernel (fused or not, in its param groups) and
        where that kernel keeps its step counts: put back this learner's."""
        for group in opt.param_groups:
            group["fused"], group["foreach"] = (True if self._fused else None), None
            for p in group["params"]:
                state = opt.state.get(p, {})
                if "step" in state:  # fused: a float32 tensor on the parameter's device; else on the CPU
                    where = p.device if self._fused else "cpu"
                    state["step"] = state["step"].to(device=where, dtype=torch.float32)
