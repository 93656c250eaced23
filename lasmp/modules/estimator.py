"""History estimators h_psi: o^H -> estimate (docs/method.md, Networks): per-step MLP, 2-layer temporal CNN, linear head."""

from __future__ import annotations

import torch
from rsl_rl.utils import resolve_nn_activation
from torch import nn


def conv_out_len(length: int, kernel: int, stride: int) -> int:
    """Output length of an unpadded 1D convolution."""
    return (length - kernel) // stride + 1


class HistoryEstimator(nn.Module):
    """o^H (n, H, obs_dim), newest first, already normalized -> (n, out_dim).

    Layers: Linear(obs_dim, mlp_dim)+act applied per time step; Conv1d(mlp_dim, channels, k0, s0)+act;
    Conv1d(channels, channels, k1, s1)+act over time; flatten; Linear(channels * L, out_dim).
    With H = 20, k = (6, 4), s = (2, 2) the time axis shrinks 20 -> 8 -> 3.
    """

    def __init__(
        self,
        obs_dim: int = 44,
        history_len: int = 20,
        out_dim: int = 13,
        mlp_dim: int = 32,
        channels: int = 32,
        kernel_sizes: tuple[int, int] = (6, 4),
        strides: tuple[int, int] = (2, 2),
        activation: str = "elu",
    ) -> None:
        super().__init__()
        if out_dim <= 0:
            raise ValueError(f"out_dim must be positive, got {out_dim}")
        length = history_len
        for k, s in zip(kernel_sizes, strides, strict=True):
            length = conv_out_len(length, k, s)
        if length < 1:
            raise ValueError(
                f"history_len={history_len} too short for kernel_sizes={kernel_sizes}, strides={strides}"
            )
        self.obs_dim = obs_dim
        self.history_len = history_len
        self.out_dim = out_dim
        self.step_mlp = nn.Sequential(nn.Linear(obs_dim, mlp_dim), resolve_nn_activation(activation))
        self.cnn = nn.Sequential(
            nn.Conv1d(mlp_dim, channels, kernel_sizes[0], strides[0]),
            resolve_nn_activation(activation),
            nn.Conv1d(channels, channels, kernel_sizes[1], strides[1]),
            resolve_nn_activation(activation),
        )
        self.head = nn.Linear(channels * length, out_dim)

    def forward(self, history: torch.Tensor) -> torch.Tensor:
        """(n, H, obs_dim) -> (n, out_dim)."""
        z = self.step_mlp(history)  # (n, H, mlp_dim)
        # (n, channels, L). Contiguous first: oneDNN convolves the transposed view more slowly, to the same
        # values bit for bit (docs/performance.md, "Measured and not kept")
        z = self.cnn(z.transpose(1, 2).contiguous())
        return self.head(z.flatten(1))
