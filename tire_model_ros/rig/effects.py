"""Effects of the virtual rig other than the thermal ones, and the effect registry.

Each effect is switchable and has named parameters with PHYSICS.md typical sizes as
defaults. An effect changes only what the tyre really sees (true inputs) or the measured
forces; the recorded input channels are what the rig's sensors read.

Effect names (``EFFECTS``) and the INTERFACE.md diagnosis word each one should be found as
(``DIAGNOSIS_WORD``):

heating -> temperature, gas_pressure -> pressure, relaxation -> relaxation,
delay -> time_delay, offset -> offset, camber -> camber, combined -> combined_slip,
speed_friction -> speed, wear -> drift, mu_step -> drift, sidewall -> sidewall_contact,
load_ripple / noise -> (none),
model_temperature -> (none: the file's own TTX/TTY terms act on the true surface temperature).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt
from numba import njit
from scipy.signal import lfilter

from .thermal import HeatingParams

#: Effects as given: names (each with its defaults), or name -> on/off or parameter overrides.
EffectsSpec = str | Sequence[str] | Mapping[str, bool | Mapping[str, float | str] | None] | None

DEG = math.pi / 180.0
F64 = npt.NDArray[np.float64]

# name -> default parameters. ``noise`` is on unless switched off (noise: False).
DEFAULTS: dict[str, dict[str, float]] = {
    "heating": HeatingParams().to_dict(),
    "gas_pressure": {},  # uses the heating nodes (which always run) and the gas law
    "relaxation": {"sigma_alpha_m": 0.5, "sigma_kappa_m": 0.25, "load_dependent": 1.0},
    "delay": {"tau_s": 0.02},
    "offset": {"fy_per_Fz": 0.03, "fy_N": 0.0, "fx_N": 0.0, "fx_per_Fz": 0.0, "mz_Nm": 0.0},
    "camber": {"per_deg": -0.026, "saturation_deg": 6.0, "fade_deg": 12.0},
    "combined": {"peak_scale": 1.0},
    "speed_friction": {"mu0_ratio": 0.6, "Vm_mps": 0.5, "h": 0.4, "Vs_ref_mps": -1.0},
    # grip loss per km of equivalent sliding; abrasion grows with the tread's heat (per K of
    # surface above ambient), so wear is not a function of the frictional work alone. The
    # size (about 3.5 % over a flat_trac session) is what the heat-free 0.08/km gave before.
    "wear": {"loss_per_km": 0.05, "abrasion_per_K": 0.02},
    "mu_step": {"ratio": 0.95, "at_s": -1.0},
    "noise": {"scale": 1.0, "colour": 0.5, "tau_s": 0.5},
    "load_ripple": {"amplitude": 0.02, "harmonic": 1.0, "recorded": 1.0},
    "model_temperature": {},
    # Sidewall contact (the seed paper: at 60 kPa and 120-160 % load near 10 deg of slip
    # angle, earlier the higher the load): deflections relative to the nominal one.
    "sidewall": {
        "deflection_on": 3.0,  # relative deflection where the gate is half open
        "deflection_width": 0.25,  # ... and its smoothstep half-width
        "alpha_on_deg": 11.0,  # contact slip angle at deflection_on
        "alpha_per_deflection_deg": 1.5,  # contact comes earlier per unit of deflection beyond
        "alpha_min_deg": 4.0,
        "depth": 0.35,  # the share of Fy and Mz the crown can lose to the sidewall
        "alpha_width_deg": 4.0,  # slip angle beyond contact over which the loss builds up
    },
}
EFFECTS = tuple(DEFAULTS)
# parameters that must be > 0 (time constants, lengths, widths, ratios) or >= 0
POSITIVE = {
    "heating": ("tau_surface_s", "tau_bulk_s", "tau_gas_s", "width_hot_K", "width_cold_K"),
    "relaxation": ("sigma_alpha_m", "sigma_kappa_m"),
    "camber": ("saturation_deg", "fade_deg"),
    "combined": ("peak_scale",),
    "speed_friction": ("Vm_mps",),
    "mu_step": ("ratio",),
    "noise": ("tau_s",),
    "load_ripple": ("harmonic",),
    "sidewall": ("deflection_width", "alpha_width_deg"),
}
NON_NEGATIVE = {
    "heating": ("k_surface_K_per_m", "k_bulk_K_per_m"),
    "delay": ("tau_s",),
    "speed_friction": ("mu0_ratio", "h"),
    "wear": ("loss_per_km", "abrasion_per_K"),
    "noise": ("scale", "colour"),
    "load_ripple": ("amplitude",),
    "sidewall": (
        "deflection_on",
        "alpha_on_deg",
        "alpha_per_deflection_deg",
        "alpha_min_deg",
        "depth",
    ),
}
DIAGNOSIS_WORD = {
    "heating": "temperature",
    "gas_pressure": "pressure",
    "relaxation": "relaxation",
    "delay": "time_delay",
    "offset": "offset",
    "camber": "camber",
    "combined": "combined_slip",
    "speed_friction": "speed",
    "wear": "drift",
    "mu_step": "drift",
    "sidewall": "sidewall_contact",
}
DEFAULT_ON = ("noise",)


def resolve_effects(effects: EffectsSpec) -> dict[str, dict[str, float]]:
    """Switched-on effects with their full parameter sets (defaults filled in).

    ``effects`` maps a name to True/False or to a dict of parameter overrides (a list of
    names switches those on with their defaults). Unknown
    names or parameters raise ValueError naming them.
    """
    out: dict[str, dict[str, float]] = {k: dict(DEFAULTS[k]) for k in DEFAULT_ON}
    if isinstance(effects, str):
        effects = [effects]
    if effects is not None and not isinstance(effects, Mapping):
        effects = dict.fromkeys(effects, True)  # a list of names: each with its defaults
    for name, value in (effects or {}).items():
        if name not in DEFAULTS:
            raise ValueError(f"unknown effect {name!r} (known: {', '.join(EFFECTS)})")
        if value is False or value is None:
            out.pop(name, None)
            continue
        params = dict(DEFAULTS[name])
        if isinstance(value, Mapping):
            for k, v in value.items():
                if k not in params:
                    raise ValueError(
                        f"effect {name}: unknown parameter {k!r} "
                        f"(known: {', '.join(params) or 'none'})"
                    )
                try:
                    params[k] = float(v)
                except (TypeError, ValueError):
                    raise ValueError(
                        f"effect {name}: parameter {k} must be a number, got {v!r}"
                    ) from None
                if not math.isfinite(params[k]):
                    raise ValueError(f"effect {name}: parameter {k} must be finite")
        elif value is not True:
            raise ValueError(f"effect {name}: expected true/false or a parameter dict")
        for k in POSITIVE.get(name, ()):
            if params[k] <= 0.0:
                raise ValueError(f"effect {name}: parameter {k} must be > 0, got {params[k]}")
        for k in NON_NEGATIVE.get(name, ()):
            if params[k] < 0.0:
                raise ValueError(f"effect {name}: parameter {k} must be >= 0, got {params[k]}")
        out[name] = params
    return out


# ------------------------------------------------------------------ relaxation, delay


def relaxation_length_alpha(
    Fz: np.ndarray, FNOMIN: float, sigma_alpha_m: float, load_dependent: bool
) -> np.ndarray:
    """sigma_alpha(Fz): saturating in load like a 205/60R15 (0.35/0.52/0.55 m at 2/4/6 kN),
    scaled so that sigma_alpha(FNOMIN) = sigma_alpha_m."""
    if not load_dependent:
        return np.full_like(Fz, sigma_alpha_m)
    ref = 0.375 * FNOMIN  # 1.5 kN for a 4 kN tyre
    shape = 1.0 - np.exp(-np.maximum(Fz, 0.0) / ref)
    return sigma_alpha_m * np.maximum(shape, 0.05) / (1.0 - math.exp(-1.0 / 0.375))


def first_order_in_distance(
    u: np.ndarray, Vx: np.ndarray, sigma: np.ndarray, dt: float
) -> np.ndarray:
    """sigma du'/ds + u' = u, exact step for piecewise-constant input (s = travelled distance)."""
    a = 1.0 - np.exp(-np.abs(Vx) * dt / np.maximum(sigma, 1e-4))
    return _lag(np.ascontiguousarray(u, dtype=np.float64), np.ascontiguousarray(a))


@njit(cache=True)
def _lag(u: npt.NDArray[np.float64], a: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    out = np.empty_like(u)
    y = u[0]
    for i in range(u.shape[0]):
        y += a[i] * (u[i] - y)
        out[i] = y
    return out


def delayed(x: np.ndarray, t: np.ndarray, tau_s: float) -> np.ndarray:
    """x(t - tau) by linear interpolation (the first value held before the start)."""
    return np.interp(t - tau_s, t, x)


# ------------------------------------------------------------------ force-level effects


def camber_thrust(
    Fz: np.ndarray,
    gamma: np.ndarray,
    alpha: np.ndarray,
    per_deg: float,
    saturation_deg: float,
    fade_deg: float,
) -> np.ndarray:
    """Extra camber thrust: per_deg*Fz per degree, saturating in gamma (tanh), fading with
    |alpha| as the contact patch slides (Lorentzian in alpha)."""
    g_deg = np.degrees(gamma)
    g_eff = saturation_deg * np.tanh(g_deg / saturation_deg)
    fade = 1.0 / (1.0 + (np.degrees(alpha) / fade_deg) ** 2)
    return per_deg * Fz * g_eff * fade


def savkoor_factor(Vs: np.ndarray, mu0_ratio: float, Vm_mps: float, h: float) -> np.ndarray:
    """Savkoor-type friction vs sliding speed: mu0 + (mum - mu0) exp(-h^2 ln^2(Vs/Vm)),
    divided by mum (1 at Vs = Vm)."""
    x = np.log(np.maximum(Vs, 1e-4) / Vm_mps)
    return mu0_ratio + (1.0 - mu0_ratio) * np.exp(-((h * x) ** 2))


def sliding_speed(Vx: np.ndarray, kappa: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """|Vs| ~ |Vx| sqrt(kappa^2 + tan^2 alpha) [m/s]."""
    return np.abs(Vx) * np.hypot(kappa, np.tan(alpha))


def relative_deflection(Fz: F64, p_gauge: F64, params: Mapping[str, float]) -> F64:
    """Tyre deflection over the nominal one: Fz / Cz(p) against FNOMIN / Cz(NOMPRES), with the
    MF 6.1 vertical stiffness Cz = VERTICAL_STIFFNESS (1 + PFZ1 dpi) (floor 10 %)."""
    p0 = float(params.get("NOMPRES") or 2.0e5)
    dpi = (np.asarray(p_gauge, dtype=np.float64) - p0) / p0
    stiffness = np.maximum(1.0 + float(params.get("PFZ1", 0.0)) * dpi, 0.1)
    return np.asarray(Fz, dtype=np.float64) / float(params["FNOMIN"]) / stiffness


def sidewall_factor(
    Fz: F64, p_gauge: F64, alpha: F64, params: Mapping[str, float], sw: Mapping[str, float]
) -> F64:
    """Share of Fy (and Mz) left when the sidewall touches the road: a smoothstep gate in the
    relative deflection, a contact slip angle that falls as the deflection grows, and a loss
    that builds up exponentially beyond it (up to ``depth``)."""
    rho = relative_deflection(Fz, p_gauge, params)
    x = np.clip((rho - sw["deflection_on"]) / (2.0 * sw["deflection_width"]) + 0.5, 0.0, 1.0)
    gate = x * x * (3.0 - 2.0 * x)
    a_on = np.maximum(
        sw["alpha_on_deg"] - sw["alpha_per_deflection_deg"] * (rho - sw["deflection_on"]),
        sw["alpha_min_deg"],
    )
    over = np.maximum(np.degrees(np.abs(alpha)) - a_on, 0.0)
    loss = gate * sw["depth"] * (1.0 - np.exp(-over / sw["alpha_width_deg"]))
    left: F64 = np.maximum(1.0 - loss, 0.0)
    return left


# ------------------------------------------------------------------ sensor noise


def coloured_noise(
    rng: np.random.Generator, n: int, sd: float, colour: float, tau_s: float, dt: float
) -> np.ndarray:
    """White Gaussian noise of sd plus AR(1) noise of sd*colour with time constant tau_s."""
    if sd <= 0.0:
        return np.zeros(n)
    white = rng.standard_normal(n) * sd
    if colour <= 0.0:
        return white
    phi = math.exp(-dt / max(tau_s, dt))
    e = rng.standard_normal(n) * sd * colour * math.sqrt(1.0 - phi * phi)
    y0 = rng.standard_normal() * sd * colour
    ar = lfilter([1.0], [1.0, -phi], e, zi=[phi * y0])[0]
    return white + ar


def noise_sd(FNOMIN: float, R0: float) -> dict[str, float]:
    """Sensor noise standard deviations of a Flat-Trac class rig (scaled with the tyre)."""
    return {
        "kappa": 2e-4,
        "alpha": 0.02 * DEG,
        "gamma": 0.01 * DEG,
        "Fz": 0.003 * FNOMIN,
        "Vx": 0.02,
        "p": 300.0,
        "T": 0.3,
        "Fx": 0.003 * FNOMIN,
        "Fy": 0.003 * FNOMIN,
        "Fz_meas": 0.003 * FNOMIN,
        "Mx": 0.001 * FNOMIN * R0,
        "My": 0.001 * FNOMIN * R0,
        "Mz": 0.0005 * FNOMIN * R0,
    }
