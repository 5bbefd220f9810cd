"""Vertical and structural quantities: rolling radii, deflection, contact patch, relaxation.

Besselink, Schmeitz, Pacejka (2010) "An improved Magic Formula/Swift tyre model that can handle
inflation pressure changes", eqs. (1)-(10), (17)-(19), as MFeval 4.3.1 evaluates them; MF 6.2
solves the loaded radius from the MF-Swift 6.2 vertical force (secant iteration).
"""

from __future__ import annotations

import math

from . import coef as c
from .jit import standalone


@standalone
def Cz_vertical_stiffness(P, dpi: float) -> float:
    """Vertical stiffness at the inflation pressure, Cz0 (1 + PFZ1 dpi) (paper eq. 5) [N/m]."""
    return P[c.VERTICAL_STIFFNESS] * (1.0 + P[c.PFZ1] * dpi)


@standalone
def Romega_free_radius(P, omega: float) -> float:
    """Free-rolling radius with centrifugal growth R0 (Q_RE0 + Q_V1 (omega R0/V0)^2) (eq. 1) [m]."""
    R0 = P[c.UNLOADED_RADIUS]
    w = omega * R0 / P[c.LONGVL]
    return R0 * (P[c.Q_RE0] + P[c.Q_V1] * w * w)


@standalone
def Re_effective_radius(P, omega: float, Fz: float, dpi: float) -> float:
    """Effective rolling radius Re (eq. 7) [m]."""
    Fz0 = P[c.FNOMIN]
    return Romega_free_radius(P, omega) - (Fz0 / Cz_vertical_stiffness(P, dpi)) * (
        P[c.DREFF] * math.atan(P[c.BREFF] * Fz / Fz0) + P[c.FREFF] * Fz / Fz0
    )


RE_TOL = 1e-9  # MFeval's stopping test on the change of Re [m]
RE_MAX_PASSES = 20  # never reached by a finite input (4 passes at most on the oracle grids)


@standalone
def rolling_state(P, uFz, kappa_raw, Vx, dpi, omega_in, converge=False):
    """Wheel speed and effective rolling radius.

    With ``omega_in`` given (finite) Re follows from it; otherwise omega = (1 + kappa) Vx / Re
    (book eq. 2.5) and Re are updated from Re = 0.965 R0. By default twice, as MFeval 4.3.1 does
    on most batches (it stops when the change of Re is below 1e-9 in *every* row of the batch,
    usually after two passes; the Q_V1 speed term makes the fixed point differ slightly at high
    speed). ``converge``: until the change of this sample's Re is at most 1e-9, which is
    MFeval's test on a batch of one (the turn-slip path: the spin phi depends on omega).

    Returns
    -------
    (Re [m], Romega [m], omega [rad/s])
    """
    if not math.isnan(omega_in):
        omega = omega_in + 1e-15  # MFeval: never exactly zero
        return Re_effective_radius(P, omega, uFz, dpi), Romega_free_radius(P, omega), omega
    Re = P[c.UNLOADED_RADIUS] * 0.965
    omega = 0.0
    if converge:
        Re_old = P[c.UNLOADED_RADIUS]
        for _ in range(RE_MAX_PASSES):
            if not abs(Re_old - Re) > RE_TOL:
                break
            Re_old = Re
            omega = (kappa_raw * Vx + Vx) / Re
            Re = Re_effective_radius(P, omega, uFz, dpi)
    else:
        for _ in range(2):
            omega = (kappa_raw * Vx + Vx) / Re
            Re = Re_effective_radius(P, omega, uFz, dpi)
    return Re, Romega_free_radius(P, omega), omega


@standalone
def Q_FZ1_linear(P) -> float:
    """Linear load-deflection coefficient from Cz0: Q_FZ1 = sqrt((Cz0 R0/Fz0)^2 - 4 Q_FZ2)."""
    a = P[c.VERTICAL_STIFFNESS] * P[c.UNLOADED_RADIUS] / P[c.FNOMIN]
    return math.sqrt(max(a * a - 4.0 * P[c.Q_FZ2], 0.0))


