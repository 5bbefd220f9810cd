"""The Magic Formula over arrays of samples: stage loops over blocks that LLVM vectorises.

The equations are scalar kernels (:mod:`.forces`, :mod:`.moments`, :mod:`.conditions`,
:mod:`.turnslip`), inlined into one loop per stage; a stage keeps what later stages need in a
scratch block. The same code serves :meth:`TireModel.evaluate` (blocks of ``BLOCK`` samples) and
:meth:`TireModel.evaluate_one` (a block of one, per ROS message). Output rows of the batch array:
the first ``N_FORCES`` rows are always computed; the rest (radii, stiffnesses, relaxation
lengths, used inputs) only when the output array has ``N_OUT`` rows.

Two variants of MFeval's useMode have their own loop, :func:`forces_loop_modes`: turn slip
(units digit 2) and alpha* = tan(alpha), gamma* = sin(gamma) (tens digit 2). A modes stage
(alpha*, gamma*, the spin and the turn-slip factors) runs first; its stages call the same
kernels with those rows where the plain stages pass constants. :func:`forces_loop`, the plain
equations, never calls them, so the variants neither slow it down nor add to its compile time.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from . import coef as c
from . import vmath as vm
from .conditions import (
    clip,
    cos_alpha_prime,
    load_increment,
    operating_point,
    pressure_increment,
    sign0,
    temperature_increment,
)
from .forces import (
    Fx0_pure,
    Fy0_pure,
    Gxa_weighting,
    Gyk_weighting,
    Kya_cornering_stiffness,
    Kyg0_camber_stiffness,
    SVyk_shift,
)
from .jit import kernel, standalone
from .moments import Mx_overturning, My_rolling_resistance, Mz_aligning
from .turnslip import (
    SHyp_shift,
    epsilon_gamma,
    spin_phi,
    zeta1_Fx,
    zeta2_Fy,
    zeta3_Kya,
    zeta5_trail,
    zeta6_residual,
    zeta7_zeta8,
)
from .vertical import contact_patch, deflection_61, deflection_62, relaxation, rolling_state

F64 = npt.NDArray[np.float64]

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


# Rows of the scratch block: what a stage passes on to later stages.
# Rows 0..N_FORCES-1 hold the outputs (FX..MZR) until they are copied to the output array.
(S_FZ, S_KAPPA, S_ALPHA, S_GAMMA, S_P, S_FZ_MZ, S_RED, S_DFZ, S_DPI, S_DT, S_COS_AP,
 S_FX0, S_FY0, S_FY0_G0, S_SHY, S_SVY, S_BY, S_CY, S_SVYK,
 S_FY_PRIME) = range(N_FORCES, N_FORCES + 20)  # fmt: skip
N_SCRATCH = N_FORCES + 20
# Rows of the variants only: alpha*, gamma* (alpha, gamma without the alpha* variant), the turn
# slip phit as used, the spin phi, eps_gamma, the turn-slip factors; Gyk (combined stage).
(S_ALPHA_S, S_GAMMA_S, S_PHIT, S_PHI, S_EPS_G, S_ZETA1, S_ZETA2, S_ZETA3, S_SHYP, S_ZETA5,
 S_ZETA6, S_GYK) = range(N_SCRATCH, N_SCRATCH + 12)  # fmt: skip
N_SCRATCH_MODES = N_SCRATCH + 12
BLOCK = 512  # samples per block: the scratch rows stay in the L1/L2 cache


@kernel
def _keep(s, rows, o, n):
    """Copy row k of a stage's block ``o`` to scratch row ``rows[k]`` (columns 0..n-1)."""
    for k in range(len(rows)):
        s[rows[k], :n] = o[k, :n]


