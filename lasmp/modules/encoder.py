"""Implicit encoder h_theta: x_imp -> l_imp (docs/method.md, Networks)."""

from __future__ import annotations

import torch
from rsl_rl.modules import MLP, EmpiricalNormalization
from torch import nn


class ImplicitEncoder(nn.Module):
    """2-layer MLP over the implicit privileged state x_imp (trunk mass kg, CoM shift m, friction,
    Kp N·m/rad, Kd N·m·s/rad), input normalized by its own running statistics because the scales
    are mixed.
    """

    def __init__(
        self,
        input_dim: int = 29,
        latent_dim: int = 16,
        hidden_dims: tuple[int, ...] | list[int] = (64,),
        activation: str = "elu",
    ) -> None:
        super().__init__()
        self.input_dim = input_dim
        self.latent_dim = latent_dim
        self.normalizer = EmpiricalNormalization(input_dim)
        self.mlp = MLP(input_dim, latent_dim, tuple(hidden_dims), activation)

    def forward(self, x_imp: torch.Tensor) -> torch.Tensor:
        """(n, input_dim) raw x_imp -> (n, latent_dim) l_imp."""
        return self.mlp(self.normalizer(x_imp))

    def update_normalization(self, x_imp: torch.Tensor) -> None:
        """Update the running x_imp statistics (no-op in eval mode, as EmpiricalNormalization)."""
        self.normalizer.update(x_imp)
