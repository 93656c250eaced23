"""The platform references of the running envs as torch tensors on the env's device, evaluated
there every policy step (no host round trip).

A `PiecewisePoly` on the host stays the source (files, statistics, plots); `DevicePoly` mirrors
the part the step needs, its breaks and coefficients, and takes new rows at reset.
"""

from __future__ import annotations

import torch

from lasmp.envs.trajectories.splines import PiecewisePoly


class DevicePoly:
    def __init__(self, poly: PiecewisePoly, device: torch.device | str, dtype: torch.dtype):
        self.device, self.dtype = torch.device(device), dtype
        self.breaks_s = self._t(poly.breaks_s)  # (M, S+1), +inf padded
        self.n_segments = torch.as_tensor(poly.n_segments, device=self.device)  # (M,)
        self.coeffs = self._t(poly.coeffs)  # (M, S, D+1, 6), zero padded
        self._gathered: torch.Tensor | None = None  # the step's coefficients, reused

    def state_dict(self) -> dict:
        return {"breaks_s": self.breaks_s, "n_segments": self.n_segments, "coeffs": self.coeffs}

    def load_state_dict(self, d: dict) -> None:
        """Take saved rows (a checkpoint's), on this mirror's device and dtype."""
        self.breaks_s, self.coeffs = self._t(d["breaks_s"]), self._t(d["coeffs"])
        self.n_segments = torch.as_tensor(d["n_segments"], device=self.device)
        self._gathered = None

    def _t(self, x) -> torch.Tensor:
        return torch.as_tensor(x, dtype=self.dtype, device=self.device)

    def replace_rows(self, rows: torch.Tensor, new: PiecewisePoly) -> None:
        """Rows `rows` take `new`'s rows (in order); the segment and degree axes grow as needed."""
        s_new, d_new = new.coeffs.shape[1], new.coeffs.shape[2]
        m, s_old, d_old = self.coeffs.shape[:3]
        s, d = max(s_old, s_new), max(d_old, d_new)
        if (s, d) != (s_old, d_old):  # pad: +inf breaks and zero coefficients change no value
            breaks = torch.full((m, s + 1), torch.inf, dtype=self.dtype, device=self.device)
            breaks[:, : s_old + 1] = self.breaks_s
            coeffs = torch.zeros((m, s, d, 6), dtype=self.dtype, device=self.device)
            coeffs[:, :s_old, :d_old] = self.coeffs
            self.breaks_s, self.coeffs = breaks, coeffs
        self.breaks_s[rows] = torch.inf
        self.breaks_s[rows, : s_new + 1] = self._t(new.breaks_s)
        self.coeffs[rows] = 0.0
        self.coeffs[rows, :s_new, :d_new] = self._t(new.coeffs)
        self.n_segments[rows] = torch.as_tensor(new.n_segments, device=self.device)

    def evaluate(
        self, t_s: torch.Tensor, rows: torch.Tensor, velocity: bool = True
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Pose and velocity (k, 6) each of rows `rows` (k,) at times `t_s` (k,); at and after a row's
        end, its final pose with zero velocity (`PiecewisePoly.evaluate` on the device, without the
        acceleration, which the step does not use). With velocity=False, (pose, None)."""
        ns = self.n_segments.index_select(0, rows)
        b = self.breaks_s.index_select(0, rows)  # (k, S+1)
        t_end = b.gather(1, ns[:, None])[:, 0]
        past = t_s >= t_end
        tc = torch.minimum(torch.clamp(t_s, min=0.0), t_end)
        seg = torch.minimum((b[:, 1:] <= tc[:, None]).sum(dim=1), ns - 1)
        tau = (tc - b.gather(1, seg[:, None])[:, 0])[:, None]
        m, s, d1 = self.coeffs.shape[:3]
        # (k, D+1, 6): rows of the flattened (row, segment) axis; index_select copies whole rows, far
        # faster on a CPU than indexing with two tensors, into a kept buffer (a fresh MB-sized one per
        # step would be page-faulted in anew each time)
        if self._gathered is None or self._gathered.shape != (len(rows), d1, 6):
            self._gathered = torch.empty((len(rows), d1, 6), dtype=self.dtype, device=self.device)
        c = torch.index_select(self.coeffs.view(m * s, d1, 6), 0, rows * s + seg, out=self._gathered)
        # Horner with the derivative: pos = sum c_j tau^j, vel = its derivative (in place, the same
        # arithmetic as vel = vel * tau + pos; pos = pos * tau + c_j)
        pos = c[:, -1].clone()
        vel = torch.zeros_like(pos) if velocity else None
        for j in range(d1 - 2, -1, -1):
            if velocity:
                vel.mul_(tau).add_(pos)
            pos.mul_(tau).add_(c[:, j])
        return pos, vel.masked_fill_(past[:, None], 0.0) if velocity else None
