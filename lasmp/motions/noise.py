"""Coloured noise and linear filters for the motion models.

:func:`filtered_white_noise` (white noise through a transfer function; PSDs per rad/s, as the
Dryden filters are written) and :func:`random_phase_noise` (a sum of random-phase cosines with a
given PSD per Hz, by one inverse FFT); :func:`sum_of_cosines` for frequency sets off a uniform grid;
:func:`lti_filter` and :func:`second_order_tf` for the vehicles' body modes; :func:`smooth_ramp`
to fade motion in from rest. All spectra are one-sided. Why the white noise is held at variance
pi / dt, and the random-phase method's exact variance: docs/real_motion.md, "Noise".

``seed`` may be an int or a ``np.random.Generator`` (used and advanced as is, so one generator can
feed several independent channels).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import signal


def lti_filter(num, den, u: np.ndarray, dt_s: float, method: str = "bilinear") -> np.ndarray:
    """``H(s) = num(s) / den(s)`` (coefficients in descending powers of s) applied to samples ``u``.

    Zero initial state. ``method`` is that of ``scipy.signal.cont2discrete``: "bilinear" (Tustin,
    the trapezoidal rule: second-order accurate for smooth inputs), "zoh" (exact for an input
    held constant over each step, as white noise is in :func:`filtered_white_noise`) or "foh"
    (exact for an input linear between samples).
    """
    if dt_s <= 0:
        raise ValueError(f"lti_filter: dt_s must be positive, got {dt_s}")
    num_d, den_d, _ = signal.cont2discrete((np.atleast_1d(num), np.atleast_1d(den)), dt_s, method=method)
    return signal.lfilter(np.ravel(num_d), np.ravel(den_d), np.asarray(u, dtype=np.float64))


def second_order_tf(omega_n_rad_s: float, zeta: float, *, base_excited: bool) -> tuple[list, list]:
    """(num, den) of a second-order mode: ``w^2 / (s^2 + 2 zeta w s + w^2)`` (a low-pass body mode,
    or a hull driven through its static response), or with ``base_excited`` the sprung mass on a
    spring and damper over a moving base, ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)``."""
    w = float(omega_n_rad_s)
    num = [2.0 * zeta * w, w * w] if base_excited else [w * w]
    return num, [1.0, 2.0 * zeta * w, w * w]


def sum_of_cosines(x: np.ndarray, omega: np.ndarray, complex_amp: np.ndarray) -> np.ndarray:
    """``Re(sum_i A_i exp(i omega_i x))`` at x (K,) for amplitudes (N,) or (N, D): (K,) or (K, D).

    A sum of cosines ``|A_i| cos(omega_i x + arg A_i)`` for any frequency set (a jittered or
    log-spaced grid, where an FFT does not apply), evaluated in chunks of x to bound the memory.
    """
    x = np.asarray(x, dtype=np.float64).reshape(-1)
    amp = np.asarray(complex_amp)
    cols = amp.reshape(len(omega), -1)
    out = np.empty((len(x), cols.shape[1]))
    chunk = max(1, 2_000_000 // max(1, len(omega)))  # ~32 MB of complex exponentials at a time
    for i in range(0, len(x), chunk):
        out[i : i + chunk] = (np.exp(1j * np.outer(x[i : i + chunk], omega)) @ cols).real
    return out if amp.ndim > 1 else out[:, 0]


def filtered_white_noise(
    num, den, n_samples: int, dt_s: float, *, seed=None, warmup_s: float = 0.0
) -> np.ndarray:
    """``n_samples`` of ``H(s) = num / den`` driven by unit one-sided-PSD (per rad/s) white noise.

    The output's one-sided PSD is ``|H(i w)|^2`` per rad/s (docs/real_motion.md, "Noise"); the first
    ``warmup_s`` seconds are simulated and discarded so the record is stationary from sample 0.
    """
    if n_samples < 1 or dt_s <= 0 or warmup_s < 0:
        raise ValueError(
            "filtered_white_noise: need n_samples >= 1, dt_s > 0, warmup_s >= 0; "
            f"got {n_samples}, {dt_s}, {warmup_s}"
        )
    rng = np.random.default_rng(seed)
    n_warm = int(np.ceil(warmup_s / dt_s))
    # a level of variance pi / dt held over each step has a one-sided PSD of 1 per rad/s
    u = rng.standard_normal(n_warm + n_samples) * np.sqrt(np.pi / dt_s)
    return lti_filter(num, den, u, dt_s, method="zoh")[n_warm:]


def random_phase_noise(
    psd_per_hz: Callable[[np.ndarray], np.ndarray],
    n_samples: int,
    dt_s: float,
    *,
    f_min_hz: float,
    f_max_hz: float,
    seed=None,
    df_hz: float | None = None,
) -> np.ndarray:
    """``n_samples`` at step ``dt_s`` of a sum of cosines with the one-sided PSD ``psd_per_hz(f)``.

    Components on ``f_k = k df`` with ``f_min_hz <= f_k <= f_max_hz`` and below the Nyquist
    frequency; amplitudes ``sqrt(2 S(f_k) df)``, phases uniform (Shinozuka and Jan 1972; docs/real_motion.md).
    ``df_hz`` defaults to ``1 / (n_samples dt_s)`` (the record is one period) and must divide
    ``1 / dt_s`` into at least ``n_samples`` steps.
    """
    if n_samples < 1 or dt_s <= 0 or not 0 <= f_min_hz < f_max_hz:
        raise ValueError(
            "random_phase_noise: need n_samples >= 1, dt_s > 0 and 0 <= f_min_hz < f_max_hz; "
            f"got {n_samples}, {dt_s}, {f_min_hz}, {f_max_hz}"
        )
    n_fft = n_samples if df_hz is None else int(round(1.0 / (df_hz * dt_s)))
    if n_fft < n_samples:
        raise ValueError(f"random_phase_noise: df_hz = {df_hz} gives a period shorter than the record")
    df = 1.0 / (n_fft * dt_s)
    k = np.arange(int(np.ceil(f_min_hz / df)), int(np.floor(f_max_hz / df)) + 1)
    k = k[(k > 0) & (2 * k < n_fft)]  # no DC, strictly below Nyquist (those bins are real-only)
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0.0, 2.0 * np.pi, len(k))
    amp = np.sqrt(2.0 * np.asarray(psd_per_hz(k * df), dtype=np.float64) * df)
    spec = np.zeros(n_fft // 2 + 1, dtype=np.complex128)
    # irfft(X)[n] = sum_k (2 / N) Re(X_k e^{2 pi i k n / N}) over 0 < k < N / 2,
    # hence X_k = N a_k e^{i phi} / 2
    spec[k] = 0.5 * n_fft * amp * np.exp(1j * phase)
    return np.fft.irfft(spec, n=n_fft)[:n_samples]


def smooth_ramp(t_s: np.ndarray, ramp_s: float) -> np.ndarray:
    """0 at t <= 0, 1 at t >= ramp_s, the quintic smoothstep between (C2: flat and straight at both ends)."""
    if ramp_s <= 0:
        raise ValueError(f"smooth_ramp: ramp_s must be positive, got {ramp_s}")
    x = np.clip(np.asarray(t_s, dtype=np.float64) / ramp_s, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)
