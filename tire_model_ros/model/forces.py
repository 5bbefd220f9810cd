"""Magic Formula forces: pure slip Fx0, Fy0 and combined slip Fx, Fy.

Pacejka, Tire and Vehicle Dynamics, 3rd ed. (2012), §4.3.2, eqs. (4.E9)-(4.E67), with the
TNO-tuned choices of MFeval 4.3.1 (A_mu = 1, LMUV = 0, eps = 1e-6, E factors clipped at 1 only
when the limits are on) and the temperature extension of INTERFACE.md on Kxk, mux, Kya, muy.
The turn-slip factors (zeta1, zeta2, zeta3, SHyp of :mod:`.turnslip`) enter as arguments: the
plain model passes 1 (0 for SHyp, ``turn_slip=False``), which folds away in the compiled loops.
With the alpha* variant (4.E3, 4.E4) the callers pass alpha* = tan(alpha) sgn(Vx) and
gamma* = sin(gamma) where MFeval uses them.
"""

from __future__ import annotations

from . import coef as c
from . import vmath as vm
from .conditions import EPS, cos_atan, nominal_load, sign1
from .jit import kernel


@kernel
def magic_formula(B: float, C: float, D: float, E: float, x: float) -> float:
    """y = D sin(C atan(Bx - E(Bx - atan Bx))) (4.E9, 4.E19 without the shift)."""
    Bx = B * x
    return D * vm.sin(C * vm.atan(Bx - E * (Bx - vm.atan(Bx))))


@kernel
def weighting(B: float, C: float, E: float, x: float) -> float:
    """Cosine weighting cos(C atan(Bx - E(Bx - atan Bx))) of (4.E51), (4.E59)."""
    Bx = B * x
    return vm.cos(C * vm.atan(Bx - E * (Bx - vm.atan(Bx))))


@kernel
def temperature_quadratic(a1: float, a2: float, dT: float) -> float:
    """Temperature factor 1 + a1 dT + a2 dT^2 of the INTERFACE.md extension."""
    return 1.0 + a1 * dT + a2 * dT * dT


# --- longitudinal, pure slip -------------------------------------------------------------


@kernel
def mux_peak(P, Fz: float, dfz: float, dpi: float, gamma: float, dT: float) -> float:
    """Longitudinal friction coefficient mux (4.E13) x (1 + TTX3 dT + TTX4 dT^2); 0 at Fz = 0."""
    if Fz == 0.0:
        return 0.0
    mux = (
        (P[c.PDX1] + P[c.PDX2] * dfz)
        * (1.0 + P[c.PPX3] * dpi + P[c.PPX4] * dpi * dpi)
        * (1.0 - P[c.PDX3] * gamma * gamma)
        * P[c.LMUX]
    )
    return mux * temperature_quadratic(P[c.TTX3], P[c.TTX4], dT)


@kernel
def Kxk_slip_stiffness(P, Fz: float, dfz: float, dpi: float, dT: float) -> float:
    """Longitudinal slip stiffness Kxk (4.E15) x (1 + TTX1 dT + TTX2 dT^2) [N]."""
    Kxk = (
        Fz
        * (P[c.PKX1] + P[c.PKX2] * dfz)
        * vm.exp(P[c.PKX3] * dfz)
        * (1.0 + P[c.PPX1] * dpi + P[c.PPX2] * dpi * dpi)
        * P[c.LKX]
    )
    return Kxk * temperature_quadratic(P[c.TTX1], P[c.TTX2], dT)


@kernel
def Ex_curvature(P, dfz: float, kappax: float, limits: bool) -> float:
    """Longitudinal curvature factor Ex (4.E14), clipped at 1 with the limits on."""
    Ex = (
        (P[c.PEX1] + P[c.PEX2] * dfz + P[c.PEX3] * dfz * dfz)
        * (1.0 - P[c.PEX4] * sign1(kappax))
        * P[c.LEX]
    )
    if limits and Ex > 1.0:
        return 1.0
    return Ex


@kernel
def Fx0_pure(P, Fz, kappa, gamma, Vx, dfz, dpi, dT, red_smooth, limits, zeta1):
    """Pure longitudinal force Fx0 (4.E9)-(4.E18); ``zeta1`` the turn-slip factor (4.105).

    Returns
    -------
    (Fx0 [N], mux [-], Kxk [N])
    """
    Cx = P[c.PCX1] * P[c.LCX]  # (4.E11)
    mux = mux_peak(P, Fz, dfz, dpi, gamma, dT)
    Dx = mux * Fz * zeta1  # (4.E12)
    Kxk = Kxk_slip_stiffness(P, Fz, dfz, dpi, dT)
    Bx = Kxk / (Cx * Dx + EPS * sign1(Dx))  # (4.E16)
    SHx = (P[c.PHX1] + P[c.PHX2] * dfz) * P[c.LHX] * red_smooth  # (4.E17), low-speed reduced
    SVx = Fz * (P[c.PVX1] + P[c.PVX2] * dfz) * P[c.LVX] * P[c.LMUX] * zeta1  # (4.E18)
    SVx = SVx * red_smooth
    kappax = kappa + SHx  # (4.E10)
    Ex = Ex_curvature(P, dfz, kappax, limits)
    Fx0 = magic_formula(Bx, Cx, Dx, Ex, kappax) + SVx  # (4.E9)
    if Vx < 0.0:  # driving backwards: the force follows the direction of travel
        Fx0 = -Fx0
    return Fx0, mux, Kxk


