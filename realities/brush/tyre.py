"""The brush tyre: a 2-D brush (rows across the width) with its own physics.

Everything here is the generator's own model (see README.md, "Physics"); the Magic Formula is
never used to compute a force. Internal coordinates: xi from the leading edge, u = xi/(2 a_r)
in [0, 1] along each row; positive slips give positive internal stresses; the ISO-W outputs
are Fx = +X, Fy = -Y (a positive slip angle gives a negative Fy), Mz = sum(x*Fy_e - y*Fx_e).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

# ------------------------------------------------------------------------------------------
# tyre parameter vector: names -> indices (module constants are compile-time constants)
# ------------------------------------------------------------------------------------------
TYRE_NAMES = (
    "R0", "FZ0", "P0", "VREF",
    "KZ0", "PFZ", "QA", "B", "PW",
    "C0", "RXY", "NCX", "KC0", "NCC",
    "MU0", "MU1", "MUP1", "MUP2", "RX", "RINF", "VC", "NQ",
    "CAMK", "PGAM", "EGAM", "CLAT", "QSX2",
    "QSY1", "QSY3", "QSY4", "QSY7", "QSY8",
)  # fmt: skip
(R0, FZ0, P0, VREF, KZ0, PFZ, QA, B, PW, C0, RXY, NCX, KC0, NCC,
 MU0, MU1, MUP1, MUP2, RX, RINF, VC, NQ, CAMK, PGAM, EGAM, CLAT, QSX2,
 QSY1, QSY3, QSY4, QSY7, QSY8) = range(len(TYRE_NAMES))  # fmt: skip
N_TYRE = len(TYRE_NAMES)

BRUSH_VERSION = "2"  # bump when the nominal steady-state physics changes (refits model.tir)
NROW = 10  # rows across the width (Gauss-Legendre)
_YR, _WR = np.polynomial.legendre.leggauss(NROW)
_ELL = np.sqrt(1.0 - _YR * _YR)  # elliptic patch: row half-length / a
_S2 = float(np.sum(_WR * _ELL * _ELL))
_AREA = float(np.sum(_WR * _ELL))
C3 = 4.0 / 3.0  # cubic longitudinal profile p_hat(u) = (1 - |2u-1|^3) * 4/3 (unit mean)
PHI0 = 8.0  # p_hat(u)/u at the leading edge
PHI_HALF = 8.0 / 3.0  # p_hat(u)/u at mid-patch

# outputs of brush_point
OUT = ("Fx", "Fy", "Mz", "Mx", "My", "Pslide", "adh")
N_OUT = len(OUT)


@njit(cache=True, fastmath=True, inline="always")
def _adhesion_end(g):
    """u_s with p_hat(u_s)/u_s = g: the adhesion zone [0, u_s) of a row (u_s = 1: no slide)."""
    if g >= PHI0:
        return 0.0
    if g <= 0.0:
        return 1.0
    if g >= PHI_HALF:  # front half: p_hat/u = C3 (6 - 12u + 8u^2)
        return (12.0 - math.sqrt(32.0 * g / C3 - 48.0)) / 16.0
    # rear half: f(u) = C3 (1 - (2u-1)^3) - g u = 0, concave: Newton from u = 1
    u = 1.0
    for _ in range(30):
        v = 2.0 * u - 1.0
        f = C3 * (1.0 - v * v * v) - g * u
        df = -6.0 * C3 * v * v - g
        du = f / df
        u -= du
        if abs(du) < 1e-13:
            break
    return min(max(u, 0.5), 1.0)


@njit(cache=True, fastmath=True, inline="always")
def _P(w):
    """Antiderivative of (1 - |w|^3) dw."""
    w4 = w * w * w * w
    return w - w4 / 4.0 if w >= 0.0 else w + w4 / 4.0


@njit(cache=True, fastmath=True, inline="always")
def _Q(w):
    """Antiderivative of -w (1 - |w|^3) dw."""
    aw = abs(w)
    return -0.5 * w * w + aw * aw * aw * aw * aw / 5.0


@njit(cache=True, fastmath=True)
def deflection(T, Fz, p):
    """Vertical deflection [m] of the tyre at load Fz and gauge pressure p."""
    dpi = (p - T[P0]) / T[P0]
    kz = T[KZ0] * (1.0 + T[PFZ] * dpi)
    return max(Fz, 0.0) / kz


@njit(cache=True, fastmath=True)
def brush_point(T, Fz, kappa, alpha, gamma, V, p, mu_scale, c_scale, speed_on, out):
    """Steady-state forces of the brush at one operating point (ISO-W), into ``out``.

    mu_scale : factor on static and sliding friction (temperature window, wear).
    c_scale : factor on the tread (bristle) stiffness (bulk temperature, wear).
    speed_on : sliding friction follows the sliding speed V |s| (V as given) instead of the
        sliding speed the slip would give at the reference speed, VREF |s|.
    out : array of N_OUT: Fx, Fy, Mz, Mx, My, sliding power [W], adhesion load fraction [-].
    """
    for k in range(N_OUT):
        out[k] = 0.0
    if Fz <= 0.0:
        return
    Fz0 = T[FZ0]
    dfz = (Fz - Fz0) / Fz0
    dpi = (p - T[P0]) / T[P0]
    b = T[B]
    # patch: half-length from the deflection (chord of the loaded radius), width fixed
    a = T[QA] * math.sqrt(2.0 * T[R0] * deflection(T, Fz, p))
    sg = math.sin(gamma)
    # bristle (tread) stiffness per unit area and unit deflection. Lateral: the carcass in
    # series, as the smooth saturation c_eff = c / sqrt(1 + (Kb/Kc)^2) of the rigid-carcass
    # cornering stiffness Kb = 2 c a^2 b S2 against the carcass limit Kc; the tread base and
    # the carcass both stiffen with the belt tension, (1 + NCC dpi). Longitudinal: the tread
    # stiffness follows the vertical stiffness (belt tension) and NCX, (1 + PFZ dpi)(1 + NCX
    # dpi), so that Kxk = 2 cx a^2 b S2 goes as Fz (1 + NCX dpi) (no series compliance).
    cy = T[C0] * (1.0 + T[NCC] * dpi) * c_scale
    cx = T[C0] * T[RXY] * (1.0 + T[PFZ] * dpi) * (1.0 + T[NCX] * dpi) * c_scale
    Kby = 2.0 * cy * a * a * b * _S2
    Kcy = T[KC0] * (1.0 + T[NCC] * dpi)
    r_c = Kby / Kcy
    cy = cy / math.sqrt(1.0 + r_c * r_c)
    # static friction at this load and pressure; sliding friction falls with sliding speed
    mu = T[MU0] * (1.0 + T[MU1] * dfz) * (1.0 + T[MUP1] * dpi + T[MUP2] * dpi * dpi) * mu_scale
    rx = T[RX]
    # practical slips (slip velocity / forward speed); camber: an equivalent lateral slip
    sx = kappa
    sy = math.tan(alpha) + T[CAMK] * sg
    Veff = V if speed_on else T[VREF]
    # row load shares: lateral pressure profile, shifted towards the lean side by camber
    tot_share = 0.0
    for r in range(NROW):
        y = _YR[r]
        tot_share += max(_WR[r] * _ELL[r] * (1.0 + T[PW] * y * y) * (1.0 - T[PGAM] * sg * y),
                         1e-9)  # fmt: skip
    X = 0.0
    Y = 0.0
    M = 0.0
    Psl = 0.0
    adh_w = 0.0
    for r in range(NROW):
        y = _YR[r]
        yb = y * b
        ell = _ELL[r]
        ar = a * ell
        L = 2.0 * ar
        dy = _WR[r] * b
        share = max(_WR[r] * ell * (1.0 + T[PW] * y * y) * (1.0 - T[PGAM] * sg * y), 1e-9)
        share /= tot_share
        Q = Fz * share / (L * dy)  # mean contact pressure of the row [Pa]
        rho = share / (_WR[r] * ell / _AREA)  # row pressure / patch mean
        mur = max(mu * (1.0 - T[NQ] * (rho - 1.0)), 0.05 * mu)
        # camber spin: the rolling radius varies across the width -> longitudinal slip
        sxr = sx + T[EGAM] * sg * yb / T[R0]
        # adhesion while |c s xi| <= mu_s q(xi) (friction ellipse mu_x = rx mu)
        gx = cx * sxr / rx
        gy = cy * sy
        us = _adhesion_end(L * math.sqrt(gx * gx + gy * gy) / (mur * Q))
        adh_w += us * share
        xs = L * us
        # adhesion zone: stress c s xi, x = ar - xi
        Fxa = cx * sxr * xs * xs / 2.0
        Fya = cy * sy * xs * xs / 2.0
        mom = ar * xs * xs / 2.0 - xs * xs * xs / 3.0
        X += Fxa * dy
        Y += Fya * dy
        M += (-(cy * sy * mom) - yb * Fxa) * dy
        # sliding zone: friction stress along the slip, falling with the sliding speed
        sn = math.sqrt(sxr * sxr + sy * sy)
        if us < 1.0 and sn > 1e-15:
            ws = 2.0 * us - 1.0
            I0 = 0.5 * C3 * (0.75 - _P(ws))
            I1 = 0.5 * C3 * (_Q(1.0) - _Q(ws))
            muk = mur * (T[RINF] + (1.0 - T[RINF]) * math.exp(-Veff * sn / T[VC]))
            nx = sxr / sn
            ny = sy / sn
            base = muk * Q * L
            Fxs = base * I0 * rx * nx
            Fys = base * I0 * ny
            X += Fxs * dy
            Y += Fys * dy
            M += (-(ar * base * I1 * ny) - yb * Fxs) * dy
            Psl += base * I0 * math.sqrt(rx * rx * nx * nx + ny * ny) * (V * sn) * dy
    Fx = X
    Fy = -Y
    Clat = T[CLAT]
    out[0] = Fx
    out[1] = Fy
    out[2] = M - Fy * Fx / Clat  # belt shifted sideways by Fy/Clat: moment arm of Fx
    out[3] = Fz * Fy / Clat - T[R0] * Fz * T[QSX2] * gamma
    vr = V / T[VREF]
    out[4] = -T[R0] * Fz0 * (T[QSY1] + T[QSY3] * abs(vr) + T[QSY4] * vr ** 4) * (
        (Fz / Fz0) ** T[QSY7]) * ((p / T[P0]) ** T[QSY8])  # fmt: skip
    out[5] = Psl
    out[6] = adh_w


@njit(cache=True, fastmath=True)
def brush_grid(T, Fz, kappa, alpha, gamma, V, p, mu_scale, c_scale, speed_on):
    """brush_point over 1-D arrays (all of one length); returns (N_OUT, n)."""
    n = Fz.shape[0]
    res = np.empty((N_OUT, n))
    o = np.empty(N_OUT)
    for i in range(n):
        brush_point(T, Fz[i], kappa[i], alpha[i], gamma[i], V[i], p[i], mu_scale[i],
                    c_scale[i], speed_on, o)  # fmt: skip
        for k in range(N_OUT):
            res[k, i] = o[k]
    return res


def evaluate(T, Fz, kappa, alpha, gamma=0.0, V=None, p=None, mu_scale=1.0, c_scale=1.0,
             speed_on=False):  # fmt: skip
    """Vectorised steady-state brush; broadcast inputs; returns dict of arrays."""
    V = T[VREF] if V is None else V
    p = T[P0] if p is None else p
    arrs = np.broadcast_arrays(
        *[np.asarray(x, float) for x in (Fz, kappa, alpha, gamma, V, p, mu_scale, c_scale)]
    )
    shape = arrs[0].shape
    flat = [np.ascontiguousarray(x.reshape(-1)) for x in arrs]
    res = brush_grid(np.asarray(T, float), *flat, bool(speed_on))
    return {name: res[k].reshape(shape) for k, name in enumerate(OUT)}


# ------------------------------------------------------------------------------------------
# tyre variants
# ------------------------------------------------------------------------------------------
@dataclass
class Variant:
    name: str
    description: str
    kind: str  # "fsae" or "car"
    width: float
    rim_radius: float
    aspect: float
    targets: dict  # Kya0 [N/rad], Kxk0 [N], Kyg0 [N/rad per N] at FZ0, P0
    params: dict  # tyre vector entries (C0, CAMK filled by calibration)
    loads: tuple  # programme loads as fractions of FZ0
    pressures: tuple  # programme pressures as fractions of P0
    thermal: dict = field(default_factory=dict)
    noise: dict = field(default_factory=dict)


VARIANTS = {
    "fsae13": Variant(
        name="fsae13",
        description="FSAE 20.5x7.0-13 racing slick (R25B-like), brush model",
        kind="fsae",
        width=0.178,
        rim_radius=0.165,
        aspect=0.45,
        targets=dict(Kby0=66000.0, Kyg_rel=1.35),
        params=dict(
            R0=0.260,
            FZ0=1100.0,
            P0=83000.0,
            VREF=11.111,
            KZ0=115000.0,
            PFZ=0.75,
            QA=0.85,
            B=0.070,
            PW=0.3,
            RXY=0.9,
            NCX=-0.3,
            KC0=110000.0,
            NCC=0.1,
            MU0=2.75,
            MU1=-0.13,
            MUP1=-0.12,
            MUP2=0.08,
            RX=0.94,
            RINF=0.78,
            VC=1.4,
            NQ=0.25,
            PGAM=2.5,
            EGAM=0.5,
            CLAT=95000.0,
            QSX2=0.35,
            QSY1=0.012,
            QSY3=0.0005,
            QSY4=0.0,
            QSY7=0.9,
            QSY8=-0.35,
        ),
        loads=(0.2, 0.4, 0.6, 0.8, 1.0, 1.2),
        pressures=(0.667, 0.833, 1.0, 1.167),
    ),
    "fsae10": Variant(
        name="fsae10",
        description="FSAE 18.0x6.0-10 racing slick (LC0-like), brush model",
        kind="fsae",
        width=0.152,
        rim_radius=0.127,
        aspect=0.5,
        targets=dict(Kby0=54000.0, Kyg_rel=1.25),
        params=dict(
            R0=0.229,
            FZ0=900.0,
            P0=83000.0,
            VREF=11.111,
            KZ0=98000.0,
            PFZ=0.8,
            QA=0.85,
            B=0.060,
            PW=0.25,
            RXY=0.95,
            NCX=-0.25,
            KC0=90000.0,
            NCC=0.12,
            MU0=2.65,
            MU1=-0.12,
            MUP1=-0.1,
            MUP2=0.06,
            RX=0.92,
            RINF=0.8,
            VC=1.3,
            NQ=0.22,
            PGAM=2.2,
            EGAM=0.45,
            CLAT=85000.0,
            QSX2=0.3,
            QSY1=0.013,
            QSY3=0.0006,
            QSY4=0.0,
            QSY7=0.9,
            QSY8=-0.35,
        ),
        loads=(0.25, 0.5, 0.75, 1.0, 1.25),
        pressures=(0.667, 0.833, 1.0, 1.167),
    ),
    "car205": Variant(
        name="car205",
        description="passenger car 205/55R16 summer tyre, brush model",
        kind="car",
        width=0.205,
        rim_radius=0.203,
        aspect=0.55,
        targets=dict(Kby0=100000.0, Kyg_rel=0.9),
        params=dict(
            R0=0.316,
            FZ0=4000.0,
            P0=220000.0,
            VREF=11.111,
            KZ0=230000.0,
            PFZ=0.8,
            QA=0.75,
            B=0.075,
            PW=0.2,
            RXY=1.0,
            NCX=-0.3,
            KC0=180000.0,
            NCC=0.1,
            MU0=1.2,
            MU1=-0.09,
            MUP1=-0.1,
            MUP2=0.05,
            RX=1.04,
            RINF=0.8,
            VC=1.8,
            NQ=0.2,
            PGAM=2.0,
            EGAM=0.4,
            CLAT=160000.0,
            QSX2=0.3,
            QSY1=0.011,
            QSY3=0.0006,
            QSY4=0.0,
            QSY7=0.9,
            QSY8=-0.4,
        ),
        loads=(0.5, 0.75, 1.0, 1.25, 1.5),
        pressures=(0.818, 1.0, 1.182),
    ),
}


def _vector(params: dict) -> np.ndarray:
    T = np.zeros(N_TYRE)
    for k, v in params.items():
        T[TYRE_NAMES.index(k)] = v
    return T


def tyre_vector(variant: Variant) -> np.ndarray:
    """The calibrated tyre vector: C0 from the rigid-carcass cornering stiffness target,
    CAMK from the camber-stiffness target (|dFy/dgamma| at alpha = 0 = Kyg_rel * FZ0)."""
    T = _vector({**variant.params, "C0": 1.0, "CAMK": 0.0})
    # C0: Kby = 2 c a^2 b S2 at FZ0, P0
    a = T[QA] * math.sqrt(2 * T[R0] * T[FZ0] / T[KZ0])
    T[C0] = variant.targets["Kby0"] / (2 * a * a * T[B] * _S2)
    # CAMK by secant on the camber stiffness
    g = math.radians(0.5)
    target = variant.targets["Kyg_rel"] * T[FZ0]

    def kyg(ck):
        T[CAMK] = ck
        r = evaluate(T, T[FZ0], 0.0, 0.0, g)
        return -r["Fy"] / g

    k0, k1 = 0.01, 0.05
    f0, f1 = kyg(k0) - target, kyg(k1) - target
    for _ in range(30):
        if abs(f1 - f0) < 1e-12:
            break
        k2 = k1 - f1 * (k1 - k0) / (f1 - f0)
        k0, f0 = k1, f1
        k1, f1 = k2, kyg(k2) - target
        if abs(f1) < 1e-6 * target:
            break
    T[CAMK] = k1
    return T
