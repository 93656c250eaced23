"""Deployable LAS-MP policy: only input is the proprioceptive window, output the mean action."""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING

import torch
from torch import nn

from lasmp.modules.obs_groups import GYRO_Z_COL, alignment_from_estimates

if TYPE_CHECKING:
    from lasmp.modules.policy import LasmpActor


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

    @torch.jit.export
    def reset(self) -> None:
        """No recurrent state (the window is given whole each step)."""
        pass

    def get_dummy_inputs(self) -> tuple[torch.Tensor]:
        return (torch.zeros(1, self.history_len + 1, self.obs_dim),)

    @property
    def input_names(self) -> list[str]:
        return ["obs_window"]

    @property
    def output_names(self) -> list[str]:
        return ["actions"]