# --- lateral, pure slip --------------------------------------------------------------------


@kernel
def muy_peak(P, Fz: float, dfz: float, dpi: float, gamma: float, dT: float) -> float:
    """Lateral friction coefficient muy (4.E23) x (1 + TTY3 dT + TTY4 dT^2); 0 at Fz = 0."""
    if Fz == 0.0:
        return 0.0
    muy = (
        (P[c.PDY1] + P[c.PDY2] * dfz)
        * (1.0 + P[c.PPY3] * dpi + P[c.PPY4] * dpi * dpi)
        * (1.0 - P[c.PDY3] * gamma * gamma)
        * P[c.LMUY]
    )
    return muy * temperature_quadratic(P[c.TTY3], P[c.TTY4], dT)


@kernel
def Kya_cornering_stiffness(P, Fz: float, dpi: float, gamma: float, dT: float) -> float:
    """Cornering stiffness Kya (4.E25) with the temperature terms of INTERFACE.md [N/rad].

    Kya = PKY1 Fz0' (1+PPY1 dpi)(1+TTY1 dT)(1-PKY3|g|)
          sin(PKY4 atan((Fz/Fz0') / ((PKY2+PKY5 g^2)(1+PPY2 dpi)(1+TTY2 dT)))) LKY
    """
    Fz0p = nominal_load(P)
    load_term = (
        (P[c.PKY2] + P[c.PKY5] * gamma * gamma) * (1.0 + P[c.PPY2] * dpi) * (1.0 + P[c.TTY2] * dT)
    )
    return (
        P[c.PKY1]
        * Fz0p
        * (1.0 + P[c.PPY1] * dpi)
        * (1.0 + P[c.TTY1] * dT)
        * (1.0 - P[c.PKY3] * abs(gamma))
        * vm.sin(P[c.PKY4] * vm.atan((Fz / Fz0p) / load_term))
        * P[c.LKY]
    )


@kernel
def Kyg0_camber_stiffness(P, Fz: float, dfz: float, dpi: float, is_mf52: bool) -> float:
    """Camber stiffness Kyg0 (4.E30); MF 5.2: PHY3 Kya0 + Fz(PVY3 + PVY4 dfz) (MF-Tyre 5.2)."""
    if is_mf52:
        Fz0p = nominal_load(P)
        Kya0 = P[c.PKY1] * Fz0p * vm.sin(P[c.PKY4] * vm.atan(Fz / (P[c.PKY2] * Fz0p)))
        return (P[c.PHY3] * Kya0 + Fz * (P[c.PVY3] + P[c.PVY4] * dfz)) * P[c.LKYC]
    return Fz * (P[c.PKY6] + P[c.PKY7] * dfz) * (1.0 + P[c.PPY5] * dpi) * P[c.LKYC]


@kernel
def Ey_curvature(P, dfz: float, gamma: float, alphay: float, limits: bool) -> float:
    """Lateral curvature factor Ey (4.E24), clipped at 1 with the limits on."""
    Ey = (
        (P[c.PEY1] + P[c.PEY2] * dfz)
        * (1.0 + P[c.PEY5] * gamma * gamma - (P[c.PEY3] + P[c.PEY4] * gamma) * sign1(alphay))
        * P[c.LEY]
    )
    if limits and Ey > 1.0:
        return 1.0
    return Ey


