"""Operating conditions: input saturation, the low-speed model and the shared increments.

Follows MFeval 4.3.1 (``Solver.parseInputs`` / ``calculateBasic``), which is tuned to TNO MF-Tyre:
with limits on (MFeval useMode 1xx) the inputs are saturated to the ranges of the .tir file and
below VXLOW the slips and the shifts are reduced towards standstill; with limits off (2xx) the
plain equations are evaluated.

All functions are scalar numba kernels; ``P`` is the coefficient vector indexed by
:mod:`tire_model_ros.model.coef`.
"""

from __future__ import annotations

import math

from . import coef as c
from . import vmath as vm
from .jit import kernel

EPS = 1e-6  # epsilon of (4.E6a); MFeval uses one value for every guard


@kernel
def sign0(x: float) -> float:
    """MATLAB ``sign``: sign(0) = 0 (used where MFeval relies on it)."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return 0.0


@kernel
def sign1(x: float) -> float:
    """Sign with sign(0) = +1: MFeval's guard so that ``x + eps*sign(x)`` is never zero."""
    return -1.0 if x < 0.0 else 1.0


@kernel
def clip(x: float, lo: float, hi: float) -> float:
    """Saturate x to [lo, hi]; NaN passes through (no comparison is true)."""
    if x < lo:
        return lo
    if x > hi:
        return hi
    return x


@kernel
def low_speed_factors(P, Vx: float, limits: bool) -> tuple[float, float]:
    """Low-speed reduction factors below VXLOW (MFeval parseInputs, empirical TNO choice).

    Returns
    -------
    (reduction_linear, reduction_smooth)
        |Vx|/VXLOW and 1 - (1 + cos(pi Vx/VXLOW))/2; both 1 above VXLOW or with limits off.
    """
    VXLOW = P[c.VXLOW]
    if not limits or not (abs(Vx) <= VXLOW):
        return 1.0, 1.0
    linear = abs(Vx / VXLOW)
    Wvlow = 0.5 * (1.0 + vm.cos(math.pi * (Vx / VXLOW)))
    return linear, 1.0 - Wvlow


@kernel
def operating_point(P, Fz, kappa, alpha, gamma, Vx, p, phit, limits):
    """Inputs as the equations see them (saturated and low-speed reduced when ``limits``).

    Returns
    -------
    tuple
        ``(Fz, kappa, alpha, gamma, phit, p, uFz, kappa_low, Fz_low, red_smooth)``:
        the inputs used by the force equations, the load before saturation (negative
        loads read as 0), the slip ratio reported as used (low-speed reduced only),
        the load for the aligning torque (at least FZMIN) and the smooth low-speed factor.
    """
    uFz = 0.0 if Fz < 0.0 else Fz
    red_linear, red_smooth = low_speed_factors(P, Vx, limits)
    kappa_low = kappa * red_linear
    Fz_low = uFz
    if limits:
        VXLOW = P[c.VXLOW]
        kappa = kappa * red_linear
        if phit != 0.0:
            phit = phit * vm.cos(alpha)  # empirical TNO choice mirrored by MFeval: input alpha
        phit = phit * red_linear
        if Vx < 0.0:
            phit = -phit
        # Slip angle reduced with the total (longitudinal + lateral) contact speed
        # (only possible below VXLOW: skip the tan above it).
        if abs(Vx) < VXLOW:
            speed_sum = abs(Vx) + abs(vm.tan(alpha) * Vx)
            if speed_sum < VXLOW:
                alpha = alpha * (speed_sum / VXLOW)
        alpha = clip(alpha, P[c.ALPMIN], P[c.ALPMAX])
        gamma = clip(gamma, P[c.CAMMIN], P[c.CAMMAX])
        Fz = clip(uFz, 0.0, P[c.FZMAX])
        p = clip(p, P[c.PRESMIN], P[c.PRESMAX])
        kappa = clip(kappa, P[c.KPUMIN], P[c.KPUMAX])
        Fz_low = P[c.FZMIN] if Fz < P[c.FZMIN] else Fz
        if uFz <= 0.0:
            Fz_low = 0.0
    else:
        Fz = uFz
    return Fz, kappa, alpha, gamma, phit, p, uFz, kappa_low, Fz_low, red_smooth


@kernel
def nominal_load(P) -> float:
    """Scaled nominal load Fz0' = LFZO FNOMIN (4.E1) [N]."""
    return P[c.LFZO] * P[c.FNOMIN]


@kernel
def load_increment(P, Fz: float) -> float:
    """Normalised load increment dfz = (Fz - Fz0')/Fz0' (4.E2a)."""
    Fz0p = nominal_load(P)
    return (Fz - Fz0p) / Fz0p


@kernel
def pressure_increment(P, p: float) -> float:
    """Normalised inflation-pressure increment dpi = (p - NOMPRES)/NOMPRES (4.E2b)."""
    return (p - P[c.NOMPRES]) / P[c.NOMPRES]


@kernel
def temperature_increment(P, T: float) -> float:
    """Normalised temperature increment dT = (T - NOMTEMP)/NOMTEMP (INTERFACE.md)."""
    return (T - P[c.NOMTEMP]) / P[c.NOMTEMP]


@kernel
def cos_alpha_prime(alpha: float, Vx: float) -> float:
    """cos(alpha') with alpha' = acos(Vcx/Vc') (4.E6, 4.E6a): simply Vcx/Vc'.

    Vcy is taken equal to the lateral slip speed tan(alpha)|Vcx| (MFeval's assumption).
    """
    Vcy = vm.tan(alpha) * abs(Vx)
    Vc = math.sqrt(Vx * Vx + Vcy * Vcy)
    Vc_prime = Vc + EPS * sign1(Vc)
    return clip(Vx / Vc_prime, -1.0, 1.0)


@kernel
def cos_atan(x: float) -> float:
    """cos(atan x) = 1/sqrt(1 + x^2), exact identity without two transcendental calls."""
    return 1.0 / math.sqrt(1.0 + x * x)