# Each stage is compiled on its own (LLVM's cost grows faster than the size of the function it
# optimises) and writes into a block it allocates: LLVM then knows that the stores cannot alias
# the inputs, P or the scratch it reads, and vectorises the loop. The rows each stage fills:
COND_ROWS = (S_FZ, S_KAPPA, S_ALPHA, S_GAMMA, S_P, S_FZ_MZ, S_RED, S_DFZ, S_DPI, S_DT, S_COS_AP, FZ)
LONG_ROWS = (S_FX0, MUX, KXK)
LAT_ROWS = (S_FY0, S_SHY, S_SVY, S_BY, S_CY, MUY, KYA)
LAT_G0_ROWS = (S_FY0_G0,)
COMB_ROWS = (FX, FY, S_SVYK, S_FY_PRIME)
MZ_ROWS = (MZ, T_TRAIL, MZR)
MOM_ROWS = (MX, MY)
MODE_ROWS = (S_ALPHA_S, S_GAMMA_S, S_PHIT, S_PHI, S_EPS_G, S_ZETA1, S_ZETA2, S_ZETA3, S_SHYP,
             S_ZETA5, S_ZETA6)  # fmt: skip
COMB_ROWS_MODES = (*COMB_ROWS, S_GYK)


@kernel
def _conditions_sample(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, limits, i, o, j):
    """Column j of the conditions block: sample i (see :func:`_conditions_stage`)."""
    Fz_, kappa_, alpha_, gamma_, _, p_, uFz, _, Fz_low, red = operating_point(
        P, Fz[i], kappa[i], alpha[i], gamma[i], Vx[i], p[i], phit[i], limits
    )
    Fz_mz = Fz_low if limits else Fz_
    o[0, j] = Fz_
    o[1, j] = kappa_
    o[2, j] = alpha_
    o[3, j] = gamma_
    o[4, j] = p_
    o[5, j] = 0.0 if Fz_ <= 0.0 else Fz_mz
    o[6, j] = red
    o[7, j] = load_increment(P, Fz_)
    o[8, j] = pressure_increment(P, p_)
    T_ = clip(T[i], P[c.TEMPMIN], P[c.TEMPMAX]) if limits else T[i]
    o[9, j] = temperature_increment(P, T_)
    o[10, j] = cos_alpha_prime(alpha_, Vx[i])
    o[11, j] = uFz


@standalone
def _conditions_stage(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, limits, i0, n):
    """Operating point and increments of samples i0..i0+n-1 (column j = i - i0), COND_ROWS.

    One loop per value of ``limits``: with a constant there, the branches of the saturation
    and low-speed model fold away and LLVM vectorises the loop.
    """
    o = np.empty((len(COND_ROWS), BLOCK))
    if limits:
        for j in range(n):
            _conditions_sample(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, True, i0 + j, o, j)
    else:
        for j in range(n):
            _conditions_sample(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, False, i0 + j, o, j)
    return o


@standalone
def _longitudinal_stage(P, Vx, limits, i0, n, s):
    """Pure-slip Fx0, mux, Kxk (4.E9)-(4.E18), LONG_ROWS."""
    o = np.empty((len(LONG_ROWS), BLOCK))
    for j in range(n):
        i = i0 + j
        o[0, j], o[1, j], o[2, j] = Fx0_pure(
            P, s[S_FZ, j], s[S_KAPPA, j], s[S_GAMMA, j], Vx[i], s[S_DFZ, j], s[S_DPI, j],
            s[S_DT, j], s[S_RED, j], limits, 1.0,
        )  # fmt: skip
    return o


@standalone
def _lateral_stage(P, limits, mf52, n, s):
    """Pure-slip Fy0, the shifts, muy and Kya (4.E19)-(4.E30), LAT_ROWS."""
    o = np.empty((len(LAT_ROWS), BLOCK))
    for j in range(n):
        Fy0, muy, Kya, SHy, SVy, By, Cy = Fy0_pure(
            P, s[S_FZ, j], s[S_ALPHA, j], s[S_GAMMA, j], s[S_DFZ, j], s[S_DPI, j], s[S_DT, j],
            s[S_RED, j], limits, mf52, False, 1.0, 1.0, 0.0,
        )  # fmt: skip
        o[0, j] = Fy0
        o[1, j] = SHy
        o[2, j] = SVy
        o[3, j] = By
        o[4, j] = Cy
        o[5, j] = muy
        o[6, j] = Kya
    return o


