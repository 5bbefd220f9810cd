"""Turn slip: the spin phi and the zeta factors of Pacejka 2012 §4.3.3, as MFeval 4.3.1 has them.

The spin phi (4.76) combines the path curvature phit (turn slip) with the camber-induced spin;
the zeta factors scale the Magic Formula with it: zeta1 on Fx0 (4.105), zeta2 on the peak and
the vertical shifts of Fy (4.77), zeta3 on Kya (4.79), zeta4 the horizontal shift SHy through
SHyp (4.80)-(4.89), zeta5 the pneumatic trail (4.91), zeta6 the residual torque's Br (4.102),
zeta7 and zeta8 its shape and the turn-slip moment (4.94)-(4.103). Without turn slip every
zeta is 1; turn slip also sets zeta0 (4.83, the camber terms of SHy and Dr) to 0.

MFeval's choices, which the oracle embeds: phi uses Vc' = |Vc| with Vc' = VXLOW sign(Vx) below
VXLOW (singularity guard, book p. 184) and the sign convention of the ISO z axis (no minus sign
on the camber spin); Kzgr0 (4.99) is QDZ8 QDZ9 dfz + QDZ10 + QDZ11 dfz |gamma| (as MFeval writes
it); the turn-slip moment Drphi and Mzphi90 use phit (not phi); zeta7 = (2/pi) acos(Mzphi90 /
|Drphi|), complex when the ratio exceeds 1 (MFeval then keeps the real part of Mz).

All functions are scalar numba kernels; ``P`` is the coefficient vector of :mod:`.coef`.
"""

from __future__ import annotations

import math

from . import coef as c
from . import vmath as vm
from .conditions import EPS, cos_atan, nominal_load, sign0, sign1
from .jit import kernel

TWO_OVER_PI = 2.0 / math.pi


@kernel
def epsilon_gamma(P, dfz: float) -> float:
    """Camber reduction factor eps_gamma = PECP1 (1 + PECP2 dfz) (4.90) [-]."""
    return P[c.PECP1] * (1.0 + P[c.PECP2] * dfz)


@kernel
def spin_phi(P, phit: float, Vx: float, alpha: float, gamma: float, omega: float,
             eps_gamma: float) -> float:  # fmt: skip
    """Spin phi = (psi_dot - (1 - eps_gamma) omega sin(gamma)) / Vc' (4.75), (4.76) [1/m].

    psi_dot = -phit Vc' (4.75); Vc' = sqrt(Vx^2 + Vsy^2) with Vsy = -tan(alpha)|Vx|, replaced by
    VXLOW sign(Vx) below VXLOW (MFeval, after the MF-Tyre equation manual).
    """
    Vsy = -vm.tan(alpha) * abs(Vx)
    Vc_prime = math.sqrt(Vx * Vx + Vsy * Vsy)
    if abs(Vx) < P[c.VXLOW]:
        Vc_prime = P[c.VXLOW] * sign1(Vx)
    psi_dot = -phit * Vc_prime
    return (1.0 / Vc_prime) * (psi_dot - (1.0 - eps_gamma) * omega * vm.sin(gamma))


@kernel
def zeta1_Fx(P, dfz: float, kappa: float, phi: float) -> float:
    """Turn-slip reduction of the peak Fx, zeta1 = cos(atan(Bxp R0 phi)) (4.105), (4.106)."""
    Bxp = P[c.PDXP1] * (1.0 + P[c.PDXP2] * dfz) * cos_atan(P[c.PDXP3] * kappa)
    return cos_atan(Bxp * P[c.UNLOADED_RADIUS] * phi)


@kernel
def zeta2_Fy(P, dfz: float, alpha: float, phi: float) -> float:
    """Turn-slip reduction of the peak Fy, zeta2 (4.77), (4.78); ``alpha`` as input (not alpha*)."""
    Byp = P[c.PDYP1] * (1.0 + P[c.PDYP2] * dfz) * cos_atan(P[c.PDYP3] * vm.tan(alpha))
    R0phi = P[c.UNLOADED_RADIUS] * abs(phi)
    return cos_atan(Byp * (R0phi + P[c.PDYP4] * math.sqrt(R0phi)))


@kernel
def zeta3_Kya(P, phi: float) -> float:
    """Turn-slip reduction of Kya, zeta3 = cos(atan(PKYP1 R0^2 phi^2)) (4.79)."""
    R0phi = P[c.UNLOADED_RADIUS] * phi
    return cos_atan(P[c.PKYP1] * R0phi * R0phi)


@kernel
def SHyp_shift(P, dfz, Vx, Kyg0, Kya0, phi, eps_gamma, limits) -> float:
    """Spin-induced horizontal shift SHyp of the Fy curve (4.80), (4.85)-(4.89) [rad].

    ``Kyg0`` is the camber stiffness (4.30), ``Kya0`` the cornering stiffness at zero camber
    (with zeta3); EHyp is clipped at 1 with the limits on.
    """
    CHyp = P[c.PHYP1]  # (4.85)
    DHyp = (P[c.PHYP2] + P[c.PHYP3] * dfz) * sign0(Vx)  # (4.86)
    EHyp = P[c.PHYP4]  # (4.87)
    if limits and EHyp > 1.0:
        EHyp = 1.0
    Kya0_prime = Kya0 + EPS * sign1(Kya0)
    KyRp0 = Kyg0 / (1.0 - eps_gamma)  # (4.89)
    BHyp = KyRp0 / (CHyp * DHyp * Kya0_prime)  # (4.88)
    x = BHyp * P[c.UNLOADED_RADIUS] * phi
    return DHyp * vm.sin(CHyp * vm.atan(x - EHyp * (x - vm.atan(x)))) * sign0(Vx)  # (4.80)


