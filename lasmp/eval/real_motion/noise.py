"""Coloured noise for the real-motion generators: filtered white noise and random-phase synthesis.

PSD convention
    All spectra here are *one-sided*: the variance is the integral over non-negative frequencies.
    :func:`filtered_white_noise` speaks in angular frequency (per rad/s), the convention of the
    Dryden forming filters of MIL-F-8785C; :func:`random_phase_noise` in cyclic frequency (per Hz),
    the convention of ``scipy.signal.welch``. The two are related by ``G(f) = 2 pi Phi(2 pi f)``.

1. White noise through a linear filter (:func:`filtered_white_noise`): continuous white noise of
   unit one-sided PSD per rad/s (``Phi_in(w) = 1`` for ``w >= 0``) drives ``H(s) = num(s) / den(s)``,
   so the output's one-sided PSD is ``Phi_out(w) = |H(i w)|^2`` and its variance
   ``int_0^inf |H(i w)|^2 dw``. On a grid of step dt the input is held over each step (a
   zero-order hold) at a Gaussian level of variance ``pi / dt``: its one-sided PSD per Hz is then
   ``2 (pi / dt) dt = 2 pi`` over [0, 1 / (2 dt)], i.e. 1 per rad/s, the continuous value (the hold
   rolls it off by sinc^2(f dt), 0.3 % at f = 1 / (20 dt)). The filter is discretised for exactly
   that held input (``scipy.signal.cont2discrete``, zero-order hold) and run with
   ``scipy.signal.lfilter``. ``warmup_s`` of output is computed and dropped first, so a record
   starts in the filter's stationary state instead of at rest.

2. Random-phase synthesis (:func:`random_phase_noise`) of a one-sided PSD ``S(f)`` per Hz::

       x(t) = sum_k sqrt(2 S(f_k) df) cos(2 pi f_k t + phi_k),    phi_k ~ U[0, 2 pi)

   on the uniform grid ``f_k = k df`` inside [f_min, f_max] (Shinozuka and Jan (1972),
   "Digital simulation of random processes and its applications", J. Sound Vib. 25(1)). The
   amplitudes are deterministic, so the variance is exactly ``sum_k S(f_k) df`` over a whole
   period 1 / df. With the default ``df = 1 / (n dt)`` the record is one period long; a smaller
   ``df`` (longer period) is allowed. Evaluated with one inverse real FFT.

Both draw from ``np.random.default_rng(seed)``; ``seed`` may also be a ``np.random.Generator``,
which is then used (and advanced) as is, so one generator can feed several independent channels.

:func:`lti_filter` runs a continuous transfer function over a sampled (smooth) signal, and
:func:`smooth_ramp` is the C2 ramp the generators use to fade the noise in from rest.
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


def filtered_white_noise(
    num, den, n_samples: int, dt_s: float, *, seed=None, warmup_s: float = 0.0
) -> np.ndarray:
    """``n_samples`` of ``H(s) = num / den`` driven by unit one-sided-PSD (per rad/s) white noise.

    The output's one-sided PSD is ``|H(i w)|^2`` per rad/s (module docstring, item 1); the first
    ``warmup_s`` seconds are simulated and discarded so the record is stationary from sample 0.
    """
    if n_samples < 1 or dt_s <= 0 or warmup_s < 0:
        raise ValueError(
            "filtered_white_noise: need n_samples >= 1, dt_s > 0, warmup_s >= 0; "
            f"got {n_samples}, {dt_s}, {warmup_s}"
        )
    rng = np.random.default_rng(seed)
    n_warm = int(np.ceil(warmup_s / dt_s))
    # the held level's variance pi / dt gives the held signal a PSD of 1 per rad/s (docstring)
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
    frequency; amplitudes ``sqrt(2 S(f_k) df)``, phases uniform (module docstring, item 2).
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
