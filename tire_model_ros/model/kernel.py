"""One evaluation of the Magic Formula per sample: the scalar kernel and its batch loop.

The same scalar code serves :meth:`TireModel.evaluate` (batch loop over samples) and
:meth:`TireModel.evaluate_one` (one sample per ROS message). Output rows of the batch array:
the first ``N_FORCES`` rows are always computed; the rest (radii, stiffnesses, relaxation
lengths, used inputs) only when the output array has ``N_OUT`` rows.
"""

from __future__ import annotations

import math

import numpy as np

from . import coef as c
from .conditions import (
    cos_alpha_prime,
    load_increment,
    operating_point,
    pressure_increment,
    temperature_increment,
)
from .forces import Fx0_pure, Fy0_pure, Gxa_weighting, Gyk_weighting, SVyk_shift
from .jit import kernel
from .moments import Mx_overturning, My_rolling_resistance, Mz_aligning
from .vertical import contact_patch, deflection_61, deflection_62, relaxation, rolling_state

# fmt: off
OUT_NAMES: tuple[str, ...] = (
    "Fx", "Fy", "Fz", "Mx", "My", "Mz", "Kxk", "Kya", "mux", "muy", "t", "Mzr",
    # full outputs only
    "Re", "omega", "rho", "Rl", "Cz", "Cx", "Cy", "sigmax", "sigmay", "two_a", "two_b",
    "kappa_used", "alpha_used", "gamma_used", "p_used",
)
# fmt: on
N_FORCES = 12
N_OUT = len(OUT_NAMES)
(FX, FY, FZ, MX, MY, MZ, KXK, KYA, MUX, MUY, T_TRAIL, MZR,
 RE, OMEGA, RHO, RL, CZ, CX, CY, SIGMAX, SIGMAY, TWO_A, TWO_B,
 KAPPA_USED, ALPHA_USED, GAMMA_USED, P_USED) = range(N_OUT)  # fmt: skip


@kernel
def is_mf52(P) -> bool:
    """FITTYP 6 or 21: the MF 5.2 branches of MFeval."""
    return P[c.FITTYP] == 6.0 or P[c.FITTYP] == 21.0


@kernel
def forces_point(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, limits):
    """Forces and moments of one sample (turn slip not modelled).

    Returns
    -------
    tuple
        ``(Fx, Fy, Fz_out, Mx, My, Mz, Kxk, Kya, mux, muy, t, Mzr)`` followed by the
        operating point used ``(Fz, kappa_low, alpha, gamma, p, dfz, dpi, uFz)``.
    """
    mf52 = is_mf52(P)
    Fz_, kappa_, alpha_, gamma_, _, p_, uFz, kappa_low, Fz_low, red = operating_point(
        P, Fz, kappa, alpha, gamma, Vx, p, phit, limits
    )
    dfz = load_increment(P, Fz_)
    dpi = pressure_increment(P, p_)
    dT = temperature_increment(P, T)
    cos_alpha_p = cos_alpha_prime(alpha_, Vx)

    Fx0, mux, Kxk = Fx0_pure(P, Fz_, kappa_, gamma_, Vx, dfz, dpi, dT, red, limits)
    Fy0, muy, Kya, SHy, SVy, By, Cy = Fy0_pure(
        P, Fz_, alpha_, gamma_, dfz, dpi, dT, red, limits, mf52
    )
    Fx = Gxa_weighting(P, kappa_, alpha_, gamma_, dfz, limits) * Fx0  # (4.E50)
    Gyk = Gyk_weighting(P, kappa_, alpha_, gamma_, dfz, limits)
    SVyk = SVyk_shift(P, Fz_, kappa_, alpha_, gamma_, dfz, muy, red)
    Fy = Gyk * Fy0 + SVyk  # (4.E58)

    # Fy' of (4.E74): Fy0 at zero camber (and no turn slip) times Gyk (MFeval keeps the
    # camber in Gyk here)
    if gamma_ == 0.0:
        Fy_prime = Gyk * Fy0
    else:
        Fy_prime = Gyk * Fy0_pure(P, Fz_, alpha_, 0.0, dfz, dpi, dT, red, limits, mf52)[0]
    Fz_mz = Fz_low if limits else Fz_
    if Fz_ <= 0.0:
        Fz_mz = 0.0
    Mz, t, Mzr = Mz_aligning(
        P, Fz_mz, dfz, dpi, kappa_, alpha_, gamma_, Vx, cos_alpha_p, limits, mf52,
        Kxk, Kya, SHy, SVy, By, Cy, Fx, Fy, SVyk, Fy_prime, red,
    )  # fmt: skip
    Mx = Mx_overturning(P, Fz_, gamma_, dpi, Fy)
    My = My_rolling_resistance(P, uFz, kappa, gamma_, Vx, p_, Fx, mf52)
    return (
        (Fx, Fy, uFz, Mx, My, Mz, Kxk, Kya, mux, muy, t, Mzr),
        (Fz_, kappa_low, alpha_, gamma_, p_, dfz, dpi, uFz, Fz_low),
    )


