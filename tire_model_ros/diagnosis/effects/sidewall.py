"""Sidewall contact: at low pressure and high load the sidewall touches the road and the
force drops beyond the peak (the seed paper: at 60 kPa near 10 deg of slip angle), only in
that corner of the operating range (PHYSICS.md: gated by the deflection, Fz / p).

Where the corner lies is the tyre's own: the gate's threshold is fitted within the upper half
of the deflections the session reaches beyond the force peak (a corner, not the whole range),
and the model must beat the same drop at every deflection (its control: the gate tested).
The threshold, slip angle and drop are the tyre's: on a car one set is fitted to every wheel
that runs past its peak, so that a wheel which runs its corners at one deflection (a loaded
front wheel) is told from one that reaches the same slip angles less deflected.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from tire_model_ros.model.states import (
    Sidewall,
    contact_alpha,
    deflection_pressure_weight,
    relative_deflection,
    sidewall_factor,
)

from ..prepare import Context
from .base import Array, EffectModel, Index, Mask, Param
from .curve import curve_shapes

# Beyond about the force peak: the file model's Fy curve has flattened to this share of its
# cornering stiffness (the tyre's own peak, not the session's largest slip angle, which one
# hard corner of a car can set).
BEYOND_PEAK_SLOPE = 0.3
# The corner (past the peak, above the median deflection there) must hold this long of
# samples: what a fit of its six parameters and a test on held-out sweeps need. A duration,
# not a share of the session: a car's front wheels reach their corner in a few seconds of an
# 8-minute session (1 % of its samples was missed by 2 % on both car sidewall recordings of
# seeds 18 and 21), and a longer session would have needed longer corners.
MIN_CORNER_S = 2.0
DROP_ACTS = 1e-3  # a factor this far below 1: the fitted drop acts there (its support)
# The share of Fy the drop saturates at: starts at the seed paper's order (a third), at least
# a few per cent (below that the drop is within the noise), at most all of it.
DEPTH_START, DEPTH_MIN = 0.3, 0.02
# The gate's width, a share of its threshold (start, least, most): how sharply the sidewall
# takes over is the tyre's, from a step (a hard contact) to a gradual one.
GATE_WIDTH = (0.05, 0.005, 0.2)
# A fitted row tells whether the gate is open only where the drop, were it open, would be at
# least this share of its depth.
TELLS_GATE = 0.25
GATE_SPAN = 5.9  # logistic widths between its 5 % and 95 % points


def deflection(ctx: Context) -> Array:
    """Relative deflection per sample (the file's nominal pressure where none is recorded)."""
    w = ctx.wheel
    p = w.inputs["p"]
    p = np.full(w.n, ctx.p_nom) if p is None else p
    k = deflection_pressure_weight(ctx.base)
    return np.asarray(relative_deflection(w.x("Fz"), ctx.base["FNOMIN"], p, ctx.p_nom, k))


def _beyond(ctx: Context) -> Mask:
    return np.asarray(curve_shapes(ctx)["slip_alpha"] < BEYOND_PEAK_SLOPE, dtype=np.bool_)


def _corner(ctx: Context) -> Mask:
    """Past the peak and above the median deflection there."""
    rho, beyond = deflection(ctx), _beyond(ctx)
    return beyond & (rho > float(np.quantile(rho[beyond], 0.5)))


def _corner_s(ctx: Context) -> float:
    """How long the session runs in the corner [s] (its samples times the sample period)."""
    t = ctx.wheel.t
    return float(np.count_nonzero(_corner(ctx)) * np.median(np.diff(t))) if len(t) > 1 else 0.0


class SidewallContact(EffectModel):
    """Fy scaled by 1 - g(rho) D (1 - exp(-d u / D)), u = max(|alpha| - alpha_c, 0): g a
    smooth gate of fitted width that opens as the relative deflection rho passes its
    threshold, the loss growing at d per rad beyond alpha_c and levelling off at the share D
    of Fy (:func:`~..model.states.sidewall_factor`): a corner beyond the trained slip angles
    is not predicted to lose without bound, nor one just below the trained deflections to
    lose through a gate wider than the data show.

    ``gated`` False is its control: the same drop beyond alpha_c at every deflection.
    """

    word = "sidewall_contact"
    tyre = True

    def __init__(self, ctx: Context, gated: bool = True):
        self.gated = gated
        self.label = (
            "force drop beyond a slip angle, gated by the deflection"
            if gated
            else "control: the same drop at every deflection"
        )
        rho = deflection(ctx)[_beyond(ctx)]
        q = {k: float(np.quantile(rho, k)) for k in (0.5, 0.6, 0.8, 0.9)}
        hi = max(float(np.max(rho)), q[0.5] * 1.001)
        a_max = float(np.max(np.abs(ctx.wheel.x("alpha"))))
        # The ungated control holds its threshold far below every deflection (gate open).
        th = (
            Param("deflection_threshold", q[0.8], q[0.5], hi, 0.05 * q[0.8])
            if gated
            else Param("deflection_threshold", 1e-3 * q[0.5], 0.0, hi, 1.0, fitted=False)
        )
        super().__init__(
            [
                th,
                Param("alpha_contact_rad", 0.6 * a_max, 0.2 * a_max, a_max, 0.02),
                Param("drop_per_rad", 0.5, 0.0, 10.0, 0.3),
                Param("depth", DEPTH_START, DEPTH_MIN, 1.0, 0.1),
                Param("gate_width", *GATE_WIDTH, 0.02, fitted=gated),  # the control: open
                Param("alpha_c_per_rho", 0.0, 0.0, a_max / max(hi - q[0.5], 1e-3), 0.05),
            ],
            [{"deflection_threshold": q[0.6]}, {"deflection_threshold": q[0.9]}] if gated else [],
        )

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        if "Fy" not in ctx.channels or not ctx.informative["y"]:
            return []
        if np.count_nonzero(_beyond(ctx)) < 10:
            return []  # the session does not run past the peak
        return [cls(ctx)] if _corner_s(ctx) >= MIN_CORNER_S else []

    def on(self, ctx: Context) -> EffectModel | None:
        return SidewallContact(ctx, self.gated) if self.propose(ctx) else None

    def controls(self, ctx: Context) -> list[EffectModel]:
        return [SidewallContact(ctx, gated=False)] if self.gated else []

    def support(self, ctx: Context, x: Array | None = None) -> Mask | None:
        """Where the fitted drop acts (before a fit: past the peak, above the median
        deflection there)."""
        if x is None:
            return _corner(ctx)
        alpha = ctx.wheel.x("alpha")
        f = sidewall_factor(deflection(ctx), alpha, _params(x))
        return np.asarray(f < 1.0 - DROP_ACTS, dtype=np.bool_)

    def settle(self, x: Array, seen: Sequence[tuple[Context, Index]]) -> Array:
        """The gate across the gap in deflection that the fitted rows leave open.

        Beyond the contact slip angle the fitted rows show the drop at some deflections and
        not at others; between the most deflected row without it and the least deflected row
        with it (on every wheel fitted: the tyre's) the cost is flat in the threshold, and a
        fit leaves it at either edge. As for a friction step between sweeps, the model
        predicts across the gap the expected drop for a threshold uniform in it: the gate is
        centred in the gap and spans it (5 % to 95 %), never narrower than fitted. A corner
        the fit did not see is never given the whole drop, or none of it, on the strength of
        an edge the data did not place.
        """
        if not self.gated:
            return x
        x = np.array(x, dtype=float)
        sw = _params(x)
        th, width = sw.threshold, sw.gate_width
        rho = np.concatenate([_telling(ctx, rows, sw) for ctx, rows in seen])
        closed, opened = rho[rho < th], rho[rho >= th]
        if not len(closed) or not len(opened):
            return x
        lo, hi = float(closed.max()), float(opened.min())
        mid = 0.5 * (lo + hi)
        x[1] = float(contact_alpha(mid, sw))  # the same contact slip angles, re-anchored
        x[0] = mid
        x[4] = max(width * th / mid, (hi - lo) / (GATE_SPAN * mid))
        return x

    def output(self, x: Array, ctx: Context, out: dict[str, Array], rows: Index) -> None:
        alpha = ctx.wheel.x("alpha")[rows]
        out["Fy"] = out["Fy"] * sidewall_factor(deflection(ctx)[rows], alpha, _params(x))

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        return {
            "sidewall": _params(x)._replace(pressure_weight=deflection_pressure_weight(ctx.base))
        }


def _telling(ctx: Context, rows: Index, sw: Sidewall) -> Array:
    """Deflections of the ``rows`` that tell whether the gate is open (slip angles where the
    open gate's drop would be at least TELLS_GATE of its depth)."""
    rho = deflection(ctx)[rows]
    u = np.maximum(np.abs(ctx.wheel.x("alpha")[rows]) - contact_alpha(rho, sw), 0.0)
    tells = -np.expm1(-sw.drop_per_rad * u / max(sw.depth, 1e-9)) >= TELLS_GATE
    return np.asarray(rho[tells], dtype=np.float64)


def _params(x: Array) -> Sidewall:
    return Sidewall(*(float(v) for v in x))