@standalone
def _lateral_zero_camber_stage(P, limits, mf52, n, s):
    """Fy0 at zero camber (and no turn slip), for Fy' of (4.E74), LAT_G0_ROWS."""
    o = np.empty((len(LAT_G0_ROWS), BLOCK))
    for j in range(n):
        o[0, j] = Fy0_pure(
            P, s[S_FZ, j], s[S_ALPHA, j], 0.0, s[S_DFZ, j], s[S_DPI, j], s[S_DT, j],
            s[S_RED, j], limits, mf52, False, 1.0, 1.0, 0.0,
        )[0]  # fmt: skip
    return o


@standalone
def _combined_stage(P, limits, n, s):
    """Combined-slip Fx (4.E50), Fy (4.E58), SVyk and Fy' (Gyk keeps the camber, as MFeval)."""
    o = np.empty((len(COMB_ROWS), BLOCK))
    for j in range(n):
        kappa_, alpha_, gamma_, dfz = s[S_KAPPA, j], s[S_ALPHA, j], s[S_GAMMA, j], s[S_DFZ, j]
        Gyk = Gyk_weighting(P, kappa_, alpha_, gamma_, dfz, limits)
        SVyk = SVyk_shift(P, s[S_FZ, j], kappa_, alpha_, gamma_, dfz, s[MUY, j], s[S_RED, j],
                          1.0)  # fmt: skip
        o[0, j] = Gxa_weighting(P, kappa_, alpha_, gamma_, dfz, limits) * s[S_FX0, j]
        o[1, j] = Gyk * s[S_FY0, j] + SVyk
        o[2, j] = SVyk
        o[3, j] = Gyk * s[S_FY0_G0, j]
    return o


@standalone
def _aligning_stage(P, Vx, limits, mf52, i0, n, s):
    """Aligning torque Mz, trail t and residual torque Mzr (4.E71)-(4.E78), MZ_ROWS."""
    o = np.empty((len(MZ_ROWS), BLOCK))
    for j in range(n):
        i = i0 + j
        gamma_ = s[S_GAMMA, j]
        o[0, j], o[1, j], o[2, j] = Mz_aligning(
            P, s[S_FZ_MZ, j], s[S_DFZ, j], s[S_DPI, j], s[S_KAPPA, j], s[S_ALPHA, j],
            gamma_, gamma_, Vx[i], s[S_COS_AP, j], limits, mf52, s[KXK, j], s[KYA, j],
            s[S_SHY, j], s[S_SVY, j], s[S_BY, j], s[S_CY, j], s[FX, j], s[FY, j],
            s[S_SVYK, j], s[S_FY_PRIME, j], s[S_RED, j], False, 1.0, 1.0, 1.0, 1.0, 0.0,
        )  # fmt: skip
    return o


# --- the variants (turn slip, alpha*): their own stages, compiled on first use --------------
# The modes stage fills MODE_ROWS; the stages below read alpha*, gamma* and the turn-slip
# factors there and pass them to the same kernels as the stages above, which pass constants
# (1, 0, False) instead. Separate functions: the plain loops stay as they were, and their
# compile time too (an inlined block shared by both would be inlined, and compiled, twice).


@kernel
def _spin_sample(P, Fz, kappa, alpha, gamma, Vx, p, phit, omega, limits, mf52, i, s, j):
    """Turn-slip quantities of sample i (scratch column j), in the order of MODE_ROWS[2:]."""
    phit_ = operating_point(P, Fz[i], kappa[i], alpha[i], gamma[i], Vx[i], p[i], phit[i],
                            limits)[4]  # fmt: skip
    Fz_, alpha_, dfz, dpi, dT = s[S_FZ, j], s[S_ALPHA, j], s[S_DFZ, j], s[S_DPI, j], s[S_DT, j]
    w = omega[i]
    if math.isnan(w):  # MFeval's omega: (1 + kappa) Vx / Re, Re iterated to |dRe| <= 1e-9
        w = rolling_state(P, s[FZ, j], kappa[i], Vx[i], dpi, math.nan, True)[2]
    eps_g = epsilon_gamma(P, dfz)
    phi = spin_phi(P, phit_, Vx[i], alpha_, s[S_GAMMA, j], w, eps_g)
    zeta3 = zeta3_Kya(P, phi)
    Kya0 = Kya_cornering_stiffness(P, Fz_, dpi, 0.0, dT) * zeta3
    Kyg0 = Kyg0_camber_stiffness(P, Fz_, dfz, dpi, mf52)
    SHyp = SHyp_shift(P, dfz, Vx[i], Kyg0, Kya0, phi, eps_g, limits)
    zeta1 = zeta1_Fx(P, dfz, s[S_KAPPA, j], phi)
    zeta2 = zeta2_Fy(P, dfz, alpha_, phi)
    return phit_, phi, eps_g, zeta1, zeta2, zeta3, SHyp, zeta5_trail(P, phi), zeta6_residual(P, phi)


