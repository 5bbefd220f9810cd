"""Magic Formula moments: overturning Mx, rolling resistance My, aligning torque Mz.

Mx: TNO MF-Tyre manual form with QSX1-QSX14 (Besselink et al. 2010, eq. 49).
My: TNO form (Pacejka 2012 appendix 3, eq. A48) with Fz0 and (p/NOMPRES)^QSY8, and MFeval's
empirical low-speed treatment. Mz: (4.E31)-(4.E49), (4.E71)-(4.E78) with the paper forms
(A54)-(A60) that MFeval 4.3.1 uses (peak trail with gamma, not |gamma|; t scaled by LFZO), and
the turn-slip factors zeta0, zeta2, zeta5-zeta8 of :mod:`.turnslip` (book §4.3.3).
"""

from __future__ import annotations

import math

from . import coef as c
from . import vmath as vm
from .conditions import EPS, cos_atan, nominal_load, sign0, sign1
from .forces import weighting
from .jit import kernel
from .turnslip import residual_cos


@kernel
def low_load_ratio(P, Fz: float) -> float:
    """Fz/FZMIN below FZMIN, else 1: Mx and My fade the load out as Fz (Fz/FZMIN)^power.

    MFeval's empirical TNO choice, with the integer powers 2 (Mx) and 1 (My): plain
    multiplications by this ratio, where a pow would cost an exp and a log per sample.
    """
    FZMIN = P[c.FZMIN]
    if FZMIN > 0.0 and Fz < FZMIN:
        return Fz / FZMIN
    return 1.0


@kernel
def Mx_overturning(P, Fz: float, gamma: float, dpi: float, Fy: float) -> float:
    """Overturning couple Mx, TNO form (Besselink 2010 eq. 49, Pacejka 4.E69 extended) [N m]."""
    r = low_load_ratio(P, Fz)
    Fz = Fz * (r * r)
    R0 = P[c.UNLOADED_RADIUS]
    Fz0 = P[c.FNOMIN]
    return R0 * Fz * P[c.LMX] * (
        P[c.QSX1] * P[c.LVMX]
        - P[c.QSX2] * gamma * (1.0 + P[c.PPMX1] * dpi)
        + P[c.QSX3] * (Fy / Fz0)
        + P[c.QSX4]
        * vm.cos(P[c.QSX5] * vm.atan((P[c.QSX6] * Fz / Fz0) * (P[c.QSX6] * Fz / Fz0)))
        * vm.sin(P[c.QSX7] * gamma + P[c.QSX8] * vm.atan(P[c.QSX9] * Fy / Fz0))
        + P[c.QSX10] * vm.atan(P[c.QSX11] * Fz / Fz0) * gamma
    ) + R0 * P[c.LMX] * (
        Fy * (P[c.QSX13] + P[c.QSX14] * abs(gamma)) - Fz * P[c.QSX12] * gamma * abs(gamma)
    )


@kernel
def My_rolling_resistance(P, uFz, kappa_raw, gamma, Vx, p, Fx, is_mf52) -> float:
    """Rolling resistance moment My, TNO form (A48); MF 5.2 manual form for FITTYP 6 [N m].

    ``uFz`` and ``kappa_raw`` are the load and slip ratio before saturation (as in MFeval).
    Near standstill MFeval fades My with the slip ratio (empirical TNO behaviour), reverses it
    for driving backwards and sets it to zero at Vx = 0.
    """
    Fz = uFz * low_load_ratio(P, uFz)
    R0 = P[c.UNLOADED_RADIUS]
    Fz0 = P[c.FNOMIN]
    V0 = P[c.LONGVL]
    v = Vx / V0
    v4 = (v * v) * (v * v)
    speed_terms = P[c.QSY1] + P[c.QSY2] * (Fx / Fz0) + P[c.QSY3] * abs(v) + P[c.QSY4] * v4
    if is_mf52:
        My = -R0 * Fz * P[c.LMY] * speed_terms
    else:
        My = (
            -R0
            * Fz0
            * P[c.LMY]
            * (speed_terms + (P[c.QSY5] + P[c.QSY6] * (Fz / Fz0)) * gamma * gamma)
            * (vm.pow(Fz / Fz0, P[c.QSY7]) * vm.pow(p / P[c.NOMPRES], P[c.QSY8]))
        )
    # Written as selects, not branches, so that the sample loop vectorises (the factors are
    # +-1 or the ramp: the products are those of the branches, bit for bit).
    high = P[c.VXLOW] / abs(Vx) - 1.0
    low = -1.0 - P[c.VXLOW] - high
    # sin ramp from 0 at kappa = -1 (wheel locked) to 1 at kappa = high
    ramp = vm.sin(0.5 * math.pi * (kappa_raw + 1.0) / (high + 1.0))
    fade = ramp if low <= kappa_raw <= high else (-1.0 if kappa_raw < low else 1.0)
    backwards = -1.0 if Vx < 0.0 else 1.0
    My = (My * backwards) * fade
    return 0.0 if Vx == 0.0 else My


