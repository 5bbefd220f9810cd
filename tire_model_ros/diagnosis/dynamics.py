"""The first-order dynamics the effect models are built of (numba kernels, no ROS).

Each is driven by recorded or derived channels and integrated exactly for an input held over
each sample step, so uneven time stamps and pauses are handled. These forms are the
diagnosis' own and deliberately simple (lumped nodes, a lag in travelled distance, a pure
delay): the diagnosis must find an effect with a model it can defend, not the rig's equations.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

Array = npt.NDArray[np.float64]


def frictional_power_W(
    Fx_N: Array, Fy_N: Array, V_mps: Array, kappa: Array, alpha_rad: Array
) -> Array:
    """Frictional power P_fric ~ |Fx V kappa| + |Fy V tan(alpha)| [W] (PHYSICS.md notation).

    Computed from *measured* forces, so that the driver of a hidden state does not depend on
    the model being fitted.
    """
    V = np.abs(np.asarray(V_mps, dtype=np.float64))
    return np.abs(Fx_N * V * kappa) + np.abs(Fy_N * V * np.tan(alpha_rad))


def stiffened(kappa: Array, alpha_rad: Array, k: Array | float) -> tuple[Array, Array]:
    """The slips at which a tyre whose slip stiffness is ``k`` times the file's gives the
    file's forces (kappa and tan(alpha) scaled: a stiffness factor as a similarity)."""
    return kappa * k, np.arctan(np.tan(alpha_rad) * k)


def cumulative_work_J(P_W: Array, t_s: Array) -> Array:
    """E_f(t) = integral of P_fric dt [J] (left rectangle rule, E_f(t0) = 0)."""
    dt = np.diff(t_s, prepend=t_s[:1])
    return np.cumsum(P_W * np.clip(dt, 0.0, None))


@njit(cache=True)
def _first_order(u, t, tau, y0):  # type: ignore[no-untyped-def]
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
    # The step's decay is recomputed only when the step changes by more than rounding: at an
    # even rate one exp, where an exp per sample was most of the cost.
    dt_a, a = -1.0, 0.0
    for i in range(1, n):
        dt = t[i] - t[i - 1]
        if dt < 0.0:
            dt = 0.0
        if not abs(dt - dt_a) <= 1e-9 * dt:  # (a NaN step is computed, as before: NaN)
            dt_a, a = dt, math.exp(-dt / tau)
        y[i] = a * y[i - 1] + (1.0 - a) * u[i - 1]
    return y


def first_order(u: Array, t_s: Array, tau_s: float, y0: float = 0.0) -> Array:
    """A lumped node y' = (u - y) / tau from y(t0) = y0 (tau <= 0: y = u, memoryless)."""
    return _first_order(  # type: ignore[no-any-return]
        np.ascontiguousarray(u, dtype=np.float64),
        np.ascontiguousarray(t_s, dtype=np.float64),
        float(tau_s),
        float(y0),
    )


def thermal_state_K(P_W: Array, t_s: Array, tau_s: float, gain_K_per_W: float) -> Array:
    """Temperature rise of one lumped thermal node above ambient [K].

    dT/dt = (k P_fric - (T - T_amb)) / tau, T(t0) = T_amb: steady state k P, time constant tau.
    """
    return first_order(gain_K_per_W * np.asarray(P_W, dtype=np.float64), t_s, tau_s)


@njit(cache=True)
def _distance_lag(x, t, V, sigma):  # type: ignore[no-untyped-def]
    """sigma dx'/ds + x' = x with ds = |V| dt, exact per step for x linear over the step
    (first-order hold: the lag goes to zero with sigma, with no half-step left over)."""
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
        if v < 0.5:  # the lag in distance is undefined at standstill; keep it finite
            v = 0.5
        ds, s = v * dt, sigma[i - 1]
        if s < 1e-9 or ds <= 0.0:
            y[i] = x[i] if s < 1e-9 else y[i - 1]
            continue
        a = math.exp(-ds / s)
        slope_s = (x[i] - x[i - 1]) * s / ds  # the input's change per lag length
        y[i] = a * y[i - 1] + x[i] - a * x[i - 1] - slope_s * (1.0 - a)
    return y


def relaxed_slip(x: Array, t_s: Array, V_mps: Array, sigma_m: float | Array) -> Array:
    """First-order lag of a slip quantity in travelled distance, relaxation length sigma [m].

    (Pacejka 2012 §7.2.1, the single-contact-point transient model: sigma da'/ds + a' = a.)
    ``sigma_m`` is a number or one value per sample (a length that varies with load and slip).
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    sig = np.broadcast_to(np.asarray(sigma_m, dtype=np.float64), x.shape)
    if np.all(sig <= 1e-6):
        return x.copy()
    return _distance_lag(  # type: ignore[no-any-return]
        x,
        np.ascontiguousarray(t_s, dtype=np.float64),
        np.ascontiguousarray(V_mps, dtype=np.float64),
        np.ascontiguousarray(sig),
    )


def lowpass(x: Array, t_s: Array, tau_s: float) -> Array:
    """A first-order filter of a smooth signal (a DAQ's anti-alias filter), exact for the
    signal linear between samples: tau -> 0 gives the signal itself."""
    if tau_s <= 0.0:
        return np.asarray(x, dtype=np.float64).copy()
    return relaxed_slip(x, t_s, np.ones_like(t_s), tau_s)


def zero_phase(x: Array, t_s: Array, V_mps: Array, sigma_m: float | Array) -> Array:
    """:func:`relaxed_slip` run forwards and then backwards in time: it smooths as a lag of
    that length does, without lagging (the control a lag must beat: a lag fitted to a slip
    channel's noise is a smoother, and gains as much without its phase)."""
    y = relaxed_slip(x, t_s, V_mps, sigma_m)
    sig = np.broadcast_to(np.asarray(sigma_m, dtype=np.float64), y.shape)
    back = relaxed_slip(y[::-1], t_s[-1] - t_s[::-1], V_mps[::-1], sig[::-1])
    return back[::-1].copy()


def delayed(x: Array, t_s: Array, tau_s: float) -> Array:
    """x(t - tau): the value a channel had tau seconds earlier (held at the first sample)."""
    if tau_s == 0.0:
        return np.asarray(x, dtype=np.float64).copy()
    return np.interp(t_s - tau_s, t_s, x)