@standalone
def _modes_stage(P, Fz, kappa, alpha, gamma, Vx, p, phit, omega, limits, mf52, turn_slip,
                 alpha_star, i0, n, s):  # fmt: skip
    """alpha*, gamma* (4.E3, 4.E4) and the turn-slip quantities of :mod:`.turnslip`, MODE_ROWS.

    Without turn slip phi = 0 and the zeta factors are 1; without alpha*, the rows hold alpha
    and gamma.
    """
    o = np.empty((len(MODE_ROWS), BLOCK))
    for j in range(n):
        i = i0 + j
        alpha_, gamma_ = s[S_ALPHA, j], s[S_GAMMA, j]
        if alpha_star:
            o[0, j] = vm.tan(alpha_) * sign0(Vx[i])
            o[1, j] = vm.sin(gamma_)
        else:
            o[0, j] = alpha_
            o[1, j] = gamma_
        if turn_slip:
            (o[2, j], o[3, j], o[4, j], o[5, j], o[6, j], o[7, j], o[8, j], o[9, j],
             o[10, j]) = _spin_sample(P, Fz, kappa, alpha, gamma, Vx, p, phit, omega, limits,
                                      mf52, i, s, j)  # fmt: skip
        else:
            for k in range(2, len(MODE_ROWS)):
                o[k, j] = 1.0
            o[2, j] = o[3, j] = o[4, j] = o[8, j] = 0.0  # phit, phi, eps_gamma, SHyp
    return o


@standalone
def _longitudinal_stage_modes(P, Vx, limits, i0, n, s):
    """:func:`_longitudinal_stage` with zeta1 (4.105)."""
    o = np.empty((len(LONG_ROWS), BLOCK))
    for j in range(n):
        i = i0 + j
        o[0, j], o[1, j], o[2, j] = Fx0_pure(
            P, s[S_FZ, j], s[S_KAPPA, j], s[S_GAMMA, j], Vx[i], s[S_DFZ, j], s[S_DPI, j],
            s[S_DT, j], s[S_RED, j], limits, s[S_ZETA1, j],
        )  # fmt: skip
    return o


@kernel
def _Fy0_modes(P, Vx, limits, mf52, turn_slip, alpha_star, s, j, gamma_):
    """Fy0_pure at alpha* and camber gamma_ with the turn-slip factors; alpha* reverses it."""
    Fy0, muy, Kya, SHy, SVy, By, Cy = Fy0_pure(
        P, s[S_FZ, j], s[S_ALPHA_S, j], gamma_, s[S_DFZ, j], s[S_DPI, j], s[S_DT, j],
        s[S_RED, j], limits, mf52, turn_slip, s[S_ZETA2, j], s[S_ZETA3, j], s[S_SHYP, j],
    )  # fmt: skip
    if alpha_star and Vx < 0.0:  # MFeval: Fy0 follows the direction of travel with alpha*
        Fy0 = -Fy0
    return Fy0, muy, Kya, SHy, SVy, By, Cy


@standalone
def _lateral_stage_modes(P, Vx, limits, mf52, turn_slip, alpha_star, i0, n, s):
    """:func:`_lateral_stage` at alpha*, gamma* with zeta2, zeta3, SHyp (4.77)-(4.89)."""
    o = np.empty((len(LAT_ROWS), BLOCK))
    for j in range(n):
        Fy0, muy, Kya, SHy, SVy, By, Cy = _Fy0_modes(
            P, Vx[i0 + j], limits, mf52, turn_slip, alpha_star, s, j, s[S_GAMMA_S, j]
        )
        o[0, j] = Fy0
        o[1, j] = SHy
        o[2, j] = SVy
        o[3, j] = By
        o[4, j] = Cy
        o[5, j] = muy
        o[6, j] = Kya
    return o