@kernel
def Fy0_pure(P, Fz, alpha, gamma, dfz, dpi, dT, red_smooth, limits, is_mf52,
             turn_slip, zeta2, zeta3, SHyp):  # fmt: skip
    """Pure lateral force Fy0 (4.E19)-(4.E30).

    Turn slip: ``zeta2`` (4.77) scales Dy, SVy and SVyg, ``zeta3`` (4.79) Kya; with
    ``turn_slip`` the camber term of SHy goes (zeta0 = 0, 4.83) and zeta4 = 1 + SHyp - SVyg/Kya'
    (4.84) shifts it (MF 6.x; the MF 5.2 SHy keeps its form, as in MFeval).

    Returns
    -------
    (Fy0 [N], muy [-], Kya [N/rad], SHy [rad], SVy [N], By [1/rad], Cy [-])
    """
    Kya = Kya_cornering_stiffness(P, Fz, dpi, gamma, dT) * zeta3
    SVyg = Fz * (P[c.PVY3] + P[c.PVY4] * dfz) * gamma * P[c.LKYC] * P[c.LMUY] * zeta2  # (4.E28)
    Kyg0 = Kyg0_camber_stiffness(P, Fz, dfz, dpi, is_mf52)
    if is_mf52:
        SHy = (P[c.PHY1] + P[c.PHY2] * dfz) * P[c.LHY] + P[c.PHY3] * gamma * P[c.LKYC]
    else:
        Kya_prime = Kya + EPS * sign1(Kya)  # (4.E39)
        if turn_slip:
            zeta4 = 1.0 + SHyp - SVyg / Kya_prime  # (4.84)
            SHy = (P[c.PHY1] + P[c.PHY2] * dfz) * P[c.LHY] + zeta4 - 1.0  # (4.E27), zeta0 = 0
        else:
            SHy = (P[c.PHY1] + P[c.PHY2] * dfz) * P[c.LHY] + (Kyg0 * gamma - SVyg) / Kya_prime
    SVy = Fz * (P[c.PVY1] + P[c.PVY2] * dfz) * P[c.LVY] * P[c.LMUY] * zeta2 + SVyg  # (4.E29)
    SHy = SHy * red_smooth  # low-speed model
    SVy = SVy * red_smooth
    alphay = alpha + SHy  # (4.E20)
    Cy = P[c.PCY1] * P[c.LCY]  # (4.E21)
    muy = muy_peak(P, Fz, dfz, dpi, gamma, dT)
    Dy = muy * Fz * zeta2  # (4.E22)
    Ey = Ey_curvature(P, dfz, gamma, alphay, limits)
    By = Kya / (Cy * Dy + EPS * sign1(Dy))  # (4.E26)
    Fy0 = magic_formula(By, Cy, Dy, Ey, alphay) + SVy  # (4.E19)
    return Fy0, muy, Kya, SHy, SVy, By, Cy


# --- combined slip -------------------------------------------------------------------------


@kernel
def Gxa_weighting(P, kappa: float, alpha: float, gamma: float, dfz: float, limits: bool):
    """Combined-slip weighting Gxa of Fx (4.E51)-(4.E57)."""
    Cxa = P[c.RCX1]  # (4.E55)
    Exa = P[c.REX1] + P[c.REX2] * dfz  # (4.E56)
    if limits and Exa > 1.0:
        Exa = 1.0
    SHxa = P[c.RHX1]  # (4.E57)
    Bxa = (
        (P[c.RBX1] + P[c.RBX3] * gamma * gamma) * cos_atan(P[c.RBX2] * kappa) * P[c.LXAL]
    )  # (4.E54)
    alphas = alpha + SHxa  # (4.E53)
    return weighting(Bxa, Cxa, Exa, alphas) / weighting(Bxa, Cxa, Exa, SHxa)  # (4.E51), (4.E52)


@kernel
def Gyk_weighting(P, kappa: float, alpha: float, gamma: float, dfz: float, limits: bool):
    """Combined-slip weighting Gyk of Fy (4.E59)-(4.E65)."""
    Cyk = P[c.RCY1]  # (4.E63)
    Eyk = P[c.REY1] + P[c.REY2] * dfz  # (4.E64)
    if limits and Eyk > 1.0:
        Eyk = 1.0
    SHyk = P[c.RHY1] + P[c.RHY2] * dfz  # (4.E65)
    Byk = (
        (P[c.RBY1] + P[c.RBY4] * gamma * gamma)
        * cos_atan(P[c.RBY2] * (alpha - P[c.RBY3]))
        * P[c.LYKA]
    )  # (4.E62)
    kappas = kappa + SHyk  # (4.E61)
    return weighting(Byk, Cyk, Eyk, kappas) / weighting(Byk, Cyk, Eyk, SHyk)  # (4.E59), (4.E60)


@kernel
def SVyk_shift(P, Fz, kappa, alpha, gamma, dfz, muy, red_smooth, zeta2) -> float:
    """Slip-ratio induced side force SVyk (4.E66), (4.E67) [N]; ``zeta2`` of turn slip (4.77)."""
    DVyk = (
        muy
        * Fz
        * (P[c.RVY1] + P[c.RVY2] * dfz + P[c.RVY3] * gamma)
        * cos_atan(P[c.RVY4] * alpha)
        * zeta2
    )  # (4.E67)
    return DVyk * vm.sin(P[c.RVY5] * vm.atan(P[c.RVY6] * kappa)) * P[c.LVYKA] * red_smooth