@standalone
def deflection_61(P, Fz, dpi, omega, Romega, Fx, Fy):
    """Deflection rho and loaded radius Rl from the MF 6.1 vertical force (eq. 4, inverted).

    Returns
    -------
    (rho [m], Rl [m], Cz [N/m])
    """
    R0 = P[c.UNLOADED_RADIUS]
    Fz0 = P[c.FNOMIN]
    Q_FZ2 = P[c.Q_FZ2]
    Q_FZ1 = Q_FZ1_linear(P)
    fcorr = (
        (
            1.0
            + P[c.Q_V2] * (R0 / P[c.LONGVL]) * abs(omega)
            - (P[c.Q_FCX] * Fx / Fz0) ** 2
            - (P[c.Q_FCY] * Fy / Fz0) ** 2
        )
        * (1.0 + P[c.PFZ1] * dpi)
        * Fz0
    )
    rhs = Fz / max(fcorr, 1e-15)
    if Q_FZ2 != 0.0:
        x = (-Q_FZ1 + math.sqrt(max(Q_FZ1 * Q_FZ1 + 4.0 * Q_FZ2 * rhs, 0.0))) / (2.0 * Q_FZ2)
    else:
        x = rhs / Q_FZ1
    rho = max(x * R0, 0.0)
    Rl = max(Romega - rho, 0.0)
    if Fz == 0.0:
        rho = 1e-6
    return rho, Rl, Fz / rho


@standalone
def Fz_62(P, Rl, gamma, omega, Romega, dpi, Fx, Fy):
    """MF 6.2 vertical force at loaded radius Rl (MF-Swift 6.2 manual) and its deflection."""
    R0 = P[c.UNLOADED_RADIUS]
    Fz0 = P[c.FNOMIN]
    Q_CAM1, Q_CAM2, Q_CAM3 = P[c.Q_CAM1], P[c.Q_CAM2], P[c.Q_CAM3]
    ratio = Rl / Romega
    Sfyg = (P[c.Q_FYS1] + P[c.Q_FYS2] * ratio + P[c.Q_FYS3] * ratio * ratio) * gamma
    rho_zfr = max(Romega - Rl, 0.0)
    rtw = (1.075 - 0.5 * P[c.ASPECT_RATIO]) * P[c.WIDTH]
    num = (Q_CAM1 * Rl + Q_CAM2 * Rl * Rl) * gamma
    den = (Q_CAM1 * Romega + Q_CAM2 * Romega * Romega) * gamma
    if den == 0.0:
        rho_zg = 0.0
    else:
        rho_zg = (num / den) ** 2 * (rtw / 8.0) * abs(math.tan(gamma)) - Q_CAM3 * rho_zfr * abs(
            gamma
        )
    rho_z = max(rho_zfr + rho_zg, 1e-12)
    fcorr = (
        1.0
        + P[c.Q_V2] * (R0 / P[c.LONGVL]) * abs(omega)
        - (P[c.Q_FCX] * Fx / Fz0) ** 2
        - ((rho_z / R0) ** P[c.Q_FCY2] * P[c.Q_FCY] * (Fy - Sfyg) / Fz0) ** 2
    ) * (1.0 + P[c.PFZ1] * dpi)
    x = rho_z / R0
    return fcorr * (Q_FZ1_linear(P) * x + P[c.Q_FZ2] * x * x) * Fz0, rho_z


@standalone
def deflection_62(P, uFz, Fz, gamma, dpi, omega, Romega, Fx, Fy):
    """Loaded radius of MF 6.2 by secant iteration on Fz_62(Rl) = uFz.

    Returns
    -------
    (rho [m], Rl [m], Cz [N/m])
    """
    R0 = P[c.UNLOADED_RADIUS]
    tol = P[c.FNOMIN] * 1e-6
    x0 = R0 * 0.95
    x1 = R0
    y0 = Fz_62(P, x0, gamma, omega, Romega, dpi, Fx, Fy)[0] - uFz
    y1 = Fz_62(P, x1, gamma, omega, Romega, dpi, Fx, Fy)[0] - uFz
    x = x1
    for _ in range(18):
        dy = y1 - y0
        if abs(dy) < 1e-15:
            break
        x = x1 - (x1 - x0) / dy * y1
        y = Fz_62(P, x, gamma, omega, Romega, dpi, Fx, Fy)[0] - uFz
        if abs(y) <= tol:
            break
        if abs(y1) < abs(y0):
            x0, y0 = x1, y1
        x1, y1 = x, y
    rho = Fz_62(P, x, gamma, omega, Romega, dpi, Fx, Fy)[1]
    if Fz == 0.0:
        rho = 1e-6
    return rho, x, Fz / rho