@standalone
def _lateral_zero_camber_stage_modes(P, Vx, limits, mf52, turn_slip, alpha_star, i0, n, s):
    """:func:`_lateral_zero_camber_stage` at alpha*, with the spin (MFeval's Fy0 'sub0')."""
    o = np.empty((len(LAT_G0_ROWS), BLOCK))
    for j in range(n):
        o[0, j] = _Fy0_modes(P, Vx[i0 + j], limits, mf52, turn_slip, alpha_star, s, j, 0.0)[0]
    return o


@standalone
def _combined_stage_modes(P, limits, n, s):
    """:func:`_combined_stage` at alpha*, gamma*, zeta2 in SVyk; also Gyk, COMB_ROWS_MODES."""
    o = np.empty((len(COMB_ROWS_MODES), BLOCK))
    for j in range(n):
        kappa_, alpha_, gamma_, dfz = s[S_KAPPA, j], s[S_ALPHA_S, j], s[S_GAMMA_S, j], s[S_DFZ, j]
        Gyk = Gyk_weighting(P, kappa_, alpha_, gamma_, dfz, limits)
        SVyk = SVyk_shift(P, s[S_FZ, j], kappa_, alpha_, gamma_, dfz, s[MUY, j], s[S_RED, j],
                          s[S_ZETA2, j])  # fmt: skip
        o[0, j] = Gxa_weighting(P, kappa_, alpha_, gamma_, dfz, limits) * s[S_FX0, j]
        o[1, j] = Gyk * s[S_FY0, j] + SVyk
        o[2, j] = SVyk
        o[3, j] = Gyk * s[S_FY0_G0, j]
        o[4, j] = Gyk
    return o


@standalone
def _aligning_stage_modes(P, Vx, limits, mf52, turn_slip, i0, n, s):
    """:func:`_aligning_stage` at alpha*, gamma* with zeta0, zeta2, zeta5-zeta8 (turn slip)."""
    o = np.empty((len(MZ_ROWS), BLOCK))
    for j in range(n):
        i = i0 + j
        Fz_mz, dfz = s[S_FZ_MZ, j], s[S_DFZ, j]
        ratio7, Drphi = 1.0, 0.0
        if turn_slip:
            ratio7, Drphi = zeta7_zeta8(P, Fz_mz, dfz, s[S_GAMMA, j], s[MUY, j], s[S_GYK, j],
                                        s[S_PHIT, j], s[S_EPS_G, j])  # fmt: skip
        o[0, j], o[1, j], o[2, j] = Mz_aligning(
            P, Fz_mz, dfz, s[S_DPI, j], s[S_KAPPA, j], s[S_ALPHA_S, j], s[S_GAMMA, j],
            s[S_GAMMA_S, j], Vx[i], s[S_COS_AP, j], limits, mf52, s[KXK, j], s[KYA, j],
            s[S_SHY, j], s[S_SVY, j], s[S_BY, j], s[S_CY, j], s[FX, j], s[FY, j],
            s[S_SVYK, j], s[S_FY_PRIME, j], s[S_RED, j], turn_slip, s[S_ZETA2, j],
            s[S_ZETA5, j], s[S_ZETA6, j], ratio7, Drphi,
        )  # fmt: skip
    return o


@standalone
def _moments_stage(P, kappa, Vx, mf52, i0, n, s):
    """Overturning couple Mx and rolling resistance My, MOM_ROWS."""
    o = np.empty((len(MOM_ROWS), BLOCK))
    for j in range(n):
        i = i0 + j
        gamma_ = s[S_GAMMA, j]
        o[0, j] = Mx_overturning(P, s[S_FZ, j], gamma_, s[S_DPI, j], s[FY, j])
        o[1, j] = My_rolling_resistance(P, s[FZ, j], kappa[i], gamma_, Vx[i], s[S_P, j],
                                        s[FX, j], mf52)  # fmt: skip
    return o


