"""The hidden states the diagnosis fits: one thermal node, first-order slip lag, wear work.

Each is a first-order system driven by recorded or derived channels, integrated exactly for a
piecewise-constant input over each sample step (so uneven time stamps and pauses are handled).
These forms are the diagnosis' own; they are deliberately simpler than any rig's physics
(one node, no grip window): the diagnosis must find an effect with the model it can defend.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


def frictional_power_W(Fx_N, Fy_N, V_mps, kappa, alpha_rad) -> np.ndarray:
    """Frictional power P_fric ~ |Fx V kappa| + |Fy V tan(alpha)| [W] (PHYSICS.md notation).

    Computed from *measured* forces so that the driver of a hidden state does not depend on the
    model being fitted. Missing force channels count as zero.
    """
    V = np.abs(np.asarray(V_mps, dtype=np.float64))
    P = np.zeros_like(V)
    if Fx_N is not None:
        P += np.abs(Fx_N * V * kappa)
    if Fy_N is not None:
        P += np.abs(Fy_N * V * np.tan(alpha_rad))
    return P


def cumulative_work_J(P_W: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """E_f(t) = integral of P_fric dt [J] (left rectangle rule, E_f(t0) = 0)."""
    dt = np.diff(t_s, prepend=t_s[:1])
    return np.cumsum(P_W * np.clip(dt, 0.0, None))


@njit(cache=True)
def _first_order(u, t, tau, y0):
    """y' = (u - y)/tau, exact step response for u held over each step; tau <= 0: y = u."""
    n = u.shape[0]
    y = np.empty(n)
    if n == 0:
        return y
    if tau <= 0.0:
        for i in range(n):
            y[i] = u[i]
        return y
    y[0] = y0
    for i in range(1, n):
        dt = t[i] - t[i - 1]
        if dt < 0.0:
            dt = 0.0
        a = math.exp(-dt / tau)
        y[i] = a * y[i - 1] + (1.0 - a) * u[i - 1]
    return y


def thermal_state_K(
    P_W: np.ndarray, t_s: np.ndarray, tau_s: float, gain_K_per_W: float
) -> np.ndarray:
    """Temperature rise of one lumped thermal node above ambient [K].

    dT/dt = (k P_fric - (T - T_amb)) / tau, T(t0) = T_amb: steady state k P, time constant tau.
    """
    u = np.ascontiguousarray(gain_K_per_W * np.asarray(P_W, dtype=np.float64))
    return _first_order(u, np.ascontiguousarray(t_s, dtype=np.float64), float(tau_s), 0.0)


@njit(cache=True)
def _distance_lag(x, t, V, sigma):
    """sigma dx'/ds + x' = x with ds = |V| dt (exact per step for x held over the step)."""
    n = x.shape[0]
    y = np.empty(n)
    if n == 0:
        return y
    y[0] = x[0]
    for i in range(1, n):
        dt = t[i] - t[i - 1]
        if dt < 0.0:
            dt = 0.0
        v = abs(V[i - 1])
        if v < 0.5:  # relaxation model is undefined at standstill; keep it finite
            v = 0.5
        s = sigma[i - 1]
        if s < 1e-6:
            y[i] = x[i]
            continue
        a = math.exp(-v * dt / s)
        y[i] = a * y[i - 1] + (1.0 - a) * x[i - 1]
    return y


def relaxed_slip(x: np.ndarray, t_s: np.ndarray, V_mps: np.ndarray, sigma_m) -> np.ndarray:
    """First-order lag of a slip quantity in travelled distance, relaxation length sigma [m].

    (Pacejka 2012 §7.2.1, the single-contact-point transient model: sigma da'/ds + a' = a.)
    ``sigma_m`` is a number or one value per sample (load-dependent relaxation length).
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    sig = np.broadcast_to(np.asarray(sigma_m, dtype=np.float64), x.shape)
    if np.all(sig <= 1e-6):
        return x.copy()
    return _distance_lag(
        x,
        np.ascontiguousarray(t_s, dtype=np.float64),
        np.ascontiguousarray(V_mps, dtype=np.float64),
        np.ascontiguousarray(sig),
    )


def delayed(x: np.ndarray, t_s: np.ndarray, tau_s: float) -> np.ndarray:
    """x(t - tau): the value a channel had tau seconds earlier (held at the first sample)."""
    if tau_s == 0.0:
        return np.asarray(x, dtype=np.float64).copy()
    return np.interp(t_s - tau_s, t_s, x)