@kernel
def _forces_loop(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, limits, out):
    """Rows 0..N_FORCES-1 of ``out`` for every sample (``limits`` a compile-time constant)."""
    for i in range(Fz.shape[0]):
        res = forces_point(P, Fz[i], kappa[i], alpha[i], gamma[i], Vx[i], p[i], T[i], phit[i],
                           limits)[0]  # fmt: skip
        out[FX, i] = res[0]
        out[FY, i] = res[1]
        out[FZ, i] = res[2]
        out[MX, i] = res[3]
        out[MY, i] = res[4]
        out[MZ, i] = res[5]
        out[KXK, i] = res[6]
        out[KYA, i] = res[7]
        out[MUX, i] = res[8]
        out[MUY, i] = res[9]
        out[T_TRAIL, i] = res[10]
        out[MZR, i] = res[11]


@kernel
def forces_loop_limits(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, out):
    """Forces and moments with the limits on (MFeval useMode 111)."""
    _forces_loop(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, True, out)


@kernel
def forces_loop_plain(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, out):
    """Forces and moments of the plain equations (MFeval useMode 211)."""
    _forces_loop(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, False, out)


@kernel
def extras_loop(P, Fz, kappa, alpha, gamma, Vx, p, phit, omega, limits, out):
    """Rows N_FORCES.. of ``out``: radii, deflection, stiffnesses, relaxation, used inputs.

    Reads Fx, Fy, Kxk, Kya from the rows the forces loop wrote.
    """
    mf52 = is_mf52(P)
    mf62 = P[c.FITTYP] == 62.0
    for i in range(Fz.shape[0]):
        Fz_, _, _, gamma_, _, p_, uFz, kappa_low, Fz_low, _ = operating_point(
            P, Fz[i], kappa[i], alpha[i], gamma[i], Vx[i], p[i], phit[i], limits
        )
        dfz = load_increment(P, Fz_)
        dpi = pressure_increment(P, p_)
        Fx, Fy, Kxk, Kya = out[FX, i], out[FY, i], out[KXK, i], out[KYA, i]
        Re, Romega, w = rolling_state(P, uFz, kappa[i], Vx[i], dpi, omega[i])
        if mf62:
            rho, Rl, Cz = deflection_62(P, uFz, Fz_, gamma_, dpi, w, Romega, Fx, Fy)
        else:
            rho, Rl, Cz = deflection_61(P, Fz_low, dpi, w, Romega, Fx, Fy)
        two_a, two_b = contact_patch(P, uFz, dpi, mf52)
        Cx, Cy, sigmax, sigmay = relaxation(P, Fz_, dfz, dpi, gamma_, Kxk, Kya, mf52)
        out[RE, i] = Re
        out[OMEGA, i] = w
        out[RHO, i] = rho
        out[RL, i] = Rl
        out[CZ, i] = Cz
        out[CX, i] = Cx
        out[CY, i] = Cy
        out[SIGMAX, i] = sigmax
        out[SIGMAY, i] = sigmay
        out[TWO_A, i] = two_a
        out[TWO_B, i] = two_b
        out[KAPPA_USED, i] = kappa_low
        out[ALPHA_USED, i] = 0.0 if Vx[i] == 0.0 else alpha[i]
        out[GAMMA_USED, i] = gamma[i]
        out[P_USED, i] = p_


def evaluate_batch(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, omega, limits, out):
    """Evaluate every sample i of the 1-D input arrays into column i of ``out``.

    ``out`` has ``N_FORCES`` rows (forces and moments only) or ``N_OUT`` rows (everything).
    """
    loop = forces_loop_limits if limits else forces_loop_plain
    loop(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, out)
    if out.shape[0] >= N_OUT:
        extras_loop(P, Fz, kappa, alpha, gamma, Vx, p, phit, omega, bool(limits), out)


@kernel
def evaluate_point(P, Fz, kappa, alpha, gamma, Vx, p, T, limits):
    """(Fx, Fy, Fz, Mx, My, Mz) of one sample: the per-message path of the node."""
    res = forces_point(P, Fz, kappa, alpha, gamma, Vx, p, T, 0.0, limits)[0]
    return res[0], res[1], res[2], res[3], res[4], res[5]


def warm_up() -> None:
    """Compile (or load from the numba cache) every entry point TireModel uses."""
    P = np.zeros(c.N_COEF)
    P[c.FNOMIN] = P[c.NOMPRES] = P[c.NOMTEMP] = P[c.LONGVL] = P[c.UNLOADED_RADIUS] = 1.0
    P.setflags(write=False)  # the types TireModel passes: read-only P, writable inputs
    x = np.ones(1)
    for limits in (True, False):
        evaluate_batch(P, x, x, x, x, x, x, x, x, x * math.nan, limits, np.empty((N_OUT, 1)))
        evaluate_point(P, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, limits)
