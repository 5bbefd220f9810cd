"""The baseline: the file's model with its scaling factors refitted (the fit that leaves
physics out). Every effect is judged by what it adds to this."""

from __future__ import annotations

from ..prepare import Context
from .base import Array, EffectModel, Param


class Scaling(EffectModel):
    """Multiplicative friction and stiffness scaling factors LMUX, LKX, LMUY, LKY."""

    word = "baseline"
    label = "scaling factors refitted"

    def __init__(self, ctx: Context):
        names = (["LMUX", "LKX"] if ctx.informative["x"] else []) + (
            ["LMUY", "LKY"] if ctx.informative["y"] else []
        )
        super().__init__([Param(k, 1.0, 0.5, 1.5, 0.05) for k in names])

    def coef(self, x: Array, ctx: Context) -> dict[str, float]:
        return {k: ctx.base[k] * float(v) for k, v in zip(self.pnames, x, strict=True)}
