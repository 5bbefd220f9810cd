"""Sidewall contact in a simulation: found, fitted and kept out of the Magic Formula fit.

At low pressure and high load the sidewall touches the road and the lateral force drops
beyond a slip angle (the seed paper; PHYSICS.md: gated by the deflection). The Magic Formula
has no such term, so a fit that includes those samples bends its lateral curves elsewhere.
:func:`find_sidewall` fits the node's form of the effect
(:func:`~tire_model_ros.model.states.sidewall_factor`: Fy scaled by 1 - drop g(rho)
max(|alpha| - alpha_c, 0), g a gate in the relative deflection rho) to the measured lateral
force against a model's, and names it ``sidewall_contact`` when it removes most of the
mismatch where it acts; its corner (the gate open, past alpha_c) is then left out of the
lateral fit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from tire_model_ros.model import TireModel
from tire_model_ros.model.states import (
    Sidewall,
    deflection_pressure_weight,
    relative_deflection,
    sidewall_factor,
)
from tire_model_ros.recording.series import WheelSeries

from .core import evaluate_on, nominal_inputs, stack_inputs
from .sweeps import noise_sigma

F64 = npt.NDArray[np.float64]
Bools = npt.NDArray[np.bool_]

WORD = "sidewall_contact"  # INTERFACE.md
PURE_KAPPA = 0.005  # lateral samples: |kappa| below this
# Search box of (deflection threshold [-], contact slip angle [rad], drop per rad [1/rad]).
LOWER = (1.0, math.radians(1.0), 0.0)
UPPER = (8.0, math.radians(20.0), 10.0)
STARTS = ((2.0, math.radians(6.0), 1.0), (3.0, math.radians(9.0), 1.0))
# Fewer lateral samples in the corner: nothing to name. An FE tool's table has a few points
# per degree (a 1-degree table at three loads past 10 deg: some 30), a rig 100 a second.
MIN_CORNER_SAMPLES = 20
MIN_GAIN = 0.5  # the corner's RMS mismatch must fall by at least half ...
MIN_MISMATCH_SIGMAS = 3.0  # ... from at least this many noise levels ...
MIN_MISMATCH_SHARE = 0.01  # ... and this share of the largest |Fy| (a noise-free table)


@dataclass(frozen=True)
class SidewallFit:
    """The fitted sidewall contact and where it acts.

    ``params`` are (deflection threshold, alpha_c [rad], drop [1/rad]) of the node's effects
    file form; ``rms_before``/``rms_after`` the RMS of measured - model Fy [N] in the corner
    without and with it; ``sigma`` the lateral force noise [N].
    """

    params: tuple[float, float, float]
    n_corner: int
    rms_before: float
    rms_after: float
    sigma: float
    named: bool
    pressure_weight: float | None  # of the deflection (the model's vertical stiffness law)

    @property
    def word(self) -> str:
        return WORD

    def corner(self, s: WheelSeries, nominal_p: float, FNOMIN: float) -> Bools:
        """Samples of ``s`` in the corner: the gate half open or more and past alpha_c."""
        th, a_c, _ = self.params
        rho = deflection(s, nominal_p, FNOMIN, self.pressure_weight)
        out: Bools = (rho > th) & (np.abs(s.alpha) > a_c)
        return out

    def to_json(self) -> dict[str, object]:
        th, a_c, drop = self.params
        return {
            "name": WORD,
            "named": self.named,
            "deflection_threshold": th,
            "alpha_contact_deg": math.degrees(a_c),
            "drop_per_rad": drop,
            "corner_samples": self.n_corner,
            "rms_before_N": self.rms_before,
            "rms_after_N": self.rms_after,
            "noise_N": self.sigma,
        }


def deflection(s: WheelSeries, nominal_p: float, FNOMIN: float, weight: float | None) -> F64:
    """Relative deflection of every sample (the nominal pressure where none is recorded;
    ``weight`` as :func:`~tire_model_ros.model.states.relative_deflection`'s)."""
    p = np.full(len(s), nominal_p) if s.p is None else s.p
    rho = relative_deflection(s.Fz, FNOMIN, p, nominal_p, weight)
    out: F64 = np.asarray(rho, dtype=np.float64)
    return out


def find_sidewall(model: TireModel, sims: Sequence[WheelSeries]) -> SidewallFit | None:
    """Fit sidewall contact to the lateral samples of ``sims`` against ``model``.

    Returns None when there are too few lateral samples at a deflection above the model's
    nominal; else the fit, ``named`` when it halves the corner's mismatch from at least
    MIN_MISMATCH_SIGMAS noise levels and MIN_MISMATCH_SHARE of the largest lateral force.
    """
    lat = [s.select(np.abs(s.kappa) < PURE_KAPPA) for s in sims if s.Fy is not None]
    lat = [s for s in lat if len(s)]
    if not lat:
        return None
    P = model.params
    nominal_p, FNOMIN = nominal_inputs(model)["p"], float(P["FNOMIN"])
    inputs, measured, valid = stack_inputs(model, lat, ("Fy",))
    Fy = measured["Fy"]
    ok = valid & np.isfinite(Fy)
    weight = deflection_pressure_weight(P)
    rho = np.concatenate([deflection(s, nominal_p, FNOMIN, weight) for s in lat])[ok]
    alpha = np.concatenate([s.alpha for s in lat])[ok]
    sub = {k: None if v is None else v[ok] for k, v in inputs.items()}
    pred = np.asarray(evaluate_on(model, sub).Fy, dtype=np.float64)
    y = Fy[ok]
    if int(np.sum(rho > LOWER[0] + 0.3)) < MIN_CORNER_SAMPLES:
        return None
    sigma = float(np.median([noise_sigma(np.asarray(s.Fy)) for s in lat]))

    def resid(x: F64) -> F64:
        out: F64 = (pred * sidewall_factor(rho, alpha, Sidewall(x[0], x[1], x[2])) - y) / sigma
        return out

    best = min(
        (least_squares(resid, np.array(x0), bounds=(LOWER, UPPER), loss="soft_l1", f_scale=3.0)
         for x0 in STARTS),
        key=lambda sol: float(sol.cost),
    )  # fmt: skip
    params = (float(best.x[0]), float(best.x[1]), float(best.x[2]))
    corner = (rho > params[0]) & (np.abs(alpha) > params[1])
    n = int(corner.sum())
    if n < MIN_CORNER_SAMPLES:
        return SidewallFit(params, n, 0.0, 0.0, sigma, False, weight)
    before = float(np.sqrt(np.mean((pred - y)[corner] ** 2)))
    after = float(np.sqrt(np.mean((resid(best.x) * sigma)[corner] ** 2)))
    floor = max(MIN_MISMATCH_SIGMAS * sigma, MIN_MISMATCH_SHARE * float(np.max(np.abs(y))))
    named = before > floor and after < (1.0 - MIN_GAIN) * before
    return SidewallFit(params, n, before, after, sigma, named, weight)
