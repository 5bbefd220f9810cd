"""Per-wheel state of the node: latest inputs, staleness, counters (no ROS import).

Decisions (one place, documented in the node's docstring too):

- ``slip`` with a non-finite component: nothing is published, ``slip_rejected`` counts it.
- ``load``: non-finite -> rejected, the previous valid load is held. ``Fz <= 0`` is a wheel off
  the ground: the published wrench is all zero with force.z = 0 (``no_contact`` counts it);
  the model is not evaluated there.
- ``load`` never received or older than its timeout: policy ``nominal`` (default) uses FNOMIN,
  so force.z of the output shows it, counted in ``fallback.load``; policy ``skip`` publishes
  nothing for that slip and counts it in ``skipped_no_load``.
- ``pressure``/``temperature``/``velocity`` never received -> the file's nominal value (INFLPRES
  else NOMPRES, NOMTEMP, LONGVL) silently (the INTERFACE rule); received once but older than
  the timeout -> the nominal value, counted in ``fallback.<input>`` and warned about.
- Non-finite pressure/temperature/velocity, negative gauge pressure, temperature below
  absolute zero: rejected, previous value held.
- Model output not finite, or the model raising: nothing published, counted.
- With an effects file (``effects``: the diagnosis' hidden states, :mod:`..model.states`), a
  temperature or pressure that is not fresh takes the hidden tread or gas node's value instead
  of the nominal one; the nodes step on the slip messages' header stamps and are driven by the
  frictional power of the wheel's own previous output.
- A .tir written by ``tire-model fit`` carries the envelope its fitted data covered
  (``[FIT_ENVELOPE]``: load, pressure, temperature cells): forces are computed all the same
  outside it (extrapolation), ``outside_envelope`` counts those samples. An unreadable envelope
  is not checked and ``last_error`` says why.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from tire_model_ros.model.envelope import Envelope
from tire_model_ros.model.states import EffectState

if TYPE_CHECKING:
    from tire_model_ros.model import TireModel

ABSOLUTE_ZERO_DEGC = -273.15


@dataclass(frozen=True)
class Nominal:
    """Values that stand in for inputs that are missing or stale (from the model's file)."""

    Fz: float
    p: float
    T: float
    Vx: float

    @classmethod
    def from_params(cls, params: Mapping[str, float]) -> Nominal:
        p_infl = float(params.get("INFLPRES", 0.0) or 0.0)
        p_nom = p_infl if p_infl > 0.0 else float(params.get("NOMPRES", 0.0))
        return cls(
            Fz=float(params["FNOMIN"]),
            p=p_nom,
            T=float(params.get("NOMTEMP", 25.0)),
            Vx=float(params.get("LONGVL", 16.7)),
        )


@dataclass
class Channel:
    """Latest valid value of one input and its receive time [s, monotonic]."""

    value: float | None = None
    t_rx: float = -math.inf
    received: int = 0
    rejected: int = 0
    fallback_stale: int = 0  # slips computed with the nominal value because this was stale
    fallback_never: int = 0  # slips computed with the nominal value, never received

    def get(self, now: float, timeout: float, nominal: float) -> tuple[float, str]:
        """Value to use and its state: 'ok', 'never' or 'stale'."""
        if self.value is None:
            self.fallback_never += 1
            return nominal, "never"
        if timeout > 0.0 and now - self.t_rx > timeout:
            self.fallback_stale += 1
            return nominal, "stale"
        return self.value, "ok"


@dataclass
class Throttle:
    """At most one log line per ``period`` [s] per key; counts the suppressed ones."""

    period: float = 5.0
    _last: dict[str, float] = field(default_factory=dict)
    _suppressed: dict[str, int] = field(default_factory=dict)

    def due(self, key: str, now: float) -> int | None:
        """None if this event must stay quiet, else how many were suppressed since the last."""
        if now - self._last.get(key, -math.inf) < self.period:
            self._suppressed[key] = self._suppressed.get(key, 0) + 1
            return None
        self._last[key] = now
        return self._suppressed.pop(key, 0)


ZERO_WRENCH = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


class WheelState:
    """Inputs and counters of one wheel; ``compute`` turns one slip sample into forces."""

    def __init__(self, prefix: str, key: str) -> None:
        self.prefix = prefix
        self.key = key
        self.slot = ""  # "" = shared model, else this wheel's key (own tir_file)
        self.load = Channel()
        self.pressure = Channel()
        self.temperature = Channel()
        self.velocity = Channel()
        self.slip_in = 0
        self.forces_out = 0
        self.slip_rejected = 0
        self.skipped_no_load = 0
        self.no_contact = 0
        self.output_nonfinite = 0
        self.model_errors = 0
        self.last_error = ""
        self.effects: EffectState | None = None  # hidden states of an effects file
        self.outside_envelope = 0
        self._envelope: tuple[TireModel | None, Envelope | None] = (None, None)

    # -- inputs: each returns None when accepted, else the reason it was rejected ----------
    def set_load(self, Fz: float, now: float) -> str | None:
        return self._set(self.load, Fz, now, "load force.z", lo=-math.inf)

    def set_pressure(self, p_gauge: float, now: float) -> str | None:
        return self._set(self.pressure, p_gauge, now, "gauge pressure", lo=0.0)

    def set_temperature(self, T: float, now: float) -> str | None:
        return self._set(self.temperature, T, now, "temperature", lo=ABSOLUTE_ZERO_DEGC)

    def set_velocity(self, Vx: float, now: float) -> str | None:
        return self._set(self.velocity, Vx, now, "velocity linear.x", lo=-math.inf)

    @staticmethod
    def _set(ch: Channel, x: float, now: float, what: str, lo: float) -> str | None:
        if not math.isfinite(x) or x < lo:
            ch.rejected += 1
            return f"{what} {x!r} rejected (kept {ch.value!r})"
        ch.value = float(x)
        ch.t_rx = now
        ch.received += 1
        return None

    # -- one slip sample -------------------------------------------------------------------
    def compute(
        self,
        kappa: float,
        alpha: float,
        gamma: float,
        now: float,
        model: TireModel,
        nominal: Nominal,
        timeouts: Mapping[str, float],
        limits: bool,
        skip_without_load: bool = False,
        stamp: float = 0.0,
    ) -> tuple[tuple[float, float, float, float, float, float] | None, list[str]]:
        """Forces for one slip sample (``stamp``: its header time [s]) and the events worth a
        (throttled) log line.

        Returns (None, events) when nothing must be published; the reason is counted.
        """
        self.slip_in += 1
        events: list[str] = []
        if not (math.isfinite(kappa) and math.isfinite(alpha) and math.isfinite(gamma)):
            self.slip_rejected += 1
            return None, [f"slip_rejected: non-finite slip ({kappa}, {alpha}, {gamma})"]
        Fz, state = self.load.get(now, timeouts["load"], nominal.Fz)
        if state != "ok":
            if skip_without_load:
                self.skipped_no_load += 1
                return None, [f"skipped_no_load: load {state}, slip not published"]
            events.append(f"fallback.load: load {state}, using FNOMIN {nominal.Fz} N")
        if Fz <= 0.0:
            self.no_contact += 1
            self.forces_out += 1
            if self.effects is not None:
                self.effects.idle(stamp)
            return ZERO_WRENCH, events
        p, sp = self.pressure.get(now, timeouts["pressure"], nominal.p)
        T, sT = self.temperature.get(now, timeouts["temperature"], nominal.T)
        Vx, sV = self.velocity.get(now, timeouts["velocity"], nominal.Vx)
        for name, s, value in (("pressure", sp, p), ("temperature", sT, T), ("velocity", sV, Vx)):
            if s == "stale":
                events.append(f"fallback.{name}: {name} stale, using nominal {value}")
        try:
            if self.effects is None:
                out = model.evaluate_one(Fz, kappa, alpha, gamma, Vx, p, T, limits=limits)
            else:
                out = self.effects.evaluate(
                    model,
                    stamp,
                    Fz,
                    kappa,
                    alpha,
                    gamma,
                    Vx,
                    T if sT == "ok" else None,
                    p if sp == "ok" else None,
                    nominal.p,
                    nominal.T,
                    nominal.Fz,
                    limits,
                )
        except Exception as exc:  # whatever the model raises, the node keeps running
            self.model_errors += 1
            self.last_error = f"{type(exc).__name__}: {exc}"
            return None, [f"model_error: {self.last_error}"]
        if not all(math.isfinite(x) for x in out):
            self.output_nonfinite += 1
            return None, [f"output_nonfinite: inputs Fz={Fz} kappa={kappa} alpha={alpha}"]
        if self._outside(model, Fz, p, T):
            self.outside_envelope += 1
        self.forces_out += 1
        return out, events

    def _outside(self, model: TireModel, Fz: float, p: float, T: float) -> bool:
        """Whether the inputs leave the envelope of the model's fitted data (read once per
        model; a model without one: never)."""
        if self._envelope[0] is not model:
            try:
                self._envelope = (model, Envelope.from_tir(model.tir))
            except ValueError as exc:
                self._envelope = (model, None)
                self.last_error = f"envelope not checked: {exc}"
        env = self._envelope[1]
        return env is not None and not env.contains_one(Fz, p, T)

    def counters(self) -> dict[str, int]:
        """Cumulative counts for the diagnostics report."""
        out = {
            "slip_in": self.slip_in,
            "forces_out": self.forces_out,
            "slip_rejected": self.slip_rejected,
            "skipped_no_load": self.skipped_no_load,
            "no_contact": self.no_contact,
            "output_nonfinite": self.output_nonfinite,
            "model_errors": self.model_errors,
            "outside_envelope": self.outside_envelope,
        }
        for name in ("load", "pressure", "temperature", "velocity"):
            ch: Channel = getattr(self, name)
            out[f"{name}.received"] = ch.received
            out[f"{name}.rejected"] = ch.rejected
            out[f"fallback.{name}.stale"] = ch.fallback_stale
            out[f"fallback.{name}.never"] = ch.fallback_never
        return out
