"""Sidewall contact: at low pressure and high load the sidewall touches the road and the
force drops beyond the peak (the seed paper: at 60 kPa near 10 deg of slip angle), only in
that corner of the operating range (PHYSICS.md: gated by the deflection, Fz / p)."""

from __future__ import annotations

from typing import Any

import numpy as np

from tire_model_ros.model.states import relative_deflection, sidewall_factor

from ..prepare import Context
from .base import Array, EffectModel, Index, Mask, Param

CORNER_DEFLECTION = 1.3  # the corner: relative deflection above this ...
CORNER_ALPHA = np.radians(4.0)  # ... and slip angle beyond this
MIN_CORNER_SHARE = 0.01  # of the samples, in the corner, for the effect to be tried


def deflection(ctx: Context) -> Array:
    """Relative deflection per sample (the file's nominal pressure where none is recorded)."""
    w = ctx.wheel
    p = w.inputs["p"]
    p = np.full(w.n, ctx.p_nom) if p is None else p
    return np.asarray(relative_deflection(w.x("Fz"), ctx.base["FNOMIN"], p, ctx.p_nom))


class SidewallContact(EffectModel):
    """Fy scaled by 1 - d g(rho) max(|alpha| - alpha_c, 0): g a smooth gate that opens as the
    relative deflection rho passes its threshold (:func:`~..model.states.sidewall_factor`)."""

    word = "sidewall_contact"
    label = "force drop beyond a slip angle, gated by the deflection"

    def __init__(self, ctx: Context):
        super().__init__(
            [
                Param("deflection_threshold", 1.6, 1.0, 6.0, 0.2),
                Param("alpha_contact_rad", np.radians(6.0), np.radians(1.0), np.radians(20), 0.02),
                Param("drop_per_rad", 0.5, 0.0, 10.0, 0.3),
            ],
            [{"deflection_threshold": 1.3}, {"deflection_threshold": 2.5}],
        )

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        if "Fy" not in ctx.channels:
            return []
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
    return (deflection(ctx) > CORNER_DEFLECTION) & (np.abs(ctx.wheel.x("alpha")) > CORNER_ALPHA)
