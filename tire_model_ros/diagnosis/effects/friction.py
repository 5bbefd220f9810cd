"""Friction that changes with sliding speed or over the session.

``speed``: friction against sliding speed, the MF form mu / (1 + LMUV Vs / V0) or a table in
ln Vs (it may rise, peak and fall), absolute or relative to the file's reference speed.
``drift``: a slow change the channels do not explain - wear growing with the frictional work
(never recovering), a plain trend in time, a step between runs (a belt or road change).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..dynamics import stiffened
from ..prepare import Context
from .base import Array, EffectModel, Index, Param


class SpeedLaw(EffectModel):
    """Speed-dependent friction mu / (1 + LMUV Vs / V0) (the MF 6.1 form, Vs sliding speed)."""

    word = "speed"
    label = "mu / (1 + LMUV Vs / V0)"

    def __init__(self, ctx: Context):
        super().__init__([Param("LMUV", 0.0, -0.5, 5.0, 0.05)])

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        return [cls(ctx)]

    def mu_scale(self, x: Array, ctx: Context, rows: Index) -> Array:
        return 1.0 / np.maximum(1.0 + float(x[0]) * ctx.wheel.Vs[rows] / ctx.V0, 0.05)

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        lnV = np.log(np.geomspace(0.01, 50.0, 24))
        mu = 1.0 / np.maximum(1.0 + float(x[0]) * np.exp(lnV) / ctx.V0, 0.05)
        return {"speed_table": (tuple(map(float, lnV)), tuple(map(float, mu)))}


class SpeedTable(EffectModel):
    """Friction against sliding speed as a table: linear in ln Vs between fixed knots.

    The knots are log-spaced over the sliding speeds where the tyre slides (5th to 99th
    percentile of Vs above 0.05 m/s); the one nearest the median is held at 1 (the scaling
    factors carry the level).

    ``relative``: the file's slip curve is taken as measured at its reference speed V0
    (LONGVL), its fall beyond the peak already the friction at the sliding speeds V0 |s| of
    that speed; at speed V friction is scaled by mu(V |s|) / mu(V0 |s|), so that the file is
    unchanged at V0 (an absolute law in Vs rescales the file's own curve at every speed).
    """

    word = "speed"
    KNOTS = 5

    def __init__(self, ctx: Context, relative: bool = False):
        self.relative = relative
        self.label = (
            "friction table in ln Vs relative to the file's reference speed"
            if relative
            else "friction table in ln Vs (piecewise linear)"
        )
        Vs = ctx.wheel.Vs[ctx.wheel.Vs > 0.05]
        lo, hi = np.percentile(Vs, [5, 99]) if len(Vs) > 10 else (0.1, 3.0)
        self.lnV = np.linspace(np.log(lo), np.log(max(hi, 2.0 * lo)), self.KNOTS)
        mid = np.log(np.median(Vs)) if len(Vs) else 0.0
        self.ref = int(np.argmin(np.abs(self.lnV - mid)))
        super().__init__(
            [
                Param(f"mu_at_{np.exp(v):.2g}_mps", 1.0, 0.3, 2.0, 0.02)
                for i, v in enumerate(self.lnV)
                if i != self.ref
            ]
        )

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        return [cls(ctx), cls(ctx, relative=True)]

    def knots(self, x: Array) -> Array:
        return np.insert(np.asarray(x, float), self.ref, 1.0)

    def mu_scale(self, x: Array, ctx: Context, rows: Index) -> Array:
        Vs, mu = ctx.wheel.Vs[rows], self.knots(x)
        out = np.interp(np.log(np.maximum(Vs, 1e-4)), self.lnV, mu)
        if self.relative:
            Vs_ref = ctx.V0 * Vs / np.maximum(np.abs(ctx.wheel.x("V")[rows]), 1e-3)  # V0 |s|
            out = out / np.interp(np.log(np.maximum(Vs_ref, 1e-4)), self.lnV, mu)
        return np.asarray(out)

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        table = (tuple(map(float, self.lnV)), tuple(map(float, self.knots(x))))
        return {"speed_table": table, "speed_reference_mps": ctx.V0 if self.relative else 0.0}


class Wear(EffectModel):
    """Friction falling with the cumulative frictional work, never recovering (wear: an
    irreversible loss, never a gain), and the slip stiffness rising with it: a worn tread's
    shorter blocks bend less (``stiffening_per_loss``: the relative stiffness gain per unit
    of grip lost). Without it, a warm-up's carcass node stood in for the stiffening (brush
    wear s34 named temperature, 1.115 vs the loss alone 1.141 held-out; with it 1.093)."""

    stable_in_time = False  # wear grows as the work does: each half sees its own part of it
    word = "drift"
    label = "friction falls with cumulative frictional work (wear)"

    def __init__(self, ctx: Context):
        super().__init__(
            [
                Param("loss_per_session", 0.02, 0.0, 0.6, 0.02),
                Param("stiffening_per_loss", 0.0, 0.0, 5.0, 0.5),
            ]
        )

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        return [cls(ctx)]

    def worn(self, x: Array, ctx: Context, rows: Index) -> Array:
        """The grip lost by ``rows`` [share]: the loss over the session times the work done."""
        return float(x[0]) * ctx.wheel.E[rows] / ctx.E_ref

    def mu_scale(self, x: Array, ctx: Context, rows: Index) -> Array:
        return 1.0 - self.worn(x, ctx, rows)

    def per_sample(self, x: Array, ctx: Context, inp: dict[str, Array | None], rows: Index) -> None:
        kappa, alpha = inp["kappa"], inp["alpha"]
        assert kappa is not None and alpha is not None
        k = 1.0 + float(x[1]) * self.worn(x, ctx, rows)
        inp["kappa"], inp["alpha"] = stiffened(kappa, alpha, k)

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        return None  # the session's history


class Trend(EffectModel):
    """Friction changing linearly in time (a plain trend; also the control of a leak)."""

    stable_in_time = False  # a trend's course over the session need not be a line
    of_time = True
    word = "drift"
    label = "friction changes linearly in time (plain trend)"

    def __init__(self, ctx: Context):
        super().__init__([Param("loss_per_session", 0.0, -0.6, 0.6, 0.02)])

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        return [cls(ctx)]

    def mu_scale(self, x: Array, ctx: Context, rows: Index) -> Array:
        return 1.0 - float(x[0]) * ctx.wheel.t[rows] / ctx.t_end

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        return None  # the session's history


class FrictionStep(EffectModel):
    """A step in friction at a fitted time (a belt or road change between runs).

    mu scale = 1 - d H(t - t_c), H a logistic of width STEP_WIDTH_S; after ``settle`` a ramp
    across the gap between fitted sweeps that holds t_c, or a step at a belt stop in that gap.
    The cost is flat in t_c across a pause (no force there) with a local minimum at each, so
    the fit starts from every pause (at most MAX_STARTS, evenly picked) and belt stop.
    """

    word = "drift"
    label = "friction step at a fitted time"
    stable_in_time = False  # a change at one time: each half sees one side of it
    STEP_WIDTH_S = 1.0
    MAX_STARTS = 24
    STOP_SPEED_MPS = 0.5  # a belt stop: below this speed for STOP_MIN_S or more
    STOP_MIN_S = 5.0

    def __init__(self, ctx: Context):
        w = ctx.wheel
        mids = sorted(
            float(np.mean(w.t[s.index[[0, -1]]])) for s in w.segments if s.kind == "pause"
        )
        if len(mids) > self.MAX_STARTS:
            mids = [mids[i] for i in np.linspace(0, len(mids) - 1, self.MAX_STARTS).astype(int)]
        self.stops = self._stops(ctx)
        super().__init__(
            [
                Param("t_step_s", 0.5 * ctx.t_end, 0.0, ctx.t_end, 0.05 * ctx.t_end),
                Param("step_mu_loss", 0.0, -0.6, 0.6, 0.02),
                # the width of the ramp across the gap that holds the step (set by settle)
                Param("ramp_s", 0.0, 0.0, ctx.t_end, 1.0, fitted=False),
            ],
            [{"t_step_s": m} for m in sorted({*mids, *self.stops})],
        )

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        return [cls(ctx)]

    def _stops(self, ctx: Context) -> list[float]:
        """Middles of the belt stops [s from start]."""
        w = ctx.wheel
        halted = np.concatenate([[False], np.abs(w.x("V")) < self.STOP_SPEED_MPS, [False]])
        edges = np.flatnonzero(np.diff(halted.astype(np.int8)))
        return [
            0.5 * (w.t[i0] + w.t[i1 - 1])
            for i0, i1 in zip(edges[::2], edges[1::2], strict=True)
            if w.t[i1 - 1] - w.t[i0] >= self.STOP_MIN_S
        ]

    def settle(self, x: Array, seen: Sequence[tuple[Context, Index]]) -> Array:
        """The change point to the belt stop in the gap between the fitted sweeps it lies in,
        else to the middle of the gap.

        Between two fitted sweeps the cost is flat in t_c. A belt or road change happens
        between runs (PHYSICS.md), so a belt stop in the gap is where it is. Without one, the
        model predicts across the gap the expected friction for a change time uniform in it
        (a ramp): a sweep in the gap that the fit did not see is never given the wrong side
        of the step in full.
        """
        ctx, rows = seen[0]  # a session's own change: one wheel
        w = ctx.wheel
        x = np.array(x, dtype=float)
        tc = float(x[0])
        moving = (np.abs(w.x("kappa")[rows]) > 0.005) | (np.abs(w.x("alpha")[rows]) > 0.01)
        t_fit = w.t[rows][moving]
        before, after = t_fit[t_fit < tc], t_fit[t_fit >= tc]
        x[2] = 0.0
        if len(before) and len(after):
            lo, hi = float(before.max()), float(after.min())
            stops = [m for m in self.stops if lo < m < hi]
            if stops:
                lo, hi = stops[0], stops[-1]
            x[0], x[2] = 0.5 * (lo + hi), hi - lo
        return x

    def mu_scale(self, x: Array, ctx: Context, rows: Index) -> Array:
        t = ctx.wheel.t[rows]
        tc, d, ramp = float(x[0]), float(x[1]), float(x[2])
        if ramp > self.STEP_WIDTH_S:
            return 1.0 - d * np.clip((t - tc + 0.5 * ramp) / ramp, 0.0, 1.0)
        z = np.clip((t - tc) / self.STEP_WIDTH_S, -50.0, 50.0)
        return 1.0 - d / (1.0 + np.exp(-z))

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        return None  # the session's history
