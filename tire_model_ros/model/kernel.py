"""The Magic Formula over arrays of samples: stage loops over blocks that LLVM vectorises.

The equations are scalar kernels (:mod:`.forces`, :mod:`.moments`, :mod:`.conditions`), inlined
into one loop per stage; a stage keeps what later stages need in a scratch block. The same
code serves :meth:`TireModel.evaluate` (blocks of ``BLOCK`` samples) and
:meth:`TireModel.evaluate_one` (a block of one, per ROS message). Output rows of the batch array:
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
from .jit import kernel, standalone
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


# Rows of the scratch block: what a stage passes on to later stages.
# Rows 0..N_FORCES-1 hold the outputs (FX..MZR) until they are copied to the output array.
(S_FZ, S_KAPPA, S_ALPHA, S_GAMMA, S_P, S_FZ_MZ, S_RED, S_DFZ, S_DPI, S_DT, S_COS_AP,
 S_FX0, S_FY0, S_FY0_G0, S_SHY, S_SVY, S_BY, S_CY, S_SVYK,
 S_FY_PRIME) = range(N_FORCES, N_FORCES + 20)  # fmt: skip
N_SCRATCH = N_FORCES + 20
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
    o[9, j] = temperature_increment(P, T[i])
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
            s[S_DT, j], s[S_RED, j], limits,
        )  # fmt: skip
    return o


@standalone
def _lateral_stage(P, limits, mf52, n, s):
    """Pure-slip Fy0, the shifts, muy and Kya (4.E19)-(4.E30), LAT_ROWS."""
    o = np.empty((len(LAT_ROWS), BLOCK))
    for j in range(n):
        Fy0, muy, Kya, SHy, SVy, By, Cy = Fy0_pure(
            P, s[S_FZ, j], s[S_ALPHA, j], s[S_GAMMA, j], s[S_DFZ, j], s[S_DPI, j], s[S_DT, j],
            s[S_RED, j], limits, mf52,
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
            s[S_RED, j], limits, mf52,
        )[0]  # fmt: skip
    return o


@standalone
def _combined_stage(P, limits, n, s):
    """Combined-slip Fx (4.E50), Fy (4.E58), SVyk and Fy' (Gyk keeps the camber, as MFeval)."""
    o = np.empty((len(COMB_ROWS), BLOCK))
    for j in range(n):
        kappa_, alpha_, gamma_, dfz = s[S_KAPPA, j], s[S_ALPHA, j], s[S_GAMMA, j], s[S_DFZ, j]
        Gyk = Gyk_weighting(P, kappa_, alpha_, gamma_, dfz, limits)
        SVyk = SVyk_shift(P, s[S_FZ, j], kappa_, alpha_, gamma_, dfz, s[MUY, j], s[S_RED, j])
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
        o[0, j], o[1, j], o[2, j] = Mz_aligning(
            P, s[S_FZ_MZ, j], s[S_DFZ, j], s[S_DPI, j], s[S_KAPPA, j], s[S_ALPHA, j],
            s[S_GAMMA, j], Vx[i], s[S_COS_AP, j], limits, mf52, s[KXK, j], s[KYA, j],
            s[S_SHY, j], s[S_SVY, j], s[S_BY, j], s[S_CY, j], s[FX, j], s[FY, j],
            s[S_SVYK, j], s[S_FY_PRIME, j], s[S_RED, j],
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
def _zero_camber(s, n) -> bool:
    """Whether the camber used by samples 0..n-1 of the block is +0.0 (not -0.0) throughout."""
    for j in range(n):
        g = s[S_GAMMA, j]
        if g != 0.0 or math.copysign(1.0, g) < 0.0:
            return False
    return True


@standalone
def forces_loop(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, limits, out):
    """Rows 0..N_FORCES-1 of ``out`` for every sample, block by block, stage by stage."""
    mf52 = is_mf52(P)
    s = np.empty((N_SCRATCH, BLOCK))
    for i0 in range(0, Fz.shape[0], BLOCK):
        n = min(BLOCK, Fz.shape[0] - i0)
        o = _conditions_stage(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, limits, i0, n)
        _keep(s, COND_ROWS, o, n)
        _keep(s, LONG_ROWS, _longitudinal_stage(P, Vx, limits, i0, n, s), n)
        _keep(s, LAT_ROWS, _lateral_stage(P, limits, mf52, n, s), n)
        if _zero_camber(s, n):  # Fy0 at zero camber is Fy0 itself: the same call, bit for bit
            s[S_FY0_G0, :n] = s[S_FY0, :n]
        else:
            _keep(s, LAT_G0_ROWS, _lateral_zero_camber_stage(P, limits, mf52, n, s), n)
        _keep(s, COMB_ROWS, _combined_stage(P, limits, n, s), n)
        _keep(s, MZ_ROWS, _aligning_stage(P, Vx, limits, mf52, i0, n, s), n)
        _keep(s, MOM_ROWS, _moments_stage(P, kappa, Vx, mf52, i0, n, s), n)
        for k in range(N_FORCES):
            out[k, i0 : i0 + n] = s[k, :n]


@standalone
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
    forces_loop(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, bool(limits), out)
    if out.shape[0] >= N_OUT:
        extras_loop(P, Fz, kappa, alpha, gamma, Vx, p, phit, omega, bool(limits), out)


@standalone
def evaluate_point(P, Fz, kappa, alpha, gamma, Vx, p, T, limits):
    """(Fx, Fy, Fz, Mx, My, Mz) of one sample: the batch stages on a block of one."""
    x = np.empty((8, 1))  # rows: the batch inputs, phit = 0
    for k, v in enumerate((Fz, kappa, alpha, gamma, Vx, p, T, 0.0)):
        x[k, 0] = v
    out = np.empty((N_FORCES, 1))
    forces_loop(P, x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], limits, out)
    return out[FX, 0], out[FY, 0], out[FZ, 0], out[MX, 0], out[MY, 0], out[MZ, 0]


def warm_up() -> None:
    """Compile (or load from the numba cache) every entry point TireModel uses."""
    P = np.zeros(c.N_COEF)
    P[c.FNOMIN] = P[c.NOMPRES] = P[c.NOMTEMP] = P[c.LONGVL] = P[c.UNLOADED_RADIUS] = 1.0
    P.setflags(write=False)  # the types TireModel passes: read-only P, writable inputs
    x = np.ones(1)
    for limits in (True, False):
        evaluate_batch(P, x, x, x, x, x, x, x, x, x * math.nan, limits, np.empty((N_OUT, 1)))
        evaluate_point(P, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, limits)