@kernel
def _zero_camber(s, row, n) -> bool:
    """Whether the camber of scratch ``row`` is +0.0 (not -0.0) in columns 0..n-1 throughout."""
    for j in range(n):
        g = s[row, j]
        if g != 0.0 or math.copysign(1.0, g) < 0.0:
            return False
    return True


@kernel
def _no_moments(s, n):
    """The moment rows (Mx, My, Mz, t, Mzr) of a forces-only evaluation: NaN, not computed."""
    for k in range(len(MZ_ROWS)):
        s[MZ_ROWS[k], :n] = math.nan
    for k in range(len(MOM_ROWS)):
        s[MOM_ROWS[k], :n] = math.nan


@standalone
def forces_loop(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, limits, out, moments=True):
    """Rows 0..N_FORCES-1 of ``out`` for every sample, block by block, stage by stage.

    ``moments`` False: the forces alone (Fx, Fy and what they need), the moment rows NaN; the
    aligning and moment stages are more than half of the loop's time. (Last, with a default:
    the loop is called from outside the package with the arguments before it.)
    """
    mf52 = is_mf52(P)
    s = np.empty((N_SCRATCH, BLOCK))
    for i0 in range(0, Fz.shape[0], BLOCK):
        n = min(BLOCK, Fz.shape[0] - i0)
        o = _conditions_stage(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, limits, i0, n)
        _keep(s, COND_ROWS, o, n)
        _keep(s, LONG_ROWS, _longitudinal_stage(P, Vx, limits, i0, n, s), n)
        _keep(s, LAT_ROWS, _lateral_stage(P, limits, mf52, n, s), n)
        if not moments:  # Fy0 at zero camber serves Fy' (Mz) only
            s[S_FY0_G0, :n] = 0.0
        elif _zero_camber(s, S_GAMMA, n):  # Fy0 at zero camber is Fy0 itself: the same call
            s[S_FY0_G0, :n] = s[S_FY0, :n]
        else:
            _keep(s, LAT_G0_ROWS, _lateral_zero_camber_stage(P, limits, mf52, n, s), n)
        _keep(s, COMB_ROWS, _combined_stage(P, limits, n, s), n)
        if moments:
            _keep(s, MZ_ROWS, _aligning_stage(P, Vx, limits, mf52, i0, n, s), n)
            _keep(s, MOM_ROWS, _moments_stage(P, kappa, Vx, mf52, i0, n, s), n)
        else:
            _no_moments(s, n)
        for k in range(N_FORCES):
            out[k, i0 : i0 + n] = s[k, :n]


@standalone
def forces_loop_modes(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, omega, limits, turn_slip,
                      alpha_star, out, moments=True):  # fmt: skip
    """:func:`forces_loop` with turn slip and/or alpha*, gamma* (MFeval useMode x2x, xx2)."""
    mf52 = is_mf52(P)
    s = np.empty((N_SCRATCH_MODES, BLOCK))
    for i0 in range(0, Fz.shape[0], BLOCK):
        n = min(BLOCK, Fz.shape[0] - i0)
        o = _conditions_stage(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, limits, i0, n)
        _keep(s, COND_ROWS, o, n)
        o = _modes_stage(P, Fz, kappa, alpha, gamma, Vx, p, phit, omega, limits, mf52,
                         turn_slip, alpha_star, i0, n, s)  # fmt: skip
        _keep(s, MODE_ROWS, o, n)
        _keep(s, LONG_ROWS, _longitudinal_stage_modes(P, Vx, limits, i0, n, s), n)
        o = _lateral_stage_modes(P, Vx, limits, mf52, turn_slip, alpha_star, i0, n, s)
        _keep(s, LAT_ROWS, o, n)
        if not moments:  # Fy0 at zero camber serves Fy' (Mz) only
            s[S_FY0_G0, :n] = 0.0
        elif _zero_camber(s, S_GAMMA_S, n):
            s[S_FY0_G0, :n] = s[S_FY0, :n]
        else:
            o = _lateral_zero_camber_stage_modes(P, Vx, limits, mf52, turn_slip, alpha_star, i0,
                                                 n, s)  # fmt: skip
            _keep(s, LAT_G0_ROWS, o, n)
        _keep(s, COMB_ROWS_MODES, _combined_stage_modes(P, limits, n, s), n)
        if moments:
            o = _aligning_stage_modes(P, Vx, limits, mf52, turn_slip, i0, n, s)
            _keep(s, MZ_ROWS, o, n)
            _keep(s, MOM_ROWS, _moments_stage(P, kappa, Vx, mf52, i0, n, s), n)
        else:
            _no_moments(s, n)
        for k in range(N_FORCES):
            out[k, i0 : i0 + n] = s[k, :n]


