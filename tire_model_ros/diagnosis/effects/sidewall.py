"""Sidewall contact: at low pressure and high load the sidewall touches the road and the
force drops beyond the peak (the seed paper: at 60 kPa near 10 deg of slip angle), only in
that corner of the operating range (PHYSICS.md: gated by the deflection, Fz / p).

Where the corner lies is the tyre's own: the gate's threshold is fitted within the deflections
the session reaches beyond the force peak, starting from their upper quantiles.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tire_model_ros.model.states import relative_deflection, sidewall_factor

from ..prepare import Context
from .base import Array, EffectModel, Index, Mask, Param

BEYOND_PEAK = 0.5  # of the session's largest |alpha|: samples past about the force peak
CORNER_QUANTILE = 0.7  # the corner: past the peak and above this quantile of the deflection
MIN_SPREAD = 1.05  # the deflections past the peak must span this ratio (95th / 50th pct.)
MIN_CORNER_SHARE = 0.01  # of the samples in the corner, for the effect to be tried


def deflection(ctx: Context) -> Array:
    """Relative deflection per sample (the file's nominal pressure where none is recorded)."""
    w = ctx.wheel
    p = w.inputs["p"]
    p = np.full(w.n, ctx.p_nom) if p is None else p
    return np.asarray(relative_deflection(w.x("Fz"), ctx.base["FNOMIN"], p, ctx.p_nom))


def _beyond(ctx: Context) -> Mask:
    a = np.abs(ctx.wheel.x("alpha"))
    return a > BEYOND_PEAK * float(np.max(a))


class SidewallContact(EffectModel):
    """Fy scaled by 1 - d g(rho) max(|alpha| - alpha_c, 0): g a smooth gate that opens as the
    relative deflection rho passes its threshold (:func:`~..model.states.sidewall_factor`)."""

    word = "sidewall_contact"
    label = "force drop beyond a slip angle, gated by the deflection"

    def __init__(self, ctx: Context):
        rho = deflection(ctx)[_beyond(ctx)]
        lo, hi = float(np.min(rho)), float(np.max(rho))
        q = {k: float(np.quantile(rho, k)) for k in (0.6, 0.8, 0.9)}
        a_max = float(np.max(np.abs(ctx.wheel.x("alpha"))))
        super().__init__(
            [
                Param("deflection_threshold", q[0.8], lo, max(hi, lo * 1.001), 0.05 * q[0.8]),
                Param("alpha_contact_rad", 0.6 * a_max, 0.2 * a_max, a_max, 0.02),
                Param("drop_per_rad", 0.5, 0.0, 10.0, 0.3),
            ],
            [{"deflection_threshold": q[0.6]}, {"deflection_threshold": q[0.9]}],
        )

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        if "Fy" not in ctx.channels or not ctx.informative["y"]:
            return []
        rho = deflection(ctx)[_beyond(ctx)]
        if len(rho) < 10 or np.quantile(rho, 0.95) < MIN_SPREAD * np.quantile(rho, 0.5):
            return []  # the session does not reach a corner of higher deflection
        return [cls(ctx)] if float(np.mean(_corner(ctx))) > MIN_CORNER_SHARE else []

    def support(self, ctx: Context) -> Mask | None:
        return _corner(ctx)

    def output(self, x: Array, ctx: Context, out: dict[str, Array], rows: Index) -> None:
        params = (float(x[0]), float(x[1]), float(x[2]))
        alpha = ctx.wheel.x("alpha")[rows]
        out["Fy"] = out["Fy"] * sidewall_factor(deflection(ctx)[rows], alpha, params)

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        return {"sidewall": (float(x[0]), float(x[1]), float(x[2]))}


def _corner(ctx: Context) -> Mask:
    rho, beyond = deflection(ctx), _beyond(ctx)
    return beyond & (rho > float(np.quantile(rho[beyond], CORNER_QUANTILE)))