@kernel
def Bt_trail_stiffness(P, dfz: float, gamma: float) -> float:
    """Pneumatic-trail stiffness factor Bt (A58; 4.E40 without QBZ6) [1/rad]."""
    return (
        (P[c.QBZ1] + P[c.QBZ2] * dfz + P[c.QBZ3] * dfz * dfz)
        * (1.0 + P[c.QBZ4] * gamma + P[c.QBZ5] * abs(gamma))
        * P[c.LKY]
        / P[c.LMUY]
    )


@kernel
def Dt_trail_peak(P, Fz: float, dfz: float, dpi: float, gamma: float) -> float:
    """Pneumatic-trail peak factor Dt (A60; 4.E43 with gamma, not |gamma|) [m N / N]."""
    return (
        (P[c.QDZ1] + P[c.QDZ2] * dfz)
        * (1.0 - P[c.PPZ1] * dpi)
        * (1.0 + P[c.QDZ3] * gamma + P[c.QDZ4] * gamma * gamma)
        * Fz
        * (P[c.UNLOADED_RADIUS] / nominal_load(P))
        * P[c.LTR]
    )


@kernel
def Et_trail_curvature(P, dfz, gamma, Bt, Ct, alphat, limits) -> float:
    """Pneumatic-trail curvature factor Et (4.E44), clipped at 1 with the limits on."""
    Et = (P[c.QEZ1] + P[c.QEZ2] * dfz + P[c.QEZ3] * dfz * dfz) * (
        1.0 + (P[c.QEZ4] + P[c.QEZ5] * gamma) * (2.0 / math.pi) * vm.atan(Bt * Ct * alphat)
    )
    if limits and Et > 1.0:
        return 1.0
    return Et


@kernel
def Dr_residual_peak(P, Fz, dfz, dpi, gamma, alpha, Vx, zeta0, zeta2) -> float:
    """Residual-torque peak factor Dr (4.E47) without its turn-slip term zeta8 - 1 [N m].

    ``zeta0`` (4.83) multiplies the camber term, ``zeta2`` (4.77) the offset term.
    """
    return (
        Fz
        * P[c.UNLOADED_RADIUS]
        * (
            (P[c.QDZ6] + P[c.QDZ7] * dfz) * P[c.LRES] * zeta2
            + (
                (P[c.QDZ8] + P[c.QDZ9] * dfz) * (1.0 + P[c.PPZ2] * dpi)
                + (P[c.QDZ10] + P[c.QDZ11] * dfz) * abs(gamma)
            )
            * gamma
            * P[c.LKZC]
            * zeta0
        )
        * P[c.LMUY]
        * sign0(Vx)
        * vm.cos(alpha)
    )


@kernel
def equivalent_slip_angle(alpha_x: float, Kxk: float, Kya_prime: float, kappa: float) -> float:
    """Combined-slip equivalent angle (A54), (A55) (the book's 4.E77, 4.E78 in tan form)."""
    ratio = Kxk / Kya_prime * kappa
    tan_a = vm.tan(alpha_x)
    return vm.atan(math.sqrt(tan_a * tan_a + ratio * ratio)) * sign0(alpha_x)


