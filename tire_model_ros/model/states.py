"""Hidden states of an improved model, run forward one sample at a time (no ROS).

``tire-model diagnose`` fits effects that a .tir file cannot hold: hidden tread and carcass
thermal nodes (or a measured temperature's lags: the tread and carcass beneath the sensor), a
grip table against the temperature, a hidden gas node, force offsets and a ply-steer
slip-angle shift, friction against sliding speed, a sidewall-contact force drop. It writes them
beside the improved .tir as an *effects file* (JSON, one entry per wheel); the node runs them
per wheel with :class:`EffectState`, so a simulation with the improved model heats the tyre as
the diagnosis found it did.

The forms are the diagnosis' (:mod:`tire_model_ros.diagnosis.effects`): each node is
``y' = (k P_fric - y) / tau``, stepped exactly for the power held over the step; friction
scales by the similarity method (Pacejka 2012 §4.3.2). One difference, by necessity: the
diagnosis drives the nodes with the frictional power of the *measured* forces, a forward model
with its own previous output forces.

Bounded, so that one absurd sample cannot corrupt the states of a running node (a slip ratio
of -1e6 once drove the tread to 2e213 degC, then inf, and the wheel went silent for minutes):

- the drive, the frictional power, is finite and at most :data:`MAX_POWER_W` (1 MW: a tyre at
  10 kN sliding at 100 m/s);
- each node's state lies within +-:data:`MAX_RISE_K` (300 K above or below ambient: the tread
  would burn first);
- a sample the caller marks as not driving (``drive=False``: the node does so for a sample whose
  inputs it had to saturate) steps the nodes with the power held from before and leaves the
  power as it was: since the step is exact for a held power, the states go on exactly as if
  that sample had not come.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import numpy.typing as npt

from tire_model_ros.vocabulary import STANDARD_ATMOSPHERE_PA

if TYPE_CHECKING:
    from tire_model_ros.model.mf import TireModel, Wrench

FORMAT = "tire_model_ros.effects"
VERSION = 8  # 8: a measured temperature's carcass, whose stiffness falls with it (a reader of 7
# would drop T_carcass); 7: a measured temperature blended with its lag, a grip table in the
# temperature
# (a reader of 6 would drop T_surface_weight and grip_table); 6: a speed table relative to a
# reference speed (a reader of 5 would drop reference_V_mps and scale the file's curve at every
# speed); 5: sidewall deflection with the tyre file's vertical stiffness law (a reader of 4
# would drop deflection_pressure_weight); 4: sidewall contact at a slip angle that falls
# with the deflection, a gas node's start
READS = (1, 2, 3, 4, 5, 6, 7, 8)  # 1 (no slow node, shift or sidewall), 2 (sidewall without depth
# and gate_width: the linear loss behind a 5 % gate), 3 (its slip angle fixed, the gas starting
# at ambient), 4 (the deflection's pressure weight the air's share), 5 (speed tables
# absolute), 6 (a measured temperature's lag alone) and 7 (its stiffness TT*1 in the .tir) read
# as subsets
T_ABS0_C = 273.15  # 0 degC in K
MIN_MU_SCALE = 0.05  # as the diagnosis' similarity evaluation
NODES = ("thermal", "thermal_slow", "gas")
MAX_POWER_W = 1e6  # the drive's bound [W]
MAX_RISE_K = 300.0  # each node state's bound [K]


@dataclass(frozen=True)
class Node:
    """One first-order node: time constant [s] and steady rise per W of frictional power."""

    tau_s: float
    gain_per_W: float


class Carcass(NamedTuple):
    """The carcass beneath a measured (surface) temperature: the channel through a first-order
    lag from a start, the slip stiffness falling with it (PHYSICS.md: with the carcass)."""

    tau_s: float  # the lag [s] (0: the channel itself)
    start_K: float  # the carcass at the first sample, above it (a tyre brought warm: > 0)
    stiffness_per_K: float  # slip stiffness scales by 1 + this * (carcass - reference_C)
    reference_C: float  # where the stiffness is the file's [degC]


class Sidewall(NamedTuple):
    """Sidewall contact (:func:`sidewall_factor`); a file without ``depth``, ``gate_width``
    or ``alpha_c_per_rho`` (written before they were fitted) reads as the form it was fitted
    with."""

    threshold: float  # relative deflection where the gate opens
    alpha_c_rad: float  # slip angle beyond which Fy drops
    drop_per_rad: float  # the loss's initial slope
    depth: float = math.inf  # the share of Fy the loss saturates at (inf: linear, unbounded)
    gate_width: float = 0.05  # the gate's logistic width, a share of the threshold
    alpha_c_per_rho: float = 0.0  # alpha_c falls by this [rad] per unit of rho past threshold
    pressure_weight: float | None = None  # k of the deflection's pressure law (None: the air's
    # share, as files before version 5 were fitted with; :func:`relative_deflection`)


@dataclass(frozen=True)
class WheelEffects:
    """The effects of one wheel (None: not part of the model)."""

    T_amb_C: float = 25.0
    thermal: Node | None = None  # tread surface [K above T_amb_C] -> the T input
    thermal_slow: Node | None = None  # carcass [K], added to the tread's -> the T input
    thermal_slow_start_K: float = 0.0  # the carcass node's state at the start (pre-warmed)
    stiffness_per_K: float = 0.0  # slip stiffness scales by 1 + this * carcass rise [1/K]
    gas: Node | None = None  # gas temperature [K above T_amb_C] -> gas law -> the p input
    gas_start_K: float = 0.0  # the gas node's state at the start (pre-warmed)
    offsets: dict[str, tuple[float, float]] = field(default_factory=dict)  # ch: (N, N at FNOMIN)
    alpha_shift_rad: float = 0.0  # ply-steer as a slip-angle shift, added to alpha
    T_lag_s: float = 0.0  # a measured temperature is lagged by this first-order node [s]
    T_surface_weight: float = 0.0  # the grip feels this share of the measured (surface)
    # temperature at once and the rest through the lag (the tread's bulk beneath the sensor)
    T_carcass: Carcass | None = None  # a measured temperature's carcass, its stiffness loss
    grip_table: tuple[tuple[float, ...], tuple[float, ...]] | None = None  # (T degC, mu): the
    # friction scale against the temperature the grip feels, linear between, held beyond
    speed_table: tuple[tuple[float, ...], tuple[float, ...]] | None = None  # (ln Vs, mu)
    # > 0: the table is relative to the file's slip curve at this speed [m/s] (friction at
    # Vs over friction at the same slip's sliding speed there); 0: absolute in Vs
    speed_reference_mps: float = 0.0
    sidewall: Sidewall | None = None  # Fy scaled by sidewall_factor

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"T_amb_C": self.T_amb_C}
        for name in NODES:
            node = getattr(self, name)
            if node is not None:
                d[name] = {"tau_s": node.tau_s, "gain_per_W": node.gain_per_W}
        if self.thermal_slow is not None:
            d["thermal_slow"]["start_K"] = self.thermal_slow_start_K
            d["thermal_slow"]["stiffness_per_K"] = self.stiffness_per_K
        if self.gas is not None:
            d["gas"]["start_K"] = self.gas_start_K
        if self.offsets:
            d["offsets"] = {ch: {"N": a, "N_at_FNOMIN": b} for ch, (a, b) in self.offsets.items()}
        if self.alpha_shift_rad:
            d["alpha_shift_rad"] = self.alpha_shift_rad
        if self.T_lag_s:
            d["T_lag_s"] = self.T_lag_s
            if self.T_surface_weight:
                d["T_surface_weight"] = self.T_surface_weight
        if self.T_carcass is not None:
            d["T_carcass"] = self.T_carcass._asdict()
        if self.grip_table is not None:
            d["grip_table"] = {"T_C": list(self.grip_table[0]), "mu": list(self.grip_table[1])}
        if self.speed_table is not None:
            d["speed_table"] = {"ln_Vs": list(self.speed_table[0]), "mu": list(self.speed_table[1])}
            if self.speed_reference_mps:
                d["speed_table"]["reference_V_mps"] = self.speed_reference_mps
        if self.sidewall is not None:
            sw = self.sidewall
            d["sidewall"] = {
                "deflection_threshold": sw.threshold,
                "alpha_contact_rad": sw.alpha_c_rad,
                "drop_per_rad": sw.drop_per_rad,
                "gate_width": sw.gate_width,
                "alpha_c_per_rho": sw.alpha_c_per_rho,
            }
            if math.isfinite(sw.depth):
                d["sidewall"]["depth"] = sw.depth
            if sw.pressure_weight is not None:
                d["sidewall"]["deflection_pressure_weight"] = sw.pressure_weight
        return d


class EffectsError(ValueError):
    """A malformed effects file; the message names the file and the key."""


@dataclass(frozen=True)
class Effects:
    """The contents of an effects file: per wheel prefix, its effects; what was not carried."""

    wheels: dict[str, WheelEffects]
    tir: str = ""
    not_carried: tuple[str, ...] = ()

    def for_wheel(self, prefix: str) -> WheelEffects | None:
        """The effects of ``prefix``; a file of a single wheel (a rig) serves every wheel."""
        if prefix in self.wheels:
            return self.wheels[prefix]
        if len(self.wheels) == 1:
            return next(iter(self.wheels.values()))
        return None

    def to_json(self) -> str:
        doc = {
            "format": FORMAT,
            "version": VERSION,
            "tir": self.tir,
            "wheels": {p: w.to_dict() for p, w in self.wheels.items()},
            "not_carried": list(self.not_carried),
        }
        return json.dumps(doc, indent=2, allow_nan=False) + "\n"

    @classmethod
    def read(cls, path: str | Path) -> Effects:
        path = Path(path)
        try:
            doc = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise EffectsError(f"{path}: not a readable effects file ({exc})") from None
        return cls.from_dict(doc, str(path))

    @classmethod
    def from_dict(cls, doc: object, where: str = "effects") -> Effects:
        if not isinstance(doc, Mapping) or doc.get("format") != FORMAT:
            raise EffectsError(f"{where}: key 'format' must be {FORMAT!r}")
        if doc.get("version") not in READS:
            raise EffectsError(f"{where}: key 'version' must be one of {READS}")
        wheels = doc.get("wheels")
        if not isinstance(wheels, Mapping) or not wheels:
            raise EffectsError(f"{where}: key 'wheels' must map wheel prefixes to effects")
        out = {str(p): _wheel(w, f"{where}: wheels.{p}") for p, w in wheels.items()}
        not_carried = doc.get("not_carried", [])
        if not isinstance(not_carried, list):
            raise EffectsError(f"{where}: key 'not_carried' must be a list of labels")
        return cls(out, str(doc.get("tir", "")), tuple(map(str, not_carried)))


def _number(d: Mapping[str, Any], key: str, where: str, lo: float = -math.inf) -> float:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < lo:
        raise EffectsError(f"{where}.{key}: expected a finite number >= {lo:g}, got {v!r}")
    return float(v)


def _share(d: Mapping[str, Any], key: str, where: str) -> float:
    """An optional share in [0, 1] (absent: 0)."""
    v = _number(d, key, where, 0.0) if key in d else 0.0
    if v > 1.0:
        raise EffectsError(f"{where}.{key}: expected a share in [0, 1], got {v!r}")
    return v


def _node(d: object, where: str) -> Node:
    if not isinstance(d, Mapping):
        raise EffectsError(f"{where}: expected an object with tau_s and gain_per_W")
    return Node(_number(d, "tau_s", where, 0.0), _number(d, "gain_per_W", where))


def _offsets(d: object, where: str) -> dict[str, tuple[float, float]]:
    if not isinstance(d, Mapping):
        raise EffectsError(f"{where}: expected an object of channels")
    out = {}
    for ch, o in d.items():
        if ch not in ("Fx", "Fy", "Mz") or not isinstance(o, Mapping):
            raise EffectsError(f"{where}.{ch}: expected Fx, Fy or Mz with N, N_at_FNOMIN")
        out[ch] = (_number(o, "N", f"{where}.{ch}"), _number(o, "N_at_FNOMIN", f"{where}.{ch}"))
    return out


def _table(t: Any, w: str, knots: str = "ln_Vs") -> tuple[tuple[float, ...], tuple[float, ...]]:
    """A friction table: rising ``knots`` and one mu > 0 at each."""
    try:
        x, mu = tuple(map(float, t[knots])), tuple(map(float, t["mu"]))
    except (TypeError, KeyError, ValueError):
        raise EffectsError(f"{w}: expected lists {knots} and mu") from None
    if len(x) < 2 or len(x) != len(mu) or any(b <= a for a, b in itertools.pairwise(x)):
        raise EffectsError(f"{w}: {knots} must rise, with one mu per knot (2 or more)")
    if not all(math.isfinite(v) and v > 0 for v in mu) or not all(map(math.isfinite, x)):
        raise EffectsError(f"{w}: values must be finite, mu > 0")
    return x, mu


def _reference(t: Any, w: str) -> float:
    if not isinstance(t, Mapping) or "reference_V_mps" not in t:
        return 0.0
    return _number(t, "reference_V_mps", w, 0.0)


def _carcass(d: object, w: str) -> Carcass:
    if not isinstance(d, Mapping):
        raise EffectsError(f"{w}: expected an object with {', '.join(Carcass._fields)}")
    return Carcass(
        _number(d, "tau_s", w, 0.0),
        _number(d, "start_K", w),
        _number(d, "stiffness_per_K", w),
        _number(d, "reference_C", w, -T_ABS0_C),
    )


def _sidewall(d: object, w: str) -> Sidewall:
    if not isinstance(d, Mapping):
        raise EffectsError(
            f"{w}: expected deflection_threshold, alpha_contact_rad, drop_per_rad"
            "[, depth, gate_width, alpha_c_per_rho]"
        )
    threshold = _number(d, "deflection_threshold", w, 0.0)
    optional = {
        k: _number(d, k, w, 0.0) for k in ("depth", "gate_width", "alpha_c_per_rho") if k in d
    }
    if "deflection_pressure_weight" in d:
        optional["pressure_weight"] = _number(d, "deflection_pressure_weight", w, 0.0)
    for key, bad, want in (
        ("deflection_threshold", threshold == 0.0, "> 0 (the gate is relative to it)"),
        ("gate_width", optional.get("gate_width") == 0.0, "a share of the threshold > 0"),
        ("depth", optional.get("depth", 0.0) > 1.0, "a share of Fy in [0, 1]"),
    ):
        if bad:
            raise EffectsError(f"{w}.{key}: expected {want}, got {d[key]!r}")
    return Sidewall(
        threshold,
        _number(d, "alpha_contact_rad", w, 0.0),
        _number(d, "drop_per_rad", w, 0.0),
        **optional,
    )


def _wheel(d: object, where: str) -> WheelEffects:
    if not isinstance(d, Mapping):
        raise EffectsError(f"{where}: expected an object")
    if "bulk" in d:
        raise EffectsError(
            f"{where}.bulk: the version 1 grip node is no longer run; rerun diagnose"
        )
    nodes = {k: _node(d[k], f"{where}.{k}") for k in NODES if k in d}
    slow = d.get("thermal_slow")
    start = _number(slow, "start_K", f"{where}.thermal_slow") if slow is not None else 0.0
    gas = d.get("gas")  # files before version 4: a gas node starting at ambient
    gas_start = (
        _number(gas, "start_K", f"{where}.gas", 0.0)
        if isinstance(gas, Mapping) and "start_K" in gas
        else 0.0
    )
    stiff = 0.0
    if isinstance(slow, Mapping) and "stiffness_per_K" in slow:  # version 2 files without it read
        stiff = _number(slow, "stiffness_per_K", f"{where}.thermal_slow")
    return WheelEffects(
        T_amb_C=_number(d, "T_amb_C", where, -T_ABS0_C) if "T_amb_C" in d else 25.0,
        thermal=nodes.get("thermal"),
        thermal_slow=nodes.get("thermal_slow"),
        thermal_slow_start_K=start,
        stiffness_per_K=stiff,
        gas=nodes.get("gas"),
        gas_start_K=gas_start,
        offsets=_offsets(d.get("offsets", {}), f"{where}.offsets"),
        alpha_shift_rad=_number(d, "alpha_shift_rad", where) if "alpha_shift_rad" in d else 0.0,
        T_lag_s=_number(d, "T_lag_s", where, 0.0) if "T_lag_s" in d else 0.0,
        T_surface_weight=_share(d, "T_surface_weight", where),
        T_carcass=_carcass(d["T_carcass"], f"{where}.T_carcass") if "T_carcass" in d else None,
        grip_table=_table(d["grip_table"], f"{where}.grip_table", "T_C")
        if "grip_table" in d
        else None,
        speed_table=_table(d["speed_table"], f"{where}.speed_table")
        if "speed_table" in d
        else None,
        speed_reference_mps=_reference(d.get("speed_table"), f"{where}.speed_table"),
        sidewall=_sidewall(d["sidewall"], f"{where}.sidewall") if "sidewall" in d else None,
    )


def gas_pressure_Pa(p0_gauge_Pa: Any, rise_K: Any, T0_C: float) -> Any:
    """Gauge pressure at constant volume after a gas-temperature rise: p_abs ~ T_abs (numbers
    or arrays; the diagnosis' gas node and the node's use this one form)."""
    p0_abs = p0_gauge_Pa + STANDARD_ATMOSPHERE_PA
    return p0_abs * (T0_C + T_ABS0_C + rise_K) / (T0_C + T_ABS0_C) - STANDARD_ATMOSPHERE_PA


def relative_deflection(
    Fz: Any, FNOMIN: float, p_gauge_Pa: Any, p_nom_Pa: float, weight: float | None
) -> Any:
    """Tyre deflection relative to the nominal one, (Fz / FNOMIN) / (1 + k dpi): the load
    over a vertical stiffness that changes with the inflation pressure as the MF 6.1 tyre's
    does, Cz = Cz0 (1 + PFZ1 dpi) (the gate of sidewall contact). ``weight`` is k
    (:func:`deflection_pressure_weight`); None: the air's share p_nom / (p_nom + p_atm), a
    stiffness proportional to the absolute pressure."""
    k = p_nom_Pa / (p_nom_Pa + STANDARD_ATMOSPHERE_PA) if weight is None else weight
    dpi = (p_gauge_Pa - p_nom_Pa) / p_nom_Pa
    return (Fz / FNOMIN) / np.maximum(1.0 + k * dpi, 0.05)


def deflection_pressure_weight(params: Mapping[str, float]) -> float | None:
    """k of :func:`relative_deflection` from a tyre file: its vertical stiffness's pressure
    term PFZ1 (MF 6.1); None when it has none (0 or absent: an MF 5.2 file), the air's share.
    A car tyre's PFZ1 (0.8-0.9) weighs the pressure more than its air's share (0.7): with the
    air's share, a corner trained only at low pressure opened the gate at nominal pressure
    and high load, where the tyre is stiffer (brush sidewall seed 22)."""
    k = float(params.get("PFZ1", 0.0) or 0.0)
    return k if k > 0.0 else None


def contact_alpha(rho: Any, sw: Sidewall) -> Any:
    """The slip angle [rad] where the sidewall meets the road: alpha_c at the threshold
    deflection, less the more the tyre is deflected (a lower sidewall reaches the road at a
    smaller lateral displacement of the contact patch), never below 0."""
    return np.maximum(sw.alpha_c_rad - sw.alpha_c_per_rho * (rho - sw.threshold), 0.0)


def sidewall_factor(rho: Any, alpha_rad: Any, sw: Sidewall) -> Any:
    """The Fy factor of sidewall contact: 1 - g(rho) depth (1 - exp(-drop u / depth)),
    u = max(|alpha| - alpha_c, 0), g a logistic gate in the relative deflection rho around the
    threshold, ``gate_width`` of it wide. The loss grows at ``drop`` per rad beyond alpha_c
    and levels off at ``depth`` of Fy (the crown cannot lose more than it carries); ``depth``
    inf is the linear loss drop u."""
    th, drop, depth, width = sw.threshold, sw.drop_per_rad, sw.depth, sw.gate_width
    gate = 1.0 / (1.0 + np.exp(-np.clip((rho - th) / (width * th), -50.0, 50.0)))
    u = np.maximum(np.abs(alpha_rad) - contact_alpha(rho, sw), 0.0)
    loss = drop * u if math.isinf(depth) else depth * -np.expm1(-drop * u / max(depth, 1e-9))
    return np.maximum(1.0 - gate * loss, 0.0)


def _arrays(
    table: tuple[tuple[float, ...], tuple[float, ...]] | None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]] | None:
    if table is None:
        return None
    return np.asarray(table[0], dtype=np.float64), np.asarray(table[1], dtype=np.float64)


class EffectState:
    """The running states of one wheel's effects.

    Per sample: :meth:`inputs` steps the nodes to time ``t_s`` and gives the model's inputs
    (temperature, pressure, the slips by the similarity method) and the friction scale;
    after the model, :meth:`outputs` scales and offsets its forces and takes their frictional
    power as the drive of the next step.
    """

    def __init__(self, effects: WheelEffects) -> None:
        self.fx = effects
        # the tables as arrays once: numpy.interp, as the diagnosis evaluates them
        self._table = _arrays(effects.speed_table)
        self._grip = _arrays(effects.grip_table)
        self.reset()

    def reset(self) -> None:
        self.t_last: float | None = None
        self.P_last = 0.0  # frictional power held over the step [W]
        self.y = {
            "thermal": 0.0,
            "thermal_slow": self.fx.thermal_slow_start_K,
            "gas": self.fx.gas_start_K,
        }
        self.T_seen = 0.0  # the lagged measured temperature (T_lag_s)
        self.carcass_C = 0.0  # the carcass beneath it (T_carcass)
        self.T_last: float | None = None  # the measured temperature held over the step
        self._rho = 1.0  # relative deflection of the current sample

    def _step(self, t_s: float) -> None:
        dt = 0.0 if self.t_last is None else max(t_s - self.t_last, 0.0)
        self.t_last = t_s
        for name in self.y:
            node: Node | None = getattr(self.fx, name)
            if node is None:
                continue
            u = node.gain_per_W * self.P_last
            self.y[name] = _bounded(_held_lag(self.y[name], u, dt, node.tau_s))

    def _measured(self, T_C: float, dt: float, drive: bool) -> tuple[float, float]:
        """The measured temperature through the grip's lag T_lag_s and the carcass' lag, as
        the diagnosis integrates them (the value held over the step; a lag of 0: the sample
        itself); ``drive`` False: ``T_C`` is not held over the next step (the one held from
        before is)."""
        fx, c = self.fx, self.fx.T_carcass
        if self.T_last is None:
            self.T_seen, self.carcass_C = T_C, T_C + (c.start_K if c is not None else 0.0)
        else:
            self.T_seen = _held_lag(self.T_seen, self.T_last, dt, fx.T_lag_s)
            if c is not None:
                self.carcass_C = _held_lag(self.carcass_C, self.T_last, dt, c.tau_s)
        if drive or self.T_last is None:
            self.T_last = T_C
        grip = self.T_seen if fx.T_lag_s > 0.0 else T_C
        return grip, self.carcass_C if c is not None and c.tau_s > 0.0 else T_C

    def idle(self, t_s: float) -> None:
        """A sample with the wheel off the ground: the nodes step to ``t_s`` and cool."""
        self._step(t_s)
        self.P_last = 0.0

    @property
    def temperature_C(self) -> float:
        """The hidden tread temperature: ambient plus the tread and carcass nodes."""
        return self.fx.T_amb_C + self.y["thermal"] + self.y["thermal_slow"]

    def inputs(
        self,
        t_s: float,
        kappa: float,
        alpha: float,
        Vx: float,
        T_C: float | None,
        p_Pa: float | None,
        p_nom: float,
        T_nom: float,
        Fz_over_FNOMIN: float = 1.0,
        drive: bool = True,
    ) -> tuple[float, float, float, float, float]:
        """(kappa, alpha, T, p, s) for the model at ``t_s`` [s]; s is the friction scale.

        A temperature ``T_C`` [degC] or gauge pressure ``p_Pa`` that is None (not measured)
        takes the hidden thermal nodes, or the gas law on ``p_nom`` with the hidden gas node;
        the nominal value when the effects have no such node. ``drive`` as in :meth:`outputs`
        (a measured temperature of a sample that does not drive is not held by the lag).
        """
        dt = 0.0 if self.t_last is None else max(t_s - self.t_last, 0.0)
        self._step(t_s)
        fx = self.fx
        T = T_C
        stiff = fx.stiffness_per_K * self.y["thermal_slow"]  # the carcass' stiffness change
        if T is not None and (fx.T_lag_s > 0.0 or fx.T_carcass is not None):
            lagged, carcass = self._measured(T, dt, drive)
            if fx.T_carcass is not None:
                stiff += fx.T_carcass.stiffness_per_K * (carcass - fx.T_carcass.reference_C)
            if fx.T_lag_s > 0.0:
                share = fx.T_surface_weight
                T = share * T + (1.0 - share) * lagged
        if T is None:
            T = self.temperature_C if fx.thermal is not None else T_nom
        p = p_Pa
        if p is None:
            p = p_nom
            if fx.gas is not None:
                p = gas_pressure_Pa(p_nom, self.y["gas"], fx.T_amb_C)
        if fx.sidewall is not None:  # the deflection gates sidewall contact, nothing else
            w = fx.sidewall.pressure_weight
            self._rho = float(relative_deflection(Fz_over_FNOMIN, 1.0, p, p_nom, w))
        alpha = alpha + fx.alpha_shift_rad
        if stiff:  # the carcass' stiffness loss: slips scaled before similarity
            k = max(1.0 + stiff, 0.3)
            kappa, alpha = kappa * k, math.atan(math.tan(alpha) * k)
        s = 1.0
        if self._grip is not None:  # grip against the temperature it feels
            s *= float(np.interp(T, *self._grip))
        if self._table is not None:
            slip = math.hypot(kappa, math.tan(alpha))
            ln_Vs, mu = self._table
            s *= float(np.interp(math.log(max(abs(Vx) * slip, 1e-4)), ln_Vs, mu))
            if fx.speed_reference_mps:
                ref = math.log(max(fx.speed_reference_mps * slip, 1e-4))
                s /= float(np.interp(ref, ln_Vs, mu))
        s = max(s, MIN_MU_SCALE)
        if s != 1.0:
            kappa, alpha = kappa / s, math.atan(math.tan(alpha) / s)
        return kappa, alpha, T, p, s

    def evaluate(
        self,
        model: TireModel,
        t_s: float,
        Fz: float,
        kappa: float,
        alpha: float,
        gamma: float,
        Vx: float,
        T_C: float | None,
        p_Pa: float | None,
        p_nom: float,
        T_nom: float,
        FNOMIN: float,
        limits: bool = True,
        drive: bool = True,
    ) -> Wrench:
        """One sample of the improved model: :meth:`inputs`, ``model.evaluate_one`` at them,
        :meth:`outputs` (Fx, Fy, Fz, Mx, My, Mz). What the node computes per slip message;
        ``drive`` as in :meth:`outputs`."""
        load = Fz / FNOMIN if FNOMIN > 0 else 0.0
        k, a, T, p, s = self.inputs(t_s, kappa, alpha, Vx, T_C, p_Pa, p_nom, T_nom, load, drive)
        out = model.evaluate_one(Fz, k, a, gamma, Vx, p, T, limits=limits)
        return self.outputs(out, s, Fz, kappa, alpha, Vx, FNOMIN, drive)

    def _offset(self, ch: str, load: float) -> float:
        a, b = self.fx.offsets.get(ch, (0.0, 0.0))
        return a + b * load

    def outputs(
        self,
        out: Wrench,
        s: float,
        Fz: float,
        kappa: float,
        alpha: float,
        Vx: float,
        FNOMIN: float,
        drive: bool = True,
    ) -> Wrench:
        """(Fx, Fy, Fz, Mx, My, Mz) scaled by s (Fx, Fy, Mz), Fy by the sidewall factor, with
        the offsets (their load part in proportion to Fz / FNOMIN); its frictional power
        |Fx V kappa| + |Fy V tan(alpha)| (the slips before the similarity method), at most
        :data:`MAX_POWER_W`, drives the next step unless ``drive`` is False (the power held
        from before drives it: a sample that is not to be trusted leaves no trace)."""
        Fx, Fy, Fz_o, Mx, My, Mz = out
        Fx, Fy, Mz = Fx * s, Fy * s, Mz * s
        if self.fx.sidewall is not None:
            Fy *= float(
                sidewall_factor(self._rho, alpha + self.fx.alpha_shift_rad, self.fx.sidewall)
            )
        load = Fz / FNOMIN if FNOMIN > 0 else 0.0
        Fx, Fy, Mz = (v + self._offset(ch, load) for ch, v in (("Fx", Fx), ("Fy", Fy), ("Mz", Mz)))
        P = abs(Fx * Vx * kappa) + abs(Fy * Vx * math.tan(alpha))
        if drive and math.isfinite(P):  # a bad sample must not poison the states
            self.P_last = min(P, MAX_POWER_W)
        return Fx, Fy, Fz_o, Mx, My, Mz


def _held_lag(y: float, u_held: float, dt: float, tau_s: float) -> float:
    """One exact step of y' = (u - y) / tau for u held over ``dt`` (tau <= 0: y = u)."""
    if tau_s <= 0.0:
        return u_held
    a = math.exp(-dt / tau_s)
    return a * y + (1.0 - a) * u_held


def _bounded(y_K: float) -> float:
    """A node state within +-MAX_RISE_K (NaN, from a NaN drive, would stay NaN: the drive is
    finite by construction)."""
    return min(max(y_K, -MAX_RISE_K), MAX_RISE_K)
