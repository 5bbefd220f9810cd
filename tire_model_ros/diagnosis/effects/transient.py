"""Force lagging slip: relaxation in travelled distance, or a channel recorded late.

PHYSICS.md tells them apart: relaxation scales with the slip rate over the speed and vanishes
in slow sweeps; a delay is the same lag in time at every speed (and a negative one is not a
delay).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..dynamics import delayed, lowpass, relaxed_slip, zero_phase
from ..prepare import Context
from .base import Array, EffectModel, Param
from .curve import curve_shapes

KAPPA_PER_ALPHA_LENGTH = 0.5  # sigma_kappa / sigma_alpha where only sigma_alpha is fitted


class Relaxation(EffectModel):
    """First-order lag of slip in travelled distance with lengths that vary with load and
    slip: sigma = sigma0 (K(Fz) / K(FNOMIN))^q (1 - c + c dF/dslip / K).

    The load shape follows the MF 6.1 lengths (sigma = K / C, Pacejka 2012 §7.2.1, the carcass
    stiffness C taken constant); the slip shape is the single-contact-point model's shortening
    as the force curve flattens towards saturation.

    ``zero_phase`` is its control: the same lengths run forwards and backwards, which smooths
    the slip's noise as much but does not lag it.
    """

    word = "relaxation"

    def __init__(self, ctx: Context, zero_phase: bool = False):
        self.zero_phase = zero_phase
        self.label = (
            "control: the same lengths forwards and backwards (smoothing, no lag)"
            if zero_phase
            else "lag in travelled distance, lengths varying with load and slip"
        )
        params = []
        if ctx.moving["y"]:
            params.append(Param("sigma_alpha_m", 0.4, 0.0, 3.0, 0.2))
        # sigma_kappa is fitted only where slip ratio is swept in every fold; where it merely
        # moves, it follows sigma_alpha at the usual ratio (PHYSICS.md: 0.25 m vs ~0.5 m).
        self.kappa_ratio = 0.0
        if ctx.informative["x"] or (ctx.moving["x"] and not ctx.moving["y"]):
            params.append(Param("sigma_kappa_m", 0.25, 0.0, 3.0, 0.2))
        elif ctx.moving["x"]:
            self.kappa_ratio = KAPPA_PER_ALPHA_LENGTH
        params += [
            Param("load_exponent", 1.0, 0.0, 2.0, 0.3),
            Param("slip_share", 0.5, 0.0, 1.0, 0.2),
        ]
        super().__init__(params)

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        return [cls(ctx)] if ctx.moving["x"] or ctx.moving["y"] else []

    def lengths(self, x: Array, ctx: Context) -> dict[str, Array]:
        v = self.values(x)
        sh = curve_shapes(ctx)
        q, c = v["load_exponent"], v["slip_share"]
        out = {}
        for key, name in (("alpha", "sigma_alpha_m"), ("kappa", "sigma_kappa_m")):
            s0 = v.get(name)
            if s0 is None and key == "kappa" and self.kappa_ratio > 0:
                s0 = self.kappa_ratio * v["sigma_alpha_m"]
            if s0 is not None:
                out[key] = s0 * sh[f"load_{key}"] ** q * (1.0 - c + c * sh[f"slip_{key}"])
        return out

    def controls(self, ctx: Context) -> list[EffectModel]:
        return [Relaxation(ctx, zero_phase=True)]

    def inputs(self, x: Array, ctx: Context, inp: dict[str, Array | None]) -> None:
        w = ctx.wheel
        lag = zero_phase if self.zero_phase else relaxed_slip
        for key, sigma in self.lengths(x, ctx).items():
            inp[key] = lag(inp[key], w.t, w.x("V"), sigma)  # type: ignore[arg-type]

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        return None  # a simulator's own transient tyre model does this


class Delay(EffectModel):
    """The forces recorded late against the slip: a pure delay and the DAQ's first-order
    filter (both >= 0: a force that leads its slip is not a delay).

    Which channels share the forces' clock is the instrumentation's: a rig's commanded load is
    on time, a wheel-force transducer's own Fz is late with its Fx and Fy. Where the load moves
    within a delay's span (a car's load transfer), the two are told apart by a model each;
    elsewhere they predict the same and only the first is tried.

    ``zero_phase`` is its control: a first-order filter run forwards and backwards in time,
    which smooths the slip's noise without lagging it.
    """

    word = "time_delay"

    def __init__(self, ctx: Context, load_with_forces: bool = False, zero_phase: bool = False):
        self.load_with_forces = load_with_forces
        self.zero_phase = zero_phase
        which = "forces and their load" if load_with_forces else "forces"
        self.label = (
            "control: the slip smoothed forwards and backwards in time (no lag)"
            if zero_phase
            else f"{which} recorded late against the slip: pure delay and first-order filter"
        )
        smooth = [Param("tau_smooth_s", 0.01, 0.0, 0.3, 0.01)]
        lag = [
            Param("tau_delay_s", 0.01, 0.0, 0.3, 0.01),
            Param("tau_filter_s", 0.0, 0.0, 0.1, 0.005),
        ]
        super().__init__(smooth if zero_phase else lag)

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        if not (ctx.moving["x"] or ctx.moving["y"]):
            return []
        out: list[EffectModel] = [cls(ctx)]
        return out + ([cls(ctx, True)] if _load_moves(ctx) else [])

    def controls(self, ctx: Context) -> list[EffectModel]:
        return [Delay(ctx, self.load_with_forces, zero_phase=True)]

    def inputs(self, x: Array, ctx: Context, inp: dict[str, Array | None]) -> None:
        t = ctx.wheel.t
        for key in ("kappa", "alpha", "gamma") + (() if self.load_with_forces else ("Fz",)):
            v = inp[key]
            assert v is not None
            if self.zero_phase:
                inp[key] = zero_phase(v, t, np.ones_like(t), float(x[0]))
            else:
                inp[key] = lowpass(delayed(v, t, float(x[0])), t, float(x[1]))

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        return None  # an artefact of the recording, not of the tyre


LOAD_MOVES_SPAN_S = 0.05  # a delay of tens of ms (PHYSICS.md)
LOAD_MOVES_SHARE = 0.01  # of FNOMIN, at the 90th percentile of the load's change over the span


def _load_moves(ctx: Context) -> bool:
    """Whether the recorded load changes within a delay's span often enough that delaying it
    or not changes the model: on a car, load transfer; on a rig, the load held per sweep."""
    t, Fz = ctx.wheel.t, ctx.wheel.x("Fz")
    change = np.abs(np.interp(t - LOAD_MOVES_SPAN_S, t, Fz) - Fz)
    return bool(np.percentile(change, 90) > LOAD_MOVES_SHARE * ctx.base["FNOMIN"])
