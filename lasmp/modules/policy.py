"""The composed LAS-MP policy: backbone + implicit encoder + history estimators
(docs/method.md#networks-lasmpmodules), and its deployable form (`LasmpDeployPolicy`: the
proprioceptive window in, the mean action out).

Usable as rsl_rl's actor: ``{"class_name": "lasmp.modules.policy:LasmpActor", ...}``.
"""

from __future__ import annotations

import copy

import torch
from tensordict import TensorDict
from torch import nn

from lasmp.compat.rsl_rl import MLPModelCompat
from lasmp.modules.encoder import ImplicitEncoder
from lasmp.modules.estimator import HistoryEstimator
from lasmp.modules.obs_groups import (
    GROUP_ALIGNMENT,
    GROUP_COMMAND,
    GROUP_DETACHED_ESTIMATES,
    GROUP_EXPLICIT,
    GROUP_HISTORY,
    GROUP_IMPLICIT,
    GROUP_OBS,
    GYRO_Z_COL,
    U_ALN_NAMES,
    X_EXP_NAMES,
    alignment_from_estimates,
    explicit_indices,
)


class LasmpActor(MLPModelCompat):
    """LAS-MP actor: b_theta([o, x_exp, u_aln]_normalized, l_imp[, o^H normalized, flattened]) -> action mean.

    Training mode (``deploy=False``) uses the true privileged groups: x_exp = `priv_explicit`,
    l_imp = encoder(`priv_implicit`), u_aln = `alignment`. Deployment mode (``deploy=True``) uses only
    `policy` and `history`: x_exp_hat and l_imp_hat from the history estimators, and u_aln_hat built
    from x_exp_hat (raw units) with the measured yaw rate o[:, 5].

    Normalization: one EmpiricalNormalization (the model's) over [o, x_exp(selected), u_aln]; the
    history is normalized per time step with the o-part of the same statistics. The encoder owns
    its own x_imp normalizer. Estimators predict raw (unnormalized) x_exp.
    """

    def __init__(
        self,
        obs: TensorDict,
        obs_groups: dict[str, list[str]],
        obs_set: str,
        output_dim: int,
        hidden_dims: tuple[int, ...] | list[int] = (512, 256, 128),
        activation: str = "elu",
        obs_normalization: bool = True,
        distribution_cfg: dict | None = None,
        latent_dim: int = 16,
        encoder_hidden_dims: tuple[int, ...] | list[int] = (64,),
        estimator_mlp_dim: int = 32,
        estimator_channels: int = 32,
        use_alignment: bool = True,
        explicit: str = "all",
        history_input: bool = False,
        command_input: bool = False,
    ) -> None:
        sel = explicit_indices(explicit)
        # whatever built it (rsl_rl's dict, a test), the actor cannot rebuild u_aln_hat without the
        # platform velocity estimates; a training config says so first (PolicyCfg.check_rules)
        if use_alignment and explicit != "all":
            raise ValueError(
                f"use_alignment=True needs explicit='all': the alignment command is rebuilt from the platform "
                f"velocity estimates, which explicit={explicit!r} does not provide (set use_alignment=False)"
            )
        # read by select_obs/backbone_input_size during MLPModel.__init__
        self.explicit = explicit
        self.num_explicit = len(sel)  # selections are prefixes of x_exp
        self.use_alignment = bool(use_alignment)
        self.num_alignment = 3 if use_alignment else 0
        self.latent_dim = latent_dim
        self.history_input = bool(history_input)
        # an external velocity command (group `command`, 3), read in both modes: the R-S baseline
        self.command_input = bool(command_input)
        self.num_command = 3 if command_input else 0
        super().__init__(
            obs, obs_groups, obs_set, output_dim, hidden_dims, activation, obs_normalization, distribution_cfg
        )
        self.deploy: bool = False
        # training on the estimates: the estimated inputs, detached so that PPO's gradients never
        # reach the estimators; set for each iteration by the learner (PPOROA's estimate schedule)
        self.act_on_estimates: bool = False
        # the estimates of the last forward pass on them (`get_latent`, outside PPO's update), detached
        self.last_detached_estimates: torch.Tensor | None = None
        self.encoder = ImplicitEncoder(self.num_implicit, latent_dim, encoder_hidden_dims, activation)
        est_kw = dict(
            obs_dim=self.num_obs,
            history_len=self.history_len,
            mlp_dim=estimator_mlp_dim,
            channels=estimator_channels,
            activation=activation,
        )
        self.explicit_estimator: HistoryEstimator | None = (
            HistoryEstimator(out_dim=self.num_explicit, **est_kw) if self.num_explicit > 0 else None
        )
        self.implicit_estimator = HistoryEstimator(out_dim=latent_dim, **est_kw)

    # ----------------------------------------------------------------- dims (MLPModel's input hooks)
    def select_obs(
        self, obs: TensorDict, obs_groups: dict[str, list[str]], obs_set: str
    ) -> tuple[list[str], int]:
        """Check the groups and return the size of the normalized part [o, x_exp(selected), u_aln]."""
        active = list(obs_groups[obs_set])
        needed = [GROUP_OBS, GROUP_HISTORY, GROUP_IMPLICIT]
        needed += [GROUP_EXPLICIT] if self.num_explicit else []
        needed += [GROUP_ALIGNMENT] if self.use_alignment else []
        needed += [GROUP_COMMAND] if self.command_input else []
        missing = [g for g in needed if g not in active]
        if missing:
            raise ValueError(f"obs_groups[{obs_set!r}] lacks {missing} needed by LasmpActor")
        o, hist = obs[GROUP_OBS], obs[GROUP_HISTORY]
        if o.dim() != 2 or hist.dim() != 3 or hist.shape[-1] != o.shape[-1]:
            raise ValueError(
                f"expected policy (n, D) and history (n, H, D), got {tuple(o.shape)}, {tuple(hist.shape)}"
            )
        if self.num_explicit and obs[GROUP_EXPLICIT].shape[-1] != len(X_EXP_NAMES):
            raise ValueError(
                f"priv_explicit must have {len(X_EXP_NAMES)} dims, got {obs[GROUP_EXPLICIT].shape[-1]}"
            )
        self.num_obs = o.shape[-1]
        self.history_len = hist.shape[1]
        self.num_implicit = obs[GROUP_IMPLICIT].shape[-1]
        return active, self.num_obs + self.num_explicit + self.num_alignment + self.num_command

    def backbone_input_size(self) -> int:
        """Backbone input size: normalized [o, x_exp, u_aln] + l_imp (+ flattened history)."""
        hist = self.history_len * self.num_obs if self.history_input else 0
        self.backbone_input_dim = self.obs_dim + self.latent_dim + hist
        return self.backbone_input_dim

    # ----------------------------------------------------------------- inputs
    def history_norm_params(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(mean, scale), each (1, D): the o-part of the model normalizer, for per-step history normalization."""
        if self.obs_normalization:
            norm = self.obs_normalizer
            return norm.mean[None, : self.num_obs], norm.std[None, : self.num_obs] + norm.eps
        ref = self.mlp[0].weight
        return ref.new_zeros(1, self.num_obs), ref.new_ones(1, self.num_obs)

    def normalize_history(self, history: torch.Tensor) -> torch.Tensor:
        """(n, H, D) raw history -> normalized with the o statistics, per time step."""
        mean, scale = self.history_norm_params()
        return (history - mean) / scale

    def _privileged_inputs(self, obs: TensorDict) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
        """True (x_exp selected, l_imp = encoder(x_imp), u_aln) in raw units."""
        x_exp = obs[GROUP_EXPLICIT][:, : self.num_explicit] if self.num_explicit else obs[GROUP_OBS][:, :0]
        l_imp = self.encoder(obs[GROUP_IMPLICIT])
        u_aln = obs[GROUP_ALIGNMENT] if self.use_alignment else None
        return x_exp, l_imp, u_aln

    def _estimated_inputs(
        self, o: torch.Tensor, history_n: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
        """Estimated (x_exp_hat, l_imp_hat, u_aln_hat) from the normalized history; raw units."""
        x_hat = self.explicit_estimator(history_n) if self.explicit_estimator is not None else o[:, :0]
        l_hat = self.implicit_estimator(history_n)
        u_hat = alignment_from_estimates(x_hat, o[:, GYRO_Z_COL]) if self.use_alignment else None
        return x_hat, l_hat, u_hat

    def _normalized_part(
        self, o: torch.Tensor, x_exp: torch.Tensor, u_aln: torch.Tensor | None, obs: TensorDict
    ) -> torch.Tensor:
        parts = [o, x_exp] + ([u_aln] if u_aln is not None else [])
        if self.command_input:
            parts.append(obs[GROUP_COMMAND])
        return torch.cat(parts, dim=-1)

    def get_latent(
        self, obs: TensorDict, masks: torch.Tensor | None = None, hidden_state=None
    ) -> torch.Tensor:
        """Backbone input [norm(o, x_exp, u_aln), l_imp(, norm(o^H) flattened)], per `self.deploy`
        (or `self.act_on_estimates`: the estimates, detached)."""
        o = obs[GROUP_OBS]
        cached = not self.deploy and self.act_on_estimates and GROUP_DETACHED_ESTIMATES in obs.keys()
        history_n = self.normalize_history(obs[GROUP_HISTORY]) if self.reads_history(cached) else None
        if self.deploy:
            x_exp, l_imp, u_aln = self._estimated_inputs(o, history_n)
        elif cached:
            x_exp, l_imp, u_aln = self.split_detached_estimates(obs[GROUP_DETACHED_ESTIMATES])
        elif self.act_on_estimates:
            with torch.no_grad():  # detached: PPO's gradients never reach the estimators
                x_exp, l_imp, u_aln = self._estimated_inputs(o, history_n)
                # kept for the rollout's PPO update (PPOROA.act), which then acts on exactly these
                self.last_detached_estimates = self._joined(x_exp, l_imp, u_aln)
        else:
            x_exp, l_imp, u_aln = self._privileged_inputs(obs)
        parts = [self.obs_normalizer(self._normalized_part(o, x_exp, u_aln, obs)), l_imp]
        if self.history_input:
            parts.append(history_n.flatten(1))
        return torch.cat(parts, dim=-1)

    def reads_history(self, estimates_cached: bool) -> bool:
        """Whether `get_latent` reads the history group in the current mode; `estimates_cached`:
        the observations carry `GROUP_DETACHED_ESTIMATES`."""
        on_estimates = self.act_on_estimates and not estimates_cached
        return self.deploy or on_estimates or self.history_input

    @torch.no_grad()
    def detached_estimates(self, obs: TensorDict) -> torch.Tensor:
        """[x_exp_hat, l_imp_hat(, u_aln_hat)] in one (..., k) tensor, for `GROUP_DETACHED_ESTIMATES`.

        PPO's epochs change neither the estimators nor the normalizer, so an iteration on the
        estimates needs them once for its whole rollout, not once per mini-batch and epoch: PPOROA
        uses those its rollout kept (`last_detached_estimates`), and this for a rollout that kept none.
        """
        o = obs[GROUP_OBS]
        return self._joined(*self._estimated_inputs(o, self.normalize_history(obs[GROUP_HISTORY])))

    @staticmethod
    def _joined(x_hat: torch.Tensor, l_hat: torch.Tensor, u_hat: torch.Tensor | None) -> torch.Tensor:
        """[x_exp_hat, l_imp_hat(, u_aln_hat)] as one (..., k) tensor (`split_detached_estimates` inverts it)."""
        return torch.cat([x_hat, l_hat] + ([u_hat] if u_hat is not None else []), dim=-1)

    def split_detached_estimates(
        self, estimates: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
        """The inverse of `detached_estimates`' concatenation."""
        x_hat, l_hat, u_hat = estimates.split(
            [self.num_explicit, self.latent_dim, self.num_alignment], dim=-1
        )
        return x_hat, l_hat, (u_hat if self.use_alignment else None)

    def update_normalization(self, obs: TensorDict) -> None:
        """Update the model normalizer with the true [o, x_exp, u_aln] and the encoder's with x_imp."""
        if self.obs_normalization:
            x_exp = (
                obs[GROUP_EXPLICIT][:, : self.num_explicit] if self.num_explicit else obs[GROUP_OBS][:, :0]
            )
            u_aln = obs[GROUP_ALIGNMENT] if self.use_alignment else None
            self.obs_normalizer.update(self._normalized_part(obs[GROUP_OBS], x_exp, u_aln, obs))
        self.encoder.update_normalization(obs[GROUP_IMPLICIT])

    # ----------------------------------------------------------------- ROA
    def estimators(self) -> list[HistoryEstimator]:
        """The history estimators (psi): the implicit one, and the explicit one if any."""
        return [self.implicit_estimator] + (
            [self.explicit_estimator] if self.explicit_estimator is not None else []
        )

    def estimator_parameters(self) -> list[nn.Parameter]:
        """Parameters of both history estimators (psi)."""
        return [p for est in self.estimators() for p in est.parameters()]

    def encoder_parameters(self) -> list[nn.Parameter]:
        """Parameters of the implicit encoder h_theta."""
        return list(self.encoder.parameters())

    def roa_losses(
        self, obs: TensorDict, lam: float
    ) -> tuple[dict[str, torch.Tensor], dict[str, torch.Tensor]]:
        """ROA losses, each squared error summed over dims and averaged over the batch
        (docs/method.md#learning-ppo-with-regularized-online-adaptation-lasmpalgo).

        - `exp`     = ||x_exp_hat - x_exp||^2 (raw units; grads only to the explicit estimator; 0 if none)
        - `imp_est` = ||l_imp_hat - sg[l_imp]||^2 (grads only to the implicit estimator)
        - `imp_reg` = lam * ||sg[l_imp_hat] - l_imp||^2 (grads only to the encoder)

        Also returns the batch's estimation errors (detached; see `_errors`) from the same forward
        pass, so that logging them costs no second pass over the rollout.
        """
        o = obs[GROUP_OBS]
        x_hat, l_hat, u_hat = self._estimated_inputs(o, self.normalize_history(obs[GROUP_HISTORY]))
        if self.explicit_estimator is not None:
            exp = (x_hat - obs[GROUP_EXPLICIT][:, : self.num_explicit]).square().sum(-1).mean()
        else:
            exp = o.new_zeros(())
        l_imp = self.encoder(obs[GROUP_IMPLICIT])
        imp_est = (l_hat - l_imp.detach()).square().sum(-1).mean()
        imp_reg = lam * (l_hat.detach() - l_imp).square().sum(-1).mean()
        with torch.no_grad():
            errors = self._errors(obs, x_hat, l_hat, u_hat, l_imp)
        return {"exp": exp, "imp_est": imp_est, "imp_reg": imp_reg}, errors

    @property
    def estimation_names(self) -> tuple[str, ...]:
        """Names of the x_exp dims the explicit estimator predicts."""
        return tuple(X_EXP_NAMES[: self.num_explicit])

    @torch.no_grad()
    def estimates(self, obs: TensorDict) -> tuple[torch.Tensor, torch.Tensor]:
        """(x_exp_hat (n, selected dims), l_imp_hat (n, latent)) from the history alone, raw units."""
        x_hat, l_hat, _ = self._estimated_inputs(obs[GROUP_OBS], self.normalize_history(obs[GROUP_HISTORY]))
        return x_hat, l_hat

    def _errors(
        self,
        obs: TensorDict,
        x_hat: torch.Tensor,
        l_hat: torch.Tensor,
        u_hat: torch.Tensor | None,
        l_imp: torch.Tensor,
    ) -> dict[str, torch.Tensor]:
        """Batch means of the estimation errors as 0-d tensors: |x_exp_hat - x_exp| per named dim (and
        per u_aln dim), and ||l_imp_hat - l_imp||_2 as `l_imp_l2`."""
        out: dict[str, torch.Tensor] = {}
        if self.num_explicit:
            err = (x_hat - obs[GROUP_EXPLICIT][:, : self.num_explicit]).abs().mean(0)
            out.update(zip(X_EXP_NAMES[: self.num_explicit], err.unbind(), strict=True))
        if u_hat is not None:
            out.update(zip(U_ALN_NAMES, (u_hat - obs[GROUP_ALIGNMENT]).abs().mean(0).unbind(), strict=True))
        out["l_imp_l2"] = (l_hat - l_imp).norm(dim=-1).mean()
        return out

    # ----------------------------------------------------------------- export
    def as_jit(self) -> nn.Module:
        """Refused: the export is ONNX (`as_onnx`, play.py --export onnx); rsl_rl's inherited
        TorchScript copy would hold the backbone without the estimators."""
        raise NotImplementedError(
            "a LAS-MP policy exports to ONNX only: play.py --export onnx (docs/deploy.md)"
        )

    def as_onnx(self, verbose: bool) -> nn.Module:
        """Deployment-mode policy over the proprioceptive window only (ONNX-exportable)."""
        self._check_exportable()
        return LasmpDeployPolicy(self, verbose)

    def _check_exportable(self) -> None:
        if self.command_input:
            raise ValueError(
                "export takes only the proprioceptive window; a command-conditioned policy "
                "(command_input=True, the R-S baseline) needs a command input and is not exported"
            )


class LasmpDeployPolicy(nn.Module):
    """obs_window (n, H+1, D) = [o_t, o_{t-1}, ..., o_{t-H}] -> actions (n, A), deployment mode, deterministic.

    Holds deep copies of the normalizer, backbone, estimators and the distribution's mean extractor;
    the history normalization (o-part of the normalizer) is frozen at export time.
    """

    is_recurrent: bool = False

    def __init__(self, actor: LasmpActor, verbose: bool = False) -> None:
        super().__init__()
        self.verbose = verbose
        self.obs_dim = actor.num_obs
        self.history_len = actor.history_len
        self.use_alignment = actor.use_alignment
        self.gyro_z_col = GYRO_Z_COL
        self.history_input = actor.history_input
        mean, scale = actor.history_norm_params()
        self.register_buffer("hist_mean", mean.detach().clone())
        self.register_buffer("hist_scale", scale.detach().clone())
        self.obs_normalizer = copy.deepcopy(actor.obs_normalizer)
        self.mlp = copy.deepcopy(actor.mlp)
        self.explicit_estimator = copy.deepcopy(actor.explicit_estimator)
        self.implicit_estimator = copy.deepcopy(actor.implicit_estimator)
        if actor.distribution is not None:
            self.deterministic_output = actor.distribution.as_deterministic_output_module()
        else:
            self.deterministic_output = nn.Identity()

    def forward(self, obs_window: torch.Tensor) -> torch.Tensor:
        o = obs_window[:, 0]
        history_n = (obs_window[:, 1:] - self.hist_mean) / self.hist_scale
        l_imp = self.implicit_estimator(history_n)
        parts = [o]
        if self.explicit_estimator is not None:
            x_hat = self.explicit_estimator(history_n)
            parts.append(x_hat)
            if self.use_alignment:
                parts.append(alignment_from_estimates(x_hat, o[:, self.gyro_z_col]))
        latent = [self.obs_normalizer(torch.cat(parts, dim=-1)), l_imp]
        if self.history_input:
            latent.append(history_n.flatten(1))
        return self.deterministic_output(self.mlp(torch.cat(latent, dim=-1)))

    def get_dummy_inputs(self) -> tuple[torch.Tensor]:
        return (torch.zeros(1, self.history_len + 1, self.obs_dim),)

    @property
    def input_names(self) -> list[str]:
        return ["obs_window"]

    @property
    def output_names(self) -> list[str]:
        return ["actions"]