@kernel
def Mz_aligning(
    P, Fz_mz, dfz, dpi, kappa, alpha, gamma, gamma_s, Vx, cos_alpha_p, limits, is_mf52,
    Kxk, Kya, SHy, SVy, By, Cy, Fx, Fy, SVyk, Fy_prime, red_smooth,
    turn_slip, zeta2, zeta5, zeta6, ratio7, Drphi,
):  # fmt: skip
    """Combined-slip aligning torque Mz (4.E71)-(4.E78), (A54)-(A60).

    ``Fy_prime`` is Gyk Fy0 evaluated at zero camber (4.E74); ``Fz_mz`` the load of the
    aligning-torque equations (not below FZMIN with the limits on). ``alpha`` is the slip angle
    of the equations (alpha* in that variant), ``gamma_s`` the camber where MFeval uses gamma*
    (SHt, Et, Dr), ``gamma`` where it keeps gamma (Bt, Dt, s).

    Turn slip (``turn_slip``): zeta5 (4.91) on Dt, zeta6 (4.102) on Br, zeta0 = 0 and zeta2 in
    Dr, zeta8 - 1 = ``Drphi`` added to Dr, and Cr = zeta7 given by ``ratio7`` (see
    :func:`.turnslip.zeta7_zeta8`); the plain model passes 1 for the factors.

    Returns
    -------
    (Mz [N m], t [m], Mzr [N m])
    """
    R0 = P[c.UNLOADED_RADIUS]
    Kya_prime = Kya + EPS * sign1(Kya)  # (4.E39)
    SHf = SHy + SVy / Kya_prime  # (4.E38)
    alphar = alpha + SHf  # (4.E37)
    SHt = P[c.QHZ1] + P[c.QHZ2] * dfz + (P[c.QHZ3] + P[c.QHZ4] * dfz) * gamma_s  # (4.E35)
    alphat = alpha + SHt  # (4.E34)
    Bt = Bt_trail_stiffness(P, dfz, gamma)
    Ct = P[c.QCZ1]  # (4.E41)
    Dt = Dt_trail_peak(P, Fz_mz, dfz, dpi, gamma) * zeta5
    Et = Et_trail_curvature(P, dfz, gamma_s, Bt, Ct, alphat, limits)
    Br = (P[c.QBZ9] * P[c.LKY] / P[c.LMUY] + P[c.QBZ10] * By * Cy) * zeta6  # (4.E45)
    zeta0 = 0.0 if turn_slip else 1.0  # (4.83)
    Dr = Dr_residual_peak(P, Fz_mz, dfz, dpi, gamma_s, alpha, Vx, zeta0, zeta2)
    if turn_slip:
        Dr = Dr + Drphi  # (4.E47): + zeta8 - 1
    alphar_eq = equivalent_slip_angle(alphar, Kxk, Kya_prime, kappa)  # (A54)
    alphat_eq = equivalent_slip_angle(alphat, Kxk, Kya_prime, kappa)  # (A55)
    s = (
        R0
        * (P[c.SSZ1] + P[c.SSZ2] * (Fy / P[c.FNOMIN]) + (P[c.SSZ3] + P[c.SSZ4] * dfz) * gamma)
        * P[c.LS]
    )  # (A56)
    # (4.E75): Cr = zeta7 with turn slip, else 1
    Mzr = Dr * (residual_cos(ratio7, Br * alphar_eq) if turn_slip else cos_atan(Br * alphar_eq))
    t = Dt * weighting(Bt, Ct, Et, alphat_eq) * cos_alpha_p
    t = t * P[c.LFZO]  # (4.E73); the LFZO factor is TNO's (MFeval note)
    t = t * red_smooth
    Mzr = Mzr * red_smooth
    # (4.E71), (4.E72); MF 5.2 (MF-Tyre manual): -t (Fy - SVyk) instead of -t Fy'
    Mz_prime = -t * (Fy - SVyk) if is_mf52 else -t * Fy_prime
    return Mz_prime + Mzr + s * Fx, t, Mzr
