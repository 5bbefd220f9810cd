"""The rig's own thermal physics: a three-node lumped tyre (tread surface, carcass, gas).

Deliberately NOT the model's temperature extension (INTERFACE.md TTX/TTY polynomials in one
temperature): here

* the tread **surface** node is heated by the frictional power and relaxes to the carcass with
  a time constant of seconds;
* the **carcass** (bulk) node takes a share of the same power and cools to ambient over
  minutes;
* the **gas** node follows the carcass (minutes) and sets the inflation pressure by the gas
  law (``gas_pressure`` effect);
* grip follows an asymmetric Gaussian *window* in surface temperature (optimum ``T_opt_C``),
  times a small linear bulk term; stiffness follows the *bulk* temperature linearly.

Powers are normalised by FNOMIN so the same defaults fit a 1 kN FSAE tyre and a 7 kN car
tyre: P/FNOMIN [W/N = m/s] is the equivalent sliding speed, and heating gains are in K per
metre of equivalent sliding. Default sizes follow PHYSICS.md (surface +4...22 degC in a ±10 deg
sweep at 3 deg/s; |mu| 6-7 % lower on the way back; bulk tau 1-5 min).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import asdict, dataclass

import numpy as np
import numpy.typing as npt
from numba import njit

from tire_model_ros.vocabulary import STANDARD_ATMOSPHERE_PA

F64 = npt.NDArray[np.float64]

KELVIN = 273.15  # degC -> K


@dataclass(frozen=True)
class HeatingParams:
    """Parameters of the ``heating`` effect (names are the effect's parameter keys)."""

    k_surface_K_per_m: float = 2.2  # surface heating per m of equivalent sliding (E_f/FNOMIN)
    tau_surface_s: float = 3.0  # surface -> carcass
    k_bulk_K_per_m: float = 0.07  # carcass heating per m of equivalent sliding
    tau_bulk_s: float = 180.0  # carcass -> ambient
    tau_gas_s: float = 60.0  # gas -> carcass
    T_opt_C: float = 28.0  # surface temperature of peak grip
    width_hot_K: float = 42.0  # Gaussian window half-width above the optimum
    width_cold_K: float = 45.0  # ... and below it
    mu_bulk_per_K: float = -0.001  # grip change per K of carcass above T_ref_C
    stiffness_per_K: float = -0.004  # slip-stiffness change per K of carcass above T_ref_C
    T_ref_C: float = 25.0  # carcass temperature at which stiffness and bulk grip are nominal

    @classmethod
    def from_dict(cls, d: Mapping[str, float]) -> HeatingParams:
        known = set(cls.__dataclass_fields__)
        bad = set(d) - known
        if bad:
            raise ValueError(
                f"effect heating: unknown parameter(s) {sorted(bad)}; known: {sorted(known)}"
            )
        return cls(**{k: float(v) for k, v in d.items()})

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


@njit(cache=True)
def _integrate(
    P_per_N: F64,
    T_amb: F64,
    dt: float,
    Ts0: float,
    Tb0: float,
    Tg0: float,
    k_s: float,
    tau_s: float,
    k_b: float,
    tau_b: float,
    tau_g: float,
) -> tuple[F64, F64, F64]:
    """Explicit Euler of the three nodes; returns surface, carcass and gas temperatures."""
    n = P_per_N.shape[0]
    Ts = np.empty(n)
    Tb = np.empty(n)
    Tg = np.empty(n)
    s, b, g = Ts0, Tb0, Tg0
    for i in range(n):
        Ts[i], Tb[i], Tg[i] = s, b, g
        q = P_per_N[i]
        ds = k_s * q - (s - b) / tau_s
        db = k_b * q - (b - T_amb[i]) / tau_b
        dg = (b - g) / tau_g
        s += dt * ds
        b += dt * db
        g += dt * dg
    return Ts, Tb, Tg


def integrate_nodes(
    P_W: np.ndarray, FNOMIN: float, T_amb: np.ndarray, dt: float, hp: HeatingParams
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node temperatures [degC] from the frictional power P_W [W]; start at ambient."""
    T0 = float(T_amb[0])
    return _integrate(
        np.ascontiguousarray(P_W / FNOMIN),
        np.ascontiguousarray(T_amb),
        dt,
        T0,
        T0,
        T0,
        hp.k_surface_K_per_m,
        hp.tau_surface_s,
        hp.k_bulk_K_per_m,
        hp.tau_bulk_s,
        hp.tau_gas_s,
    )


def frictional_power(Fx: F64, Fy: F64, Vx: F64, kappa: F64, alpha: F64) -> F64:
    """P_fric = |Fx Vx kappa| + |Fy Vx tan(alpha)| [W] (PHYSICS.md)."""
    return np.abs(Fx * Vx * kappa) + np.abs(Fy * Vx * np.tan(alpha))


def grip_window(Ts: np.ndarray, hp: HeatingParams) -> np.ndarray:
    """Asymmetric Gaussian grip window in surface temperature (1 at T_opt_C)."""
    d = Ts - hp.T_opt_C
    w = np.where(d > 0.0, hp.width_hot_K, hp.width_cold_K)
    return np.exp(-((d / w) ** 2))


def grip_factor(Ts: np.ndarray, Tb: np.ndarray, hp: HeatingParams) -> np.ndarray:
    """Friction scale from the surface window and the carcass term (clipped to [0.3, 1.5])."""
    return np.clip(grip_window(Ts, hp) * (1.0 + hp.mu_bulk_per_K * (Tb - hp.T_ref_C)), 0.3, 1.5)


def stiffness_factor(Tb: np.ndarray, hp: HeatingParams) -> np.ndarray:
    """Slip-stiffness scale from the carcass temperature (clipped to [0.5, 1.5])."""
    return np.clip(1.0 + hp.stiffness_per_K * (Tb - hp.T_ref_C), 0.5, 1.5)


def gas_law_pressure(p_set_gauge: np.ndarray, Tg: np.ndarray, run: np.ndarray) -> np.ndarray:
    """Gauge pressure of a sealed tyre: p_abs = p0_abs T_gas / T0 (constant volume).

    The tyre is (re)inflated to ``p_set_gauge`` at the start of each run, at the gas
    temperature of that moment (T0); within a run the set pressure may ramp (the rig's
    regulator is then still connected), so p0 follows ``p_set_gauge``.
    """
    starts = np.concatenate([[0], np.flatnonzero(np.diff(run)) + 1])
    T0 = np.empty_like(Tg)
    bounds = [*starts.tolist(), len(run)]
    for a, b in itertools.pairwise(bounds):
        T0[a:b] = Tg[a]
    p_abs = (p_set_gauge + STANDARD_ATMOSPHERE_PA) * (Tg + KELVIN) / (T0 + KELVIN)
    return p_abs - STANDARD_ATMOSPHERE_PA