@standalone
def extras_loop(P, Fz, kappa, alpha, gamma, Vx, p, phit, omega, limits, converge, out):
    """Rows N_FORCES.. of ``out``: radii, deflection, stiffnesses, relaxation, used inputs.

    Reads Fx, Fy, Kxk, Kya from the rows the forces loop wrote. ``converge``: omega and Re
    iterated per sample as for the turn-slip spin (see :func:`.vertical.rolling_state`).
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
        Re, Romega, w = rolling_state(P, uFz, kappa[i], Vx[i], dpi, omega[i], converge)
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


def evaluate_batch(
    P: F64,
    Fz: F64,
    kappa: F64,
    alpha: F64,
    gamma: F64,
    Vx: F64,
    p: F64,
    T: F64,
    phit: F64,
    omega: F64,
    limits: bool,
    out: F64,
    turn_slip: bool = False,
    alpha_star: bool = False,
    moments: bool = True,
) -> None:
    """Evaluate every sample i of the 1-D input arrays into column i of ``out``.

    ``out`` has ``N_FORCES`` rows (forces and moments only) or ``N_OUT`` rows (everything).
    ``turn_slip``, ``alpha_star``: MFeval's useMode units and tens digits 2 (see
    :meth:`TireModel.evaluate`); either runs :func:`forces_loop_modes`. ``moments`` False:
    Mx, My, Mz, t and Mzr are not computed (NaN).
    """
    limits, turn_slip, alpha_star = bool(limits), bool(turn_slip), bool(alpha_star)
    moments = bool(moments)
    if turn_slip or alpha_star:
        forces_loop_modes(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, omega, limits, turn_slip,
                          alpha_star, out, moments)  # fmt: skip
    else:
        forces_loop(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, limits, out, moments)
    if out.shape[0] >= N_OUT:
        extras_loop(P, Fz, kappa, alpha, gamma, Vx, p, phit, omega, limits, turn_slip, out)


@standalone
def evaluate_point(P, Fz, kappa, alpha, gamma, Vx, p, T, limits):
    """(Fx, Fy, Fz, Mx, My, Mz) of one sample: the batch stages on a block of one."""
    x = np.empty((8, 1))  # rows: the batch inputs, phit = 0
    for k, v in enumerate((Fz, kappa, alpha, gamma, Vx, p, T, 0.0)):
        x[k, 0] = v
    out = np.empty((N_FORCES, 1))
    forces_loop(P, x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], limits, out)
    return out[FX, 0], out[FY, 0], out[FZ, 0], out[MX, 0], out[MY, 0], out[MZ, 0]


def warm_up(variants: bool = False) -> None:
    """Compile (or load from the numba cache) every entry point TireModel uses.

    ``variants``: also the turn-slip / alpha* loop (:func:`forces_loop_modes`); by default it is
    compiled on its first use, so that installing and the plain path do not pay for it.
    """
    P = np.zeros(c.N_COEF)
    P[c.FNOMIN] = P[c.NOMPRES] = P[c.NOMTEMP] = P[c.LONGVL] = P[c.UNLOADED_RADIUS] = 1.0
    P.setflags(write=False)  # the types TireModel passes: read-only P, writable inputs
    x = np.ones(1)
    for limits in (True, False):
        evaluate_batch(P, x, x, x, x, x, x, x, x, x * math.nan, limits, np.empty((N_OUT, 1)))
        evaluate_point(P, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, limits)
        if variants:
            evaluate_batch(P, x, x, x, x, x, x, x, x, x * math.nan, limits,
                           np.empty((N_OUT, 1)), turn_slip=True, alpha_star=True)  # fmt: skip
