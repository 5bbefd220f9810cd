"""The wheel-force transducers and the other sensors: effects of the measurement chain (delay,
DAQ filter, zero offsets), then noise, quantisation and the imperfections of a null session."""

from __future__ import annotations

import numpy as np
from scipy import signal

WHEELS = ("/car/fl", "/car/fr", "/car/rl", "/car/rr")
RATE = 100.0  # slip, load, measured_forces [Hz]
VEL_EVERY = 10  # velocity at 10 Hz
TEMP_EVERY = 10  # temperature at 10 Hz
PRES_EVERY = 50  # pressure at 2 Hz


def draw_noise(rng) -> dict:
    return {
        "Fx_Fy_N": rng.uniform(10.0, 25.0),
        "Fz_N": rng.uniform(15.0, 35.0),
        "M_Nm": rng.uniform(1.0, 3.0),
        "kappa": rng.uniform(1e-4, 3e-4),
        "alpha_rad": rng.uniform(2e-4, 5e-4),
        "gamma_rad": rng.uniform(1e-4, 3e-4),
        "Vx_mps": rng.uniform(0.02, 0.05),
        "T_degC": rng.uniform(0.3, 0.8),
        "T_lag_s": rng.uniform(0.1, 0.4),
        "p_Pa": rng.uniform(300.0, 600.0),
        "quant_force_N": 0.25,
        "quant_moment_Nm": 0.01,
        "quant_T_degC": 0.1,
        "quant_p_Pa": 500.0,
    }


def delay_filter(x, fs, delay_s, fc):
    """x (n, ...) sampled at fs: late by delay_s (linear interpolation), then the DAQ's causal
    2nd-order Butterworth low-pass at fc."""
    n = x.shape[0]
    t = np.arange(n) / fs
    flat = x.reshape(n, -1)
    y = np.empty_like(flat)
    for j in range(flat.shape[1]):
        y[:, j] = np.interp(t - delay_s, t, flat[:, j], left=flat[0, j])
    fc = min(fc, 0.45 * fs)
    sos = signal.butter(2, fc, fs=fs, output="sos")
    zi = signal.sosfilt_zi(sos)
    for j in range(flat.shape[1]):
        y[:, j] = signal.sosfilt(sos, y[:, j], zi=zi * y[0, j])[0]
    return y.reshape(x.shape)


def quant(x, q):
    return np.round(x / q) * q


def gaps(rng, n, count, lo_s=0.05, hi_s=0.5):
    """A boolean keep-mask of n samples at RATE with `count` gaps of lo..hi seconds."""
    keep = np.ones(n, bool)
    spans = []
    for _ in range(count):
        length = int(round(rng.uniform(lo_s, hi_s) * RATE))
        start = int(rng.integers(100, max(101, n - length - 100)))
        keep[start : start + length] = False
        spans.append((start / RATE, (start + length) / RATE))
    return keep, spans


def ou_walk(rng, n, sigma, tau, fs=RATE):
    """A slowly wandering zero: an Ornstein-Uhlenbeck process, stationary sigma, time tau."""
    a = np.exp(-1.0 / (fs * tau))
    e = rng.standard_normal(n) * sigma * np.sqrt(1 - a * a)
    e[0] = rng.standard_normal() * sigma
    return signal.lfilter([1.0], [1.0, -a], e)
