"""Inflation pressure: a recorded channel refitted, or a concealed change inferred.

Concealed, the pressure changes in two ways (PHYSICS.md): a sealed tyre's gas warms (a lumped
gas node heated by the frictional power, minutes) and its pressure follows the gas law; a slow
leak lowers it in time, with no link to heat. Both act through the file's own pressure terms
(PPX*, PPY*), so they can only be told where the file has them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from tire_model_ros.model.states import Node, gas_pressure_Pa

from ..dynamics import first_order
from ..prepare import Context
from .base import Array, EffectModel, Param, coefficient_params
from .friction import Trend
from .static import inclination_moves

# MF 6.1: Kxk (PPX1, PPX2), mux (PPX3, PPX4), Kya (PPY1, PPY2), muy (PPY3, PPY4), and the
# camber stiffness Kyg0 (PPY5, 4.E30) where the inclination moves: a programme that runs its
# low pressure at an inclination (flattrac pressure_recorded s1) otherwise lets the camber
# coefficients take the pressure's camber thrust.
PRESSURE_TERMS = ("PPX1", "PPX2", "PPX3", "PPX4", "PPY1", "PPY2", "PPY3", "PPY4", "PPY5")
RECORDED_P_MIN_STD = 0.01  # of the nominal pressure: a channel that moves less tells nothing


def _file_has_pressure_terms(ctx: Context) -> bool:
    return any(abs(ctx.base.get(k, 0.0)) > 0 for k in PRESSURE_TERMS)


def _terms(ctx: Context) -> list[str]:
    inclined = inclination_moves(ctx)
    return [
        k
        for k in PRESSURE_TERMS
        if (k[2] == "X" and ctx.informative["x"])
        or (k[2] == "Y" and ctx.informative["y"] and (k != "PPY5" or inclined))
    ]


class SealedGas(EffectModel):
    """Concealed: a gas node heated by frictional power, the gas law, the file's terms.

    The node may start pre-warmed (``gas_T0_K`` above ambient: a tyre brought warm to the rig
    or the track), its pressure then falling back as the gas cools while the power heats it.

    Where the tread temperature is recorded, it drives the gas node instead of the power (a
    recorded channel is a thermometer: the gas follows the tread with a lag, heating less).
    ``mode`` "physical" is the model; "memoryless", "reversed" (the drive played backwards:
    a node of minutes is not tested by shuffling seconds) and "trend" (the gas a ramp in time
    of either sign, and the pre-warmed start's cooling that the model has without any power)
    are its controls.
    """

    stable_in_time = False  # the first half sees the gas warm up, the second warm

    word = "pressure"
    concealed = True

    def __init__(self, ctx: Context, mode: str = "physical"):
        self.mode = mode
        self.of_time = mode == "trend"
        self.label = {
            "physical": "hidden gas node heated by frictional power, gas law, file's terms",
            "memoryless": "control: gas temperature follows frictional power at once",
            "reversed": "control: the gas node driven by the power played backwards",
            "trend": "control: gas temperature a plain function of time",
        }[mode]
        self.by_T = ctx.wheel.inputs["T"] is not None
        gain = (
            Param("gas_share_of_tread_rise", 0.5, 0.0, 2.0, 0.1)
            if self.by_T
            else Param("gain_gas_K_per_kW", 2.0, 0.0, 300.0, 2.0)
        )
        cooling = [
            Param("tau_gas_s", 120.0, 20.0, 1800.0, 60.0),
            Param("gas_T0_K", 0.0, 0.0, 60.0, 10.0),  # a pre-warmed start (0: at ambient)
        ]
        params = {
            "physical": [*cooling, gain],
            "memoryless": [gain],
            "trend": [*cooling, Param("ramp_K", 0.0, -60.0, 60.0, 5.0)],
        }
        params["reversed"] = params["physical"]
        starts = [{"tau_gas_s": 30.0}, {"tau_gas_s": 600.0}]
        super().__init__(params[mode], starts if mode != "memoryless" else [])

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        if ctx.wheel.inputs["p"] is not None or not _file_has_pressure_terms(ctx):
            return []
        return [cls(ctx)]

    def controls(self, ctx: Context) -> list[EffectModel]:
        return [SealedGas(ctx, m) for m in ("memoryless", "reversed", "trend")]

    def drive(self, x: Array, ctx: Context) -> Array:
        """The gas node's input [K]: the share of the recorded tread rise over its start, or
        the power times the gain."""
        w = ctx.wheel
        if self.by_T:
            T = w.inputs["T"]
            assert T is not None
            return np.asarray(float(x[-1]) * (T - T[0]), dtype=np.float64)
        return float(x[-1]) * 1e-3 * w.P

    def pressure(self, x: Array, ctx: Context) -> Array:
        """The hidden gauge pressure [Pa] (integrated once per parameter set)."""
        return self.remembered(  # type: ignore[no-any-return]
            "p", ctx, tuple(float(v) for v in x), lambda: self._pressure(x, ctx)
        )

    def _pressure(self, x: Array, ctx: Context) -> Array:
        w = ctx.wheel
        if self.mode == "trend":  # the ramp, and what the start's cooling adds to it
            u = float(x[2]) * w.t / ctx.t_end
            rise = u + first_order(0.0 * u, w.t, float(x[0]), float(x[1]))
            return np.asarray(gas_pressure_Pa(ctx.p_nom, rise, ctx.T_amb), dtype=np.float64)
        u = self.drive(x, ctx)
        u = u[::-1] if self.mode == "reversed" else u
        rise = u if self.mode == "memoryless" else first_order(u, w.t, float(x[0]), float(x[1]))
        return np.asarray(gas_pressure_Pa(ctx.p_nom, rise, ctx.T_amb), dtype=np.float64)

    def inputs(self, x: Array, ctx: Context, inp: dict[str, Array | None]) -> None:
        inp["p"] = self.pressure(x, ctx)

    def inferred(self, x: Array, ctx: Context, inp: Mapping[str, Array | None]) -> dict[str, Array]:
        return {"p": self.pressure(x, ctx)}

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        if self.by_T:
            return None  # driven by a recorded channel the node does not see as a gas drive
        tau, start, gain = (float(v) for v in x)
        return {"T_amb_C": ctx.T_amb, "gas": Node(tau, gain * 1e-3), "gas_start_K": start}


class PressureTrend(EffectModel):
    """Concealed: the pressure changing linearly in time through the file's pressure terms -
    a slow leak (no link to heat), or a rise no channel explains (a sealed tyre on a car
    that never pauses warms its gas like a ramp: whether it followed the heat cannot be told
    there, that the pressure changed can). Its control is a plain friction trend (drift):
    a pressure moves stiffness and grip in the file's proportions, a drift grip alone."""

    stable_in_time = False  # a leak slows as the pressure falls: each half sees its own part
    word = "pressure"
    label = "pressure changing linearly in time (a slow leak, or a rise), file's terms"
    concealed = True

    def __init__(self, ctx: Context):
        super().__init__(
            [Param("loss_per_session", 0.05, -0.5, 0.8, 0.02)], [{"loss_per_session": -0.05}]
        )

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        if ctx.wheel.inputs["p"] is not None or not _file_has_pressure_terms(ctx):
            return []
        return [cls(ctx)]

    def controls(self, ctx: Context) -> list[EffectModel]:
        return [Trend(ctx)]

    def pressure(self, x: Array, ctx: Context) -> Array:
        return ctx.p_nom * (1.0 - float(x[0]) * ctx.wheel.t / ctx.t_end)

    def inputs(self, x: Array, ctx: Context, inp: dict[str, Array | None]) -> None:
        inp["p"] = self.pressure(x, ctx)

    def inferred(self, x: Array, ctx: Context, inp: Mapping[str, Array | None]) -> dict[str, Array]:
        return {"p": self.pressure(x, ctx)}

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        return None  # the session's history


class RecordedPressure(EffectModel):
    """A recorded pressure: the file's pressure terms refitted on it. Its control is a
    pressure ramp in time of the same range (a drift that happens to go with it)."""

    stable_in_time = False  # each half sees its own range of pressure

    word = "pressure"
    concealed = False

    def __init__(self, ctx: Context, mode: str = "recorded"):
        self.mode = mode
        self.label = {
            "recorded": "recorded pressure, pressure terms refitted",
            "trend": "control: a pressure ramp in time",
        }[mode]
        names = _terms(ctx)
        super().__init__(coefficient_params(ctx, names, [0.1] * len(names), span=30.0))

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        p = ctx.wheel.inputs["p"]
        if p is None or float(np.std(p)) < RECORDED_P_MIN_STD * ctx.p_nom or not _terms(ctx):
            return []
        return [cls(ctx)]

    def controls(self, ctx: Context) -> list[EffectModel]:
        return [RecordedPressure(ctx, "trend")]

    def coef(self, x: Array, ctx: Context) -> dict[str, float]:
        return {k: ctx.base.get(k, 0.0) + float(v) for k, v in zip(self.pnames, x, strict=True)}

    def inputs(self, x: Array, ctx: Context, inp: dict[str, Array | None]) -> None:
        if self.mode == "trend":
            p = ctx.wheel.inputs["p"]
            assert p is not None
            lo, hi = np.percentile(p, [5, 95])
            inp["p"] = lo + (hi - lo) * ctx.wheel.t / ctx.t_end
