"""Tyre temperature: a recorded channel refitted, or concealed heating inferred.

The grip of rubber has a temperature window (PHYSICS.md): it rises towards an optimum and
falls beyond it; stiffness falls with the carcass temperature. The .tir temperature extension
(INTERFACE.md: TT*1-4, quadratics in dT about NOMTEMP, on one temperature input) carries a
recorded temperature's stiffness TT*1; what it cannot carry the effects file does: a window
may be skewed and flat beyond its optimum, which a quadratic cannot follow, and a quadratic
fitted on some temperatures keeps rising beyond them, so the grip is a table against the
temperature (similarity method); and the stiffness falls with a carcass that lags the tread,
a factor per K of the carcass (a hidden node, or the recorded channel through its own lag).
Concealed, the tread temperature is the sum of two lumped nodes heated by the frictional
power: the tread surface (seconds) on the carcass (minutes), each cooling back when the power
stops, plus what is left of a pre-warmed start.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tire_model_ros.model.states import Carcass, Node

from ..dynamics import first_order, stiffened
from ..prepare import THERMAL_RISE_REF_K, Context
from .base import Array, EffectModel, Index, Param

TAU_FAST_S = (0.3, 60.0)  # tread surface (PHYSICS.md: seconds)
TAU_SLOW_S = (30.0, 900.0)  # carcass (PHYSICS.md: 1-5 min; up to 15 for a big tyre)
TT_ALL = tuple(f"TT{a}{i}" for a in "XY" for i in (1, 2, 3, 4))
STIFFNESS_PER_K = 0.02  # bound of the carcass' stiffness loss [1/K] (PHYSICS.md: -10 % / 10 K)
TT_SPAN = 2.0  # bound of a TT coefficient change (dT is about 1 over the convention's rise)
# A temperature law keeps each factor (stiffness: 1 + TT*1 dT + TT*2 dT^2, grip: TT*3, TT*4,
# the guide's) within these over the temperatures it is applied to (PHYSICS.md: grip -10 % per
# +10 degC at most, stiffness larger cold): beyond, a fitted quadratic is extrapolating.
FACTOR_RANGE = (0.5, 1.5)
PENALTY_WEIGHT = 300.0  # noise units per unit of factor outside its range
CARCASS_START_K = (-30.0, 60.0)  # a recorded channel's carcass at the start [K from it]
RECORDED_T_MIN_STD_K = 0.5  # a recorded temperature that moves less tells nothing
# A recorded temperature spans enough of the window to show its shape: the grip is a table at
# these percentiles of the channel (the median's 1: the baseline's friction scaling is there)
GRIP_KNOTS_PCT = (2.0, 25.0, 50.0, 75.0, 98.0)
# Concealed, the temperature is the model's own, without a sensor's outliers: the table spans
# all of it (a tyre brought hot is hotter than the rest of the session for a minute or two),
# from a knot at ambient where it is 1, as the quadratic it takes over from
HIDDEN_KNOTS_PCT = (0.0, 25.0, 50.0, 75.0, 100.0)
# ... and fitted first with a quadratic friction scale in dT for a guide
GUIDE = ("grip_per_dT", "grip_per_dT2")
GRIP_KNOT_MIN_K = 0.1  # knots closer than this (a quantised channel) are spread apart


def _axes(ctx: Context) -> list[str]:
    """X where slip ratio is swept, Y where slip angle is."""
    return [axis for axis, key in (("X", "x"), ("Y", "y")) if ctx.informative[key]]


def _stiffness_params(ctx: Context) -> list[Param]:
    """Stiffness TT1, one for both directions (the rubber's: TTX1 = TTY1; a direction swept
    in a few sweeps borrows the other's): falling with temperature (PHYSICS.md:
    monotonically, so linear, TT*2 left as the file has it)."""
    return [Param("TT1", 0.0, -TT_SPAN, 0.0, 0.1)] if _axes(ctx) else []


def _carcass_stiffness() -> Param:
    """The slip stiffness' loss per K of the carcass (PHYSICS.md: stiffness falls with the
    carcass temperature, monotonically): one for both directions (the rubber's; a direction
    swept in a few sweeps borrows the other's)."""
    return Param("stiffness_per_K", 0.0, -STIFFNESS_PER_K, 0.0, 0.002)


def _dT(T: Array, ref_C: float) -> Array:
    """The TT convention's normalised increment (T - ref)/ref (INTERFACE.md)."""
    return (T - ref_C) / max(ref_C, 1e-6)


def _rising(knots: Array) -> Array:
    """The grip table's knots [degC] strictly rising."""
    k = np.array(knots, dtype=float)
    for i in range(1, len(k)):
        k[i] = max(k[i], k[i - 1] + GRIP_KNOT_MIN_K)
    return k


class _TTModel(EffectModel):
    """Shared: the grip table (a friction scale at knots of the temperature, 1 at the
    ``anchor``'s; its parameters last), the TT parameters, applied to TTX and TTY additively
    to the file's, and the factors they make stay physical over the model's temperatures."""

    word = "temperature"
    anchor: int  # the knot whose friction scale is 1
    n_knots: int

    def knots(self, x: Array, ctx: Context) -> Array:
        """The grip table's knots [degC]."""
        raise NotImplementedError

    def grip_params(self, names: list[str], stage: int = 0) -> list[Param]:
        """A friction scale at each knot but the anchor's, named ``names``."""
        return [
            Param(n, 1.0, *FACTOR_RANGE, 0.05, stage=stage)
            for i, n in enumerate(names)
            if i != self.anchor
        ]

    def grip(self, x: Array) -> tuple[float, ...]:
        """The friction scale at each knot (the grip parameters come last)."""
        mu = [float(v) for v in x[len(x) - self.n_knots + 1 :]]
        mu.insert(self.anchor, 1.0)
        return tuple(mu)

    def grip_table(self, x: Array, ctx: Context) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """What the effects file carries: the knots [degC] and the scale at each."""
        return tuple(float(k) for k in self.knots(x, ctx)), self.grip(x)

    def mu_scale(self, x: Array, ctx: Context, rows: Index) -> Array:
        return np.interp(self.temperature(x, ctx)[rows], self.knots(x, ctx), self.grip(x))

    def settle(self, x: Array, seen: Sequence[tuple[Context, Index]]) -> Array:
        """The grip held beyond the hottest fitted sample (PHYSICS.md: flat beyond the
        window): a knot whose neighbours below are all hotter is not seen by any fitted row,
        and would otherwise keep its start and bend the grip back to it."""
        ctx = seen[0][0]  # a wheel's own state: one wheel
        T_max = max(float(np.max(self.temperature(x, c)[rows])) for c, rows in seen)
        knots = self.knots(x, ctx)
        mu = list(self.grip(x))
        for i in range(1, len(knots)):
            if knots[i - 1] >= T_max:
                mu[i] = mu[i - 1]
        return self.with_grip(x, mu)

    def with_grip(self, x: Array, mu: Sequence[float] | Array) -> Array:
        """``x`` with the friction scale ``mu`` at each knot (the anchor's left at 1)."""
        x = np.array(x, dtype=float)
        x[len(x) - self.n_knots + 1 :] = np.delete(np.asarray(mu, dtype=float), self.anchor)
        return x

    def coef(self, x: Array, ctx: Context) -> dict[str, float]:
        out = {}
        for k, v in zip(self.pnames, x, strict=True):
            if k.startswith("TT"):
                for axis in _axes(ctx):
                    name = f"TT{axis}{k[2:]}"
                    out[name] = ctx.base.get(name, 0.0) + float(v)
        return out

    def temperature(self, x: Array, ctx: Context) -> Array:
        raise NotImplementedError

    def reference_C(self, ctx: Context) -> float:
        """The temperature the TT terms are relative to: NOMTEMP."""
        return ctx.T_amb

    def factors(self, x: Array, ctx: Context, dT: Array) -> list[Array]:
        """The temperature laws' factors at ``dT``: the file's TT terms with the fitted ones
        (stiffness TT*1/TT*2, grip TT*3/TT*4, per direction)."""
        c = {**ctx.base, **self.coef(x, ctx)}
        out = []
        for axis in _axes(ctx):
            for lin, quad in ((1, 2), (3, 4)):
                a, b = c.get(f"TT{axis}{lin}", 0.0), c.get(f"TT{axis}{quad}", 0.0)
                out.append(1.0 + a * dT + b * dT**2)
        return out

    def penalty(self, x: Array, ctx: Context) -> Array:
        T = self.temperature(x, ctx)
        dT = _dT(np.linspace(float(T.min()), float(T.max()), 9), self.reference_C(ctx))
        lo, hi = FACTOR_RANGE
        out = [np.maximum(lo - f, 0.0) + np.maximum(f - hi, 0.0) for f in self.factors(x, ctx, dT)]
        return PENALTY_WEIGHT * np.concatenate(out) if out else np.zeros(0)


class HiddenThermal(_TTModel):
    """Concealed heating: the grip follows T = T_amb + fast + share * slow (the tread surface
    on the carcass, heated by k P_fric; the carcass node starts at a pre-warmed T0) through
    the grip table at percentiles of T, the slip stiffness the carcass alone: a factor
    1 + c * slow [1/K]. The table's freedom would lead the nodes astray from a start: they are
    fitted first with a quadratic grip factor (:data:`GUIDE`), whose shape the table then
    takes over (a quadratic keeps rising beyond the temperatures it was fitted on, the table
    holds).

    ``mode`` "physical" is the model; "memoryless" (T follows the power at once), "scrambled"
    (the same nodes driven by a block-shuffled power: the tread's seconds tested), "reversed"
    (the power played backwards: the carcass' minutes tested) and "trend" (T a plain function
    of time: a ramp, and the pre-warmed start's cooling that the model has without any power)
    are its controls. The trend must have that cooling: a model left with it alone (no power
    heating, a flat table) is a decay in time, which mimics a slow leak's stiffness change
    (brush multi2_b s32: a leak and wear named temperature against a ramp-only control).
    """

    stable_in_time = False  # the first half sees the tyre warm up, the second hot

    concealed = True
    shown_by_drive = True
    anchor, n_knots = 0, 1 + len(HIDDEN_KNOTS_PCT)

    def __init__(self, ctx: Context, mode: str = "physical"):
        self.mode = mode
        self.of_time = mode == "trend"
        self.label = {
            "physical": "hidden tread and carcass nodes heated by frictional power",
            "memoryless": "control: temperature follows frictional power at once",
            "scrambled": "control: the nodes driven by a time-scrambled power",
            "reversed": "control: the nodes driven by the power played backwards",
            "trend": "control: temperature a plain trend in time",
        }[mode]
        nodes = [
            Param("tau_fast_s", 3.0, *TAU_FAST_S, 3.0),
            Param("tau_slow_s", 150.0, *TAU_SLOW_S, 80.0),
            # the carcass node's steady rise per watt, a multiple of the tread node's
            Param("slow_gain", 1.0, 0.0, 20.0, 0.5),
            Param("T0_K", 0.0, 0.0, 90.0, 10.0),  # a pre-warmed start (0: at ambient)
        ]
        cooling = [nodes[1], nodes[3]]
        ramp = [Param("ramp_K", THERMAL_RISE_REF_K, 0.0, 90.0, 10.0)]
        head = {"memoryless": [], "trend": [*cooling, *ramp]}.get(mode, nodes)
        stiff = [_carcass_stiffness()]
        starts = [
            {"tau_fast_s": 1.0},
            {"tau_fast_s": 10.0},
            {"tau_slow_s": 60.0, "slow_gain": 2.0},
            {"T0_K": 30.0},  # a tyre brought warm: it cools before it heats
        ]
        guide = [Param(k, 0.0, -TT_SPAN, TT_SPAN, 0.1, stage=1) for k in GUIDE]
        names = ["mu_at_T_amb", *(f"mu_at_T_p{q:03.0f}" for q in HIDDEN_KNOTS_PCT)]
        table = self.grip_params(names, stage=2)
        starts = [st for st in starts if set(st) <= {p.name for p in head}]
        super().__init__([*head, *stiff, *guide, *table], starts)
        self.n_nodes = len(head)  # the parameters first: what the nodes depend on

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        if ctx.wheel.inputs["T"] is not None or not _axes(ctx):
            return []
        return [cls(ctx)]

    def controls(self, ctx: Context) -> list[EffectModel]:
        return [HiddenThermal(ctx, m) for m in ("memoryless", "scrambled", "reversed", "trend")]

    def _node_key(self, x: Array) -> tuple[float, ...]:
        """The parameters the nodes depend on (the controls without nodes: none)."""
        return tuple(float(v) for v in x[: self.n_nodes])

    def nodes(self, x: Array, ctx: Context) -> tuple[Array, Array]:
        """The tread (fast) and carcass (slow) rises [K] on the convention's scale."""
        return self.remembered(  # type: ignore[no-any-return]
            "nodes", ctx, self._node_key(x), lambda: self._integrate(x, ctx)
        )

    def _integrate(self, x: Array, ctx: Context) -> tuple[Array, Array]:
        w, k = ctx.wheel, ctx.k_thermal
        if self.mode == "memoryless":
            return k * w.P, k * w.P
        v = self.values(x)
        if self.mode == "trend":
            ramp = v["ramp_K"] * w.t / ctx.t_end
            cooling = first_order(0.0 * ramp, w.t, v["tau_slow_s"], v["T0_K"])
            return np.zeros_like(ramp), ramp + cooling
        P = {"scrambled": w.P[w.scramble], "reversed": w.P[::-1]}.get(self.mode, w.P)
        fast = first_order(k * P, w.t, v["tau_fast_s"])
        slow = first_order(k * v["slow_gain"] * P, w.t, v["tau_slow_s"], v["T0_K"])
        return fast, slow

    def knots(self, x: Array, ctx: Context) -> Array:
        """Ambient, and percentiles of the hidden temperature over the session."""

        def make() -> Array:
            T = np.percentile(self.temperature(x, ctx), HIDDEN_KNOTS_PCT)
            return _rising(np.concatenate([[ctx.T_amb], T]))

        return self.remembered("knots", ctx, self._node_key(x), make)  # type: ignore[no-any-return]

    def guide(self, x: Array, dT: Array) -> Array:
        """The quadratic grip factor at ``dT`` (the TT convention's, from ambient)."""
        v = self.values(x)
        return 1.0 + v[GUIDE[0]] * dT + v[GUIDE[1]] * dT**2

    def mu_scale(self, x: Array, ctx: Context, rows: Index) -> Array:
        dT = _dT(self.temperature(x, ctx)[rows], ctx.T_amb)
        return self.guide(x, dT) * super().mu_scale(x, ctx, rows)

    def factors(self, x: Array, ctx: Context, dT: Array) -> list[Array]:
        """With the guide's, kept in range too over the temperatures it is applied to."""
        return [*super().factors(x, ctx, dT), self.guide(x, dT)]

    def handover(self, x: Array, ctx: Context) -> Array:
        """The table takes the quadratic's grip at its knots (1 at ambient for both: the
        same friction scale there, linear between), the quadratic returns to none."""
        q = self.guide(x, _dT(self.knots(x, ctx), ctx.T_amb))
        x = self.with_grip(x, np.clip(np.asarray(self.grip(x)) * q, *FACTOR_RANGE))
        x[[self.pnames.index(k) for k in GUIDE]] = 0.0
        return x

    def temperature(self, x: Array, ctx: Context) -> Array:
        """The hidden tread temperature [degC] that the grip follows."""

        def make() -> Array:
            fast, slow = self.nodes(x, ctx)
            return ctx.T_amb + (fast if self.mode == "memoryless" else fast + slow)

        return self.remembered("T", ctx, self._node_key(x), make)  # type: ignore[no-any-return]

    def inputs(self, x: Array, ctx: Context, inp: dict[str, Array | None]) -> None:
        inp["T"] = self.temperature(x, ctx)

    def per_sample(self, x: Array, ctx: Context, inp: dict[str, Array | None], rows: Index) -> None:
        kappa, alpha = inp["kappa"], inp["alpha"]
        assert kappa is not None and alpha is not None
        c = self.values(x)["stiffness_per_K"]
        k = np.maximum(1.0 + c * self.nodes(x, ctx)[1][rows], 0.3)
        inp["kappa"], inp["alpha"] = stiffened(kappa, alpha, k)

    def inferred(self, x: Array, ctx: Context, inp: Mapping[str, Array | None]) -> dict[str, Array]:
        return {"T": self.temperature(x, ctx)}

    def reported(self, x: Array, ctx: Context) -> dict[str, float]:
        """With the convention that sets the hidden scale (K per W of the nodes, ambient) and
        the grip table's knots; without the guide, handed over to the table."""
        v = {k: val for k, val in self.values(x).items() if k not in GUIDE}
        knots = self.knots(x, ctx)[1:]
        v.update(
            {f"T_p{q:03.0f}_C": float(k) for q, k in zip(HIDDEN_KNOTS_PCT, knots, strict=True)}
        )
        return {**v, "gain_K_per_W": ctx.k_thermal, "T_amb_C": ctx.T_amb}

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        v = self.values(x)
        return {
            "T_amb_C": ctx.T_amb,
            "thermal": Node(v["tau_fast_s"], ctx.k_thermal),
            "thermal_slow": Node(v["tau_slow_s"], ctx.k_thermal * v["slow_gain"]),
            "thermal_slow_start_K": v["T0_K"],
            "stiffness_per_K": v["stiffness_per_K"],
            "grip_table": self.grip_table(x, ctx),
        }


class RecordedThermal(_TTModel):
    """A recorded tread temperature: the grip and stiffness laws the file lacks (or has
    wrong) fitted on it. A sensor reads the surface; beneath it the tread's bulk and the
    carcass lag (PHYSICS.md: the surface in seconds on the bulk in minutes). The grip feels
    ``T_surface_weight`` of the channel and the rest of it through a first-order lag
    ``tau_T_s`` (the tread beneath the sensor).

    Grip against it is a window of any shape (PHYSICS.md: an optimum, often skewed, flat
    beyond): a friction table at percentiles of the channel (similarity method, as the
    speed law), which the quadratic TT*3, TT*4 cannot follow over a session that crosses the
    optimum and saturates (car heat_recorded s29: the rest was named wear). The slip
    stiffness falls through TT*1 on the temperature the grip feels, and with the carcass
    (PHYSICS.md: stiffness falls with the carcass temperature), as the concealed model's: the
    channel through its own lag ``tau_carcass_s`` from a start ``T0_K`` above its first
    sample (a tyre brought warm). Through TT*1 alone the stiffness followed the surface, and
    a tyre below its grip optimum, whose grip rises as the surface warms while its stiffness
    falls with the slower bulk, was left far off its true forces (brush heat_recorded s45:
    held-out 76 -> 40.5 N against a 33.3 N floor; 34.2 N with the carcass). ``mode``
    "scrambled" (the channel block-shuffled) and "trend" (a ramp in time of the same range)
    are its controls: the recorded temperature must explain more than a drift that happens
    to go with it."""

    stable_in_time = False  # each half sees its own range of temperature

    concealed = False
    anchor, n_knots = GRIP_KNOTS_PCT.index(50.0), len(GRIP_KNOTS_PCT)

    def __init__(self, ctx: Context, mode: str = "recorded"):
        self.mode = mode
        self.label = {
            "recorded": "recorded temperature: grip table, TTX/TTY, carcass stiffness",
            "scrambled": "control: the recorded temperature time-scrambled",
            "trend": "control: a temperature ramp in time",
        }[mode]
        T = ctx.wheel.inputs["T"]
        assert T is not None
        # A file without temperature terms leaves their reference free: the session's median
        # recorded temperature, so that dT is centred on the data (a quadratic about a
        # NOMTEMP far below every sample is ill-conditioned and extrapolates wildly). The
        # carcass' stiffness is the baseline's where the lagged channel is at that median.
        no_terms = all(ctx.base.get(k, 0.0) == 0.0 for k in TT_ALL)
        self.T_ref = round(float(np.median(T)), 1)
        self.ref = self.T_ref if no_terms else ctx.T_amb
        lag = [
            Param("tau_T_s", 0.0, 0.0, 600.0, 5.0),  # the tread's bulk lags the surface
            Param("T_surface_weight", 1.0, 0.0, 1.0, 0.2),  # what the grip feels of each
            Param("tau_carcass_s", 120.0, *TAU_SLOW_S, 60.0),  # the carcass lags further
            # the carcass at the start above the first sample (a tyre brought warm: > 0)
            Param("T0_K", 0.0, *CARCASS_START_K, 10.0),
        ]
        self._knots = np.round(_rising(np.percentile(T, GRIP_KNOTS_PCT)), 2)
        grip = self.grip_params([f"mu_at_{k:.2f}_C" for k in self._knots])  # >= 0.1 K apart
        starts = [{"tau_T_s": 120.0, "T_surface_weight": 0.5}]
        super().__init__([*lag, _carcass_stiffness(), *_stiffness_params(ctx), *grip], starts)

    def reference_C(self, ctx: Context) -> float:
        return self.ref

    def knots(self, x: Array, ctx: Context) -> Array:
        """At percentiles of the channel."""
        return self._knots

    def coef(self, x: Array, ctx: Context) -> dict[str, float]:
        out = super().coef(x, ctx)
        if self.ref != ctx.T_amb:
            out["NOMTEMP"] = self.ref
        return out

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        T = ctx.wheel.inputs["T"]
        if T is None or float(np.std(T)) < RECORDED_T_MIN_STD_K or not _axes(ctx):
            return []
        return [cls(ctx)]

    def controls(self, ctx: Context) -> list[EffectModel]:
        return [RecordedThermal(ctx, m) for m in ("scrambled", "trend")]

    def channel(self, ctx: Context) -> Array:
        """The recorded temperature [degC] (a control's: scrambled, or a ramp)."""
        T = ctx.wheel.inputs["T"]
        assert T is not None
        if self.mode == "scrambled":
            return T[ctx.wheel.scramble]
        if self.mode == "trend":
            lo, hi = np.percentile(T, [5, 95])
            return np.asarray(lo + (hi - lo) * ctx.wheel.t / ctx.t_end, dtype=np.float64)
        return T

    def carcass(self, x: Array, ctx: Context) -> Array:
        """The channel through the lag ``tau_carcass_s`` from its start [degC]."""

        def make() -> Array:
            T = self.channel(ctx)
            return first_order(T, ctx.wheel.t, float(x[2]), float(T[0] + x[3]))

        key = (float(x[2]), float(x[3]))
        return self.remembered("carcass", ctx, key, make)  # type: ignore[no-any-return]

    def temperature(self, x: Array, ctx: Context) -> Array:
        """The temperature the grip feels [degC]."""
        T, w = self.channel(ctx), float(x[1])
        return w * T + (1.0 - w) * first_order(T, ctx.wheel.t, float(x[0]), float(T[0]))

    def per_sample(self, x: Array, ctx: Context, inp: dict[str, Array | None], rows: Index) -> None:
        kappa, alpha = inp["kappa"], inp["alpha"]
        assert kappa is not None and alpha is not None
        k = np.maximum(1.0 + float(x[4]) * (self.carcass(x, ctx)[rows] - self.T_ref), 0.3)
        inp["kappa"], inp["alpha"] = stiffened(kappa, alpha, k)

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        return {
            "T_lag_s": float(x[0]),
            "T_surface_weight": float(x[1]),
            "T_carcass": Carcass(float(x[2]), float(x[3]), float(x[4]), self.T_ref),
            "grip_table": self.grip_table(x, ctx),
        }

    def inputs(self, x: Array, ctx: Context, inp: dict[str, Array | None]) -> None:
        inp["T"] = self.temperature(x, ctx)
