"""Per-wheel state of the node: stamped input histories, saturation, counters (no ROS import).

Decisions (one place, documented in the node's docstring too):

- Every input is taken by header stamp (:mod:`.history`): each slip message is computed with the
  latest value of each input stamped at or before it; staleness is stamp time (the slip's
  stamp minus the value's), never wall time.
- ``slip`` with a non-finite component: nothing is published, ``slip_rejected`` counts it.
- A message that cannot be read (the node's raw-bytes path): dropped, counted in
  ``slip_malformed`` or ``<input>.malformed``.
- ``load``: non-finite -> rejected (not kept in the history). ``Fz <= 0`` is a wheel off the
  ground: the published wrench is all zero with force.z = 0 (``no_contact`` counts it); the
  model is not evaluated there.
- ``load`` with no value for the slip (never received, stale, or only values stamped after the
  slip): policy ``nominal`` (default) uses FNOMIN, so force.z of the output shows it, counted in
  ``fallback.load.<state>``; policy ``skip`` publishes nothing, counted in ``skipped_no_load``.
- ``pressure``/``temperature``/``velocity`` without a value -> the file's nominal value (INFLPRES
  else NOMPRES, NOMTEMP, LONGVL), counted in ``fallback.<input>.<state>``; never received is the
  INTERFACE rule and no warning, stale or ahead is warned about.
- Non-finite pressure/temperature/velocity, negative gauge pressure, temperature below absolute
  zero: rejected.
- Every input (the slips too) outside the file's range counts in ``out_of_range.<input>``;
  with ``limits`` it is saturated first (:mod:`.ranges`).
- Model output not finite, or the model raising: nothing published, counted.
- Forces the publisher refuses (the context shut down under the callback at SIGTERM):
  ``publish_failed``, not ``forces_out``.
- With an effects file (``effects``: the diagnosis' hidden states, :mod:`..model.states`), a
  temperature or pressure without a fresh value takes the hidden tread or gas node's value
  instead of the nominal one; the nodes step on the slip messages' header stamps, driven by the
  frictional power of the wheel's own previous output, except by a sample with an input out of
  range (it leaves no trace in them).
- A .tir written by ``tire-model fit`` carries the envelope its fitted data covered
  (``[FIT_ENVELOPE]``: load, pressure, temperature cells): forces are computed all the same
  outside it (extrapolation), ``outside_envelope`` counts those answers (the inputs as
  received, apart from the saturation at the file's ranges). An unreadable envelope is not
  checked and ``last_error`` says why.
- A slip may be held until the other inputs' stamps have caught up with it, bounded on the
  ROS clock (``hold``, :mod:`.hold`); it is counted in ``slip_in`` when it is computed, so a
  pending slip is in neither side of the sum below until it is released.

Every slip message taken is counted in ``slip_in`` and either answered (``forces_out``) or
counted under one of :data:`UNANSWERED`: ``slip_in == forces_out + sum(UNANSWERED)``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from tire_model_ros.delivery import NODE, UNANSWERED, report_line
from tire_model_ros.model.envelope import Envelope
from tire_model_ros.model.states import EffectState
from tire_model_ros.vocabulary import NODE_INPUTS, NS_PER_S
from tire_model_ros.wheel.history import STATES, StampedHistory
from tire_model_ros.wheel.hold import SlipHold
from tire_model_ros.wheel.ranges import SAMPLE_INPUTS, InputRanges, Sample

if TYPE_CHECKING:
    from tire_model_ros.model import TireModel
    from tire_model_ros.model.mf import Wrench

ABSOLUTE_ZERO_DEGC = -273.15
ZERO_WRENCH = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
_LOWEST = {"load": -math.inf, "pressure": 0.0, "temperature": ABSOLUTE_ZERO_DEGC}
_WHAT = {
    "load": "load force.z",
    "pressure": "gauge pressure",
    "temperature": "temperature",
    "velocity": "velocity linear.x",
}


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


@dataclass(frozen=True)
class WheelModel:
    """What a wheel computes with: the model, its nominal inputs, its input ranges and the
    envelope of its fitted data (None: none, or unreadable and ``envelope_error`` says why)."""

    model: TireModel
    nominal: Nominal
    ranges: InputRanges
    envelope: Envelope | None = None
    envelope_error: str = ""

    @classmethod
    def of(cls, model: TireModel) -> WheelModel:
        nominal, ranges = Nominal.from_params(model.params), InputRanges.from_params(model.params)
        try:
            return cls(model, nominal, ranges, Envelope.from_tir(model.tir))
        except ValueError as exc:
            return cls(model, nominal, ranges, None, f"envelope not checked: {exc}")


@dataclass(frozen=True)
class Settings:
    """The node settings a slip sample needs: staleness [ns] per input (0 = never stale), the
    limits, and the policy for a missing load."""

    timeouts_ns: Mapping[str, int]
    limits: bool = True
    skip_without_load: bool = False

    @classmethod
    def of(cls, timeouts_s: Mapping[str, float], limits: bool, skip: bool) -> Settings:
        return cls({k: round(v * NS_PER_S) for k, v in timeouts_s.items()}, limits, skip)


@dataclass
class Input:
    """One input of a wheel: its stamped history and its counters."""

    history: StampedHistory = field(default_factory=StampedHistory)
    received: int = 0
    rejected: int = 0
    malformed: int = 0
    fallback: dict[str, int] = field(default_factory=lambda: dict.fromkeys(STATES[1:], 0))


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


class WheelState:
    """Inputs and counters of one wheel; ``compute`` turns one slip sample into forces."""

    def __init__(self, prefix: str, key: str) -> None:
        self.prefix = prefix
        self.key = key
        self.slot = ""  # "" = shared model, else this wheel's key (own tir_file)
        self.inputs = {name: Input() for name in NODE_INPUTS}
        self.counts = dict.fromkeys(("slip_in", "forces_out", "no_contact", *UNANSWERED), 0)
        self.counts["outside_envelope"] = 0
        self.out_of_range = dict.fromkeys(SAMPLE_INPUTS, 0)
        self.outside: tuple[str, ...] = ()  # inputs out of range at the last slip
        self.last_slip_ns: int | None = None
        self.last_error = ""
        self.effects: EffectState | None = None  # hidden states of an effects file
        self.hold = SlipHold(NODE_INPUTS)  # slips waiting for their inputs' stamps

    # -- inputs --------------------------------------------------------------------------
    def set_input(self, name: str, stamp_ns: int, x: float) -> str | None:
        """Take one value of input ``name``; None when accepted, else why it was rejected."""
        ch = self.inputs[name]
        if not math.isfinite(x) or x < _LOWEST.get(name, -math.inf):
            ch.rejected += 1
            return f"{_WHAT[name]} {x!r} rejected"
        ch.history.put(stamp_ns, float(x))
        ch.received += 1
        return None

    def malformed(self, channel: str) -> None:
        """Count a message of ``channel`` (slip or an input) that could not be read."""
        if channel == "slip":
            self.counts["slip_in"] += 1
            self.counts["slip_malformed"] += 1
        else:
            self.inputs[channel].malformed += 1

    def inactive(self) -> None:
        """Count a slip message that arrived while the (managed) node was not active."""
        self.counts["slip_in"] += 1
        self.counts["slip_inactive"] += 1

    def unpublished(self, reason: str) -> None:
        """Count forces computed but refused by the publisher (the context shut down under
        the callback at SIGTERM): an answer not delivered, not an answer."""
        self.counts["forces_out"] -= 1
        self.counts["publish_failed"] += 1
        self.last_error = reason

    def _value(self, name: str, stamp_ns: int, timeout_ns: int) -> tuple[float | None, str]:
        ch = self.inputs[name]
        value, state, _ = ch.history.at(stamp_ns, timeout_ns)
        if state != "ok":
            ch.fallback[state] += 1
        return value, state

    # -- one slip sample -------------------------------------------------------------------
    def compute(
        self,
        kappa: float,
        alpha: float,
        gamma: float,
        stamp_ns: int,
        wm: WheelModel,
        settings: Settings,
    ) -> tuple[Wrench | None, list[str]]:
        """Forces for one slip sample stamped ``stamp_ns`` and the events worth a (throttled)
        log line. Returns (None, events) when nothing must be published; the reason is counted.
        """
        self.counts["slip_in"] += 1
        self.last_slip_ns = stamp_ns
        if not (math.isfinite(kappa) and math.isfinite(alpha) and math.isfinite(gamma)):
            self.counts["slip_rejected"] += 1
            return None, [f"slip_rejected: non-finite slip ({kappa}, {alpha}, {gamma})"]
        events: list[str] = []
        Fz = self._load(stamp_ns, wm, settings, events)
        if Fz is None:
            return None, events
        if Fz <= 0.0:
            return self._no_contact(stamp_ns), events
        p, T, Vx, measured = self._optional(stamp_ns, wm, settings, events)
        used, outside = wm.ranges.saturate((Fz, kappa, alpha, gamma, p, T, Vx), settings.limits)
        self.outside = outside
        for name in outside:
            self.out_of_range[name] += 1
        if outside:
            how = "saturated" if settings.limits else "limits off: not saturated"
            events.append(f"out_of_range: {', '.join(outside)} ({how})")
        out, problems = self._evaluate(wm, settings, stamp_ns, used, measured, not outside)
        if out is not None and self._outside_envelope(wm, Fz, p, T):
            self.counts["outside_envelope"] += 1
        return out, events + problems

    def _outside_envelope(self, wm: WheelModel, Fz: float, p: float, T: float) -> bool:
        """Whether the inputs leave the envelope of the model's fitted data."""
        if wm.envelope_error:
            self.last_error = wm.envelope_error
        return wm.envelope is not None and not wm.envelope.contains_one(Fz, p, T)

    def _load(
        self, stamp_ns: int, wm: WheelModel, settings: Settings, events: list[str]
    ) -> float | None:
        """The load for the slip, FNOMIN when it has none; None: skip the slip (counted)."""
        Fz, state = self._value("load", stamp_ns, settings.timeouts_ns["load"])
        if Fz is not None:
            return Fz
        if settings.skip_without_load:
            self.counts["skipped_no_load"] += 1
            events.append(f"skipped_no_load: load {state}, slip not published")
            return None
        events.append(f"fallback.load: load {state}, using FNOMIN {wm.nominal.Fz} N")
        return wm.nominal.Fz

    def _optional(
        self, stamp_ns: int, wm: WheelModel, settings: Settings, events: list[str]
    ) -> tuple[float, float, float, tuple[bool, bool]]:
        """(p, T, Vx) for the slip, nominal where none, and whether p and T were measured."""
        out = []
        nominal = {"pressure": wm.nominal.p, "temperature": wm.nominal.T, "velocity": wm.nominal.Vx}
        for name, nom in nominal.items():
            value, state = self._value(name, stamp_ns, settings.timeouts_ns[name])
            if value is None and state != "never":  # never received: the INTERFACE rule
                events.append(f"fallback.{name}: {name} {state}, using nominal {nom}")
            out.append(value)
        p, T, Vx = (
            v if v is not None else nom for v, nom in zip(out, nominal.values(), strict=True)
        )
        return p, T, Vx, (out[0] is not None, out[1] is not None)

    def _no_contact(self, stamp_ns: int) -> Wrench:
        self.counts["no_contact"] += 1
        self.counts["forces_out"] += 1
        if self.effects is not None:
            self.effects.idle(stamp_ns / NS_PER_S)
        return ZERO_WRENCH

    def _evaluate(
        self,
        wm: WheelModel,
        settings: Settings,
        stamp_ns: int,
        used: Sample,
        measured: tuple[bool, bool],
        drive: bool,
    ) -> tuple[Wrench | None, list[str]]:
        """The model (with the effects' hidden states, which ``drive`` may leave untouched)."""
        Fz, kappa, alpha, gamma, p, T, Vx = used
        try:
            if self.effects is None:
                out = wm.model.evaluate_one(Fz, kappa, alpha, gamma, Vx, p, T, settings.limits)
            else:
                nom = wm.nominal
                out = self.effects.evaluate(
                    wm.model, stamp_ns / NS_PER_S, Fz, kappa, alpha, gamma, Vx,
                    T if measured[1] else None, p if measured[0] else None,
                    nom.p, nom.T, nom.Fz, settings.limits, drive=drive,
                )  # fmt: skip
        except Exception as exc:  # whatever the model raises, the node keeps running
            self.counts["model_errors"] += 1
            self.last_error = f"{type(exc).__name__}: {exc}"
            return None, [f"model_errors: {self.last_error}"]
        if not all(math.isfinite(x) for x in out):
            self.counts["output_nonfinite"] += 1
            return None, [f"output_nonfinite: inputs {used}"]
        self.counts["forces_out"] += 1
        return out, []

    # -- reports -----------------------------------------------------------------------------
    def counters(self) -> dict[str, int]:
        """Cumulative counts for the diagnostics report and the final summary."""
        out = dict(self.counts)
        for name, ch in self.inputs.items():
            out[f"{name}.received"] = ch.received
            out[f"{name}.rejected"] = ch.rejected
            out[f"{name}.malformed"] = ch.malformed
            for state, n in ch.fallback.items():
                out[f"fallback.{name}.{state}"] = n
        for name, n in self.out_of_range.items():
            out[f"out_of_range.{name}"] = n
        out.update(self.hold.counts)
        out["longest_catch_up_ms"] = self.hold.longest_catch_up_ns // 1_000_000
        return out

    def input_age_s(self, name: str) -> float | None:
        """Stamp time [s] from the newest value of ``name`` to the last slip, None if none."""
        latest = self.inputs[name].history.latest()
        if latest is None or self.last_slip_ns is None:
            return None
        return (self.last_slip_ns - latest[1]) / NS_PER_S


def final_line(prefix: str, counts: Mapping[str, int]) -> str:
    """The node's last word on a wheel (printed at exit): every counter (:mod:`..delivery`)."""
    return report_line(NODE, prefix, counts)