@standalone
def contact_patch(P, uFz: float, dpi: float, is_mf52: bool):
    """Contact patch length 2a and width 2b (paper eqs. 9, 10; MF 5.2: Q_A1, Q_A2) [m]."""
    R0 = P[c.UNLOADED_RADIUS]
    w = P[c.WIDTH]
    Fz0 = P[c.FNOMIN]
    NCz = Cz_vertical_stiffness(P, dpi)
    Fz = uFz
    if R0 - uFz / NCz - (P[c.RIM_RADIUS] + P[c.BOTTOM_OFFST]) < 0.0:  # bottoming
        Fz = (R0 - P[c.RIM_RADIUS] - P[c.BOTTOM_OFFST]) * NCz
    if is_mf52:
        Q_A1, Q_A2 = P[c.Q_A1], P[c.Q_A2]
        if Q_A1 == 0.0 and Q_A2 == 0.0:
            y = math.log10(R0 * P[c.VERTICAL_STIFFNESS] / Fz0)
            Q_A1 = -0.0388 * y**3 + 0.2509 * y**2 - 0.6283 * y + 0.6279
            Q_A2 = 1.693 * Q_A1 * Q_A1
        a = R0 * (Q_A2 * (Fz / Fz0) + Q_A1 * math.sqrt(Fz / Fz0))
        b = 0.5 * w
    else:
        n = Fz / (NCz * R0)
        a = R0 * (P[c.Q_RA2] * n + P[c.Q_RA1] * math.sqrt(n))
        b = w * (P[c.Q_RB2] * n + P[c.Q_RB1] * n ** (1.0 / 3.0))
    return 2.0 * a, 2.0 * b


@standalone
def relaxation(P, Fz, dfz, dpi, gamma, Kxk, Kya, is_mf52):
    """Carcass stiffnesses Cx, Cy (paper eqs. 17, 18) and relaxation lengths (eq. 19).

    MF 5.2 uses the PTX/PTY relaxation-length coefficients of the MF-Tyre 5.2 manual.

    Returns
    -------
    (Cx [N/m], Cy [N/m], sigmax [m], sigmay [m])
    """
    Cx = (
        P[c.LONGITUDINAL_STIFFNESS]
        * (1.0 + P[c.PCFX1] * dfz + P[c.PCFX2] * dfz * dfz)
        * (1.0 + P[c.PCFX3] * dpi)
    )
    Cy = (
        P[c.LATERAL_STIFFNESS]
        * (1.0 + P[c.PCFY1] * dfz + P[c.PCFY2] * dfz * dfz)
        * (1.0 + P[c.PCFY3] * dpi)
    )
    if is_mf52:
        R0 = P[c.UNLOADED_RADIUS]
        Fz0 = P[c.FNOMIN]
        Fz0p = P[c.LFZO] * Fz0
        sigmax = (
            (P[c.PTX1] + P[c.PTX2] * dfz) * math.exp(-P[c.PTX3] * dfz) * P[c.LSGKP] * R0 * Fz / Fz0
        )
        sigmay = (
            P[c.PTY1]
            * math.sin(2.0 * math.atan(Fz / (P[c.PTY2] * Fz0p)))
            * (1.0 - P[c.PKY3] * abs(gamma))
            * R0
            * P[c.LFZO]
            * P[c.LSGAL]
        )
        return Cx, Cy, sigmax, sigmay
    return Cx, Cy, abs(Kxk / Cx), abs(Kya / Cy)