@kernel
def zeta5_trail(P, phi: float) -> float:
    """Turn-slip reduction of the pneumatic trail, zeta5 = cos(atan(QDTP1 R0 phi)) (4.91)."""
    return cos_atan(P[c.QDTP1] * P[c.UNLOADED_RADIUS] * phi)


@kernel
def zeta6_residual(P, phi: float) -> float:
    """Turn-slip factor of Br of the residual torque, zeta6 = cos(atan(QBRP1 R0 phi)) (4.102)."""
    return cos_atan(P[c.QBRP1] * P[c.UNLOADED_RADIUS] * phi)


@kernel
def Mzphi_inf(P, Fz: float, muy: float) -> float:
    """Turn-slip moment at large spin Mzphi_inf (4.95), kept positive (1e-6 if not) [N m]."""
    M = (
        P[c.QCRP1] * abs(muy) * P[c.UNLOADED_RADIUS] * Fz * math.sqrt(Fz / nominal_load(P))
        * P[c.LMP]
    )  # fmt: skip
    return 1e-6 if M < 0.0 else M


@kernel
def Kzgr0_camber_torque(P, Fz: float, dfz: float, gamma: float) -> float:
    """Camber torque stiffness Kzgr0 (4.99) in MFeval's form [N m/rad]."""
    return (
        Fz * P[c.UNLOADED_RADIUS]
        * (P[c.QDZ8] * P[c.QDZ9] * dfz + (P[c.QDZ10] + P[c.QDZ11] * dfz * abs(gamma)))
        * P[c.LKZC]
    )  # fmt: skip


@kernel
def zeta7_zeta8(P, Fz, dfz, gamma, muy, Gyk, phit, eps_gamma) -> tuple[float, float]:
    """Residual-torque shape ratio and turn-slip moment Drphi (book §4.3.3, MF-Tyre manual form).

    DDrp (4.94) from Mzphi_inf (4.95) and CDrp (4.96); BDrp = Kzgr0 / (CDrp DDrp (1 - eps_gamma))
    with Kzgr0 (4.99); Drphi = DDrp sin(CDrp atan(BDrp R0 phit)); Mzphi90 (4.103);
    zeta7 = (2/pi) acos(Mzphi90 / |Drphi|), zeta8 = 1 + Drphi (MFeval: "from the manual").
    At phit = 0 the ratio is 0/0 in MFeval (NaN Mz, Mzr); the limit phit -> 0 is used instead,
    (2/pi) QCRP2 Gyk Mzphi_inf |1 - eps_gamma| / |Kzgr0|. At Fz <= 0 (0/0 too): ratio 0
    (zeta7 = 1) and Drphi 0.

    Returns
    -------
    (ratio [-], Drphi [N m])
        ``ratio`` = cos(pi zeta7 / 2), the argument of acos, which may exceed 1 (see
        :func:`residual_cos`); zeta8 - 1 = Drphi.
    """
    if Fz <= 0.0:  # no load, no moment: 1 and 0 (MFeval: 0/0) keep Mz at 0 as without turn slip
        return 0.0, 0.0
    R0 = P[c.UNLOADED_RADIUS]
    Minf = Mzphi_inf(P, Fz, muy)
    CDrp = P[c.QDRP1]  # (4.96)
    DDrp = Minf / vm.sin(0.5 * math.pi * CDrp)  # (4.94)
    Kzgr0 = Kzgr0_camber_torque(P, Fz, dfz, gamma)
    BDrp = Kzgr0 / (CDrp * DDrp * (1.0 - eps_gamma))
    Drphi = DDrp * vm.sin(CDrp * vm.atan(BDrp * R0 * phit))
    if phit == 0.0:
        ratio = TWO_OVER_PI * P[c.QCRP2] * Gyk * Minf * abs(1.0 - eps_gamma) / abs(Kzgr0)
    else:
        Mzphi90 = Minf * TWO_OVER_PI * vm.atan(P[c.QCRP2] * R0 * abs(phit)) * Gyk  # (4.103)
        ratio = Mzphi90 / abs(Drphi)
    return ratio, Drphi


@kernel
def residual_cos(ratio: float, x: float) -> float:
    """cos(Cr atan(x)) of Mzr (4.E75), Cr = zeta7 = (2/pi) acos(ratio) (4.E46); its real part.

    For ratio > 1 acos is imaginary, i acosh(ratio): cos(Cr a) = cosh((2/pi) acosh(ratio) a);
    for ratio < -1, acos = pi - i acosh(-ratio) and the real part is cos(2a) cosh(...). libm
    calls: this path is not vectorised, and the plain loops keep the inlined code small.
    """
    a = math.atan(x)
    if ratio > 1.0:
        return math.cosh(TWO_OVER_PI * math.acosh(ratio) * a)
    if ratio < -1.0:
        return math.cos(2.0 * a) * math.cosh(TWO_OVER_PI * math.acosh(-ratio) * a)
    return math.cos(TWO_OVER_PI * math.acos(ratio) * a)
