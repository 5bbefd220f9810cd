"""Test programmes of the virtual rig: time series of the rig's commanded inputs.

A programme is what the rig operator writes: per wheel the commanded slip ratio, slip angle,
inclination, vertical load, belt (road) speed and inflation set pressure, sampled at the
recording rate, plus a list of labelled segments (sweeps, pauses, transitions). The rig's
physics (``session.py``) turns it into forces; nothing here knows about effects.

Programmes
----------
``flat_trac``
    An MTS Flat-Trac style session: warm-up, reference sweeps repeated through the session,
    pure lateral sweeps at 0.5/1/1.5 FNOMIN, pure longitudinal sweeps at the same loads, a
    pressure block (0.8/1.1/0.7/1.2/0.9 NOMPRES; only when the pressure channel is recorded),
    two sweep rates, two speeds, a reversed sweep, combined-slip sweeps (alpha held, kappa
    swept), a camber block (2/4/1/-2/3 deg), a heat soak (raises the bulk temperature) and a
    cooling pause.
``lateral_sweeps``, ``longitudinal_sweeps``, ``combined``, ``camber``, ``pressure``
    Smaller focused sessions (2-4 min).
``transient``
    Slip-angle sines at 0.25-4 Hz and step steers at two speeds (relaxation vs delay).
``safe_envelope``
    What a real Flat-Trac tests safely (loads 40-120 % FNOMIN, pressures 85-115 % NOMPRES, at
    the ambient), the tyre heating as it runs: ``heating`` on (with SEED_TYRE_HEATING) and the
    temperature channel left out unless the caller says otherwise. Reference, reversed and slow
    sweeps and a cooling pause (about 9 min).
``special_conditions``
    What the rig cannot test, run isothermally like an FE model: the rig's conditions at the
    ambient (the overlap), then the seed paper's 60/140/220 kPa at 120 % load, 120/140/160 %
    load at 60 kPa and -10/40/80 degC at 220 kPa and 120 %; the temperature channel is the set
    temperature; ``sidewall`` on unless switched off, and the temperature law of ``heating``
    (SEED_TYRE_HEATING unless given) acts at the set temperature.
``ttc_cornering``
    An FSAE Tire Test Consortium style cornering run: continuous constant-rate slip-angle
    sweeps 0 -> +A -> -A -> 0 over load blocks (1/0.5/1.5/0.75 FNOMIN) inside inclination
    blocks (0/2/4 deg) inside pressure blocks (1/0.8/1.2 NOMPRES), with no pause between: the
    load, inclination or pressure changes in a second at zero slip and the next sweep starts.
    As on the real rig, the load and inclination follow the lateral force a little (5 % and
    0.25 deg at full slip angle).
``ttc_drive_brake``
    The TTC's drive/brake run: slip-ratio sweeps 0 -> -k -> +k -> 0 at held slip angles
    (0/-3/-6 deg) over load blocks (1/0.5/1.5 FNOMIN), inclination (0/2 deg) and pressure
    (1/0.8/1.2 NOMPRES) blocks, again without pauses.
``track``
    Four wheels (``/car/fl``, ``/car/fr``, ``/car/rl``, ``/car/rr``) of a car lapping a
    circuit: load transfer, steering, braking (front bias) and rear-wheel traction.

Options (``programme_options``): ``repeats`` (int, default 1: the main body is repeated),
``rate_scale`` (sweep rates x this; <1 makes longer sessions), ``amplitude_deg`` (lateral
sweep amplitude, default 10), ``kappa_max`` (longitudinal amplitude, default 0.15),
``speed`` [m/s] (default LONGVL), ``ambient_C`` (default 25), ``vary_pressure`` (default: True
unless the pressure channel is omitted), ``laps`` (track, default 2), ``soak_s`` and
``soak_deg`` (flat_trac's heat soak: duration, default 25 s, and slip angle, default 5 deg),
``stop_s`` (flat_trac, lateral_sweeps: a belt stop of this many seconds between two runs,
after the load and pressure blocks; default 0, none); ``p_low_kPa``, ``p_mid_kPa``,
``p_high_kPa``, ``cold_C``, ``warm_C``, ``hot_C`` (special_conditions: the seed paper's
60, 140, 220 kPa and -10, 40, 80 degC by default).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from tire_model_ros.vocabulary import RIG_PREFIX

F64 = npt.NDArray[np.float64]

DEG = math.pi / 180.0
G_ACC = 9.81  # m/s^2

BELT_STOP = "belt stop"  # label of the pause where the belt halts between two runs
CAR_PREFIXES = ("/car/fl", "/car/fr", "/car/rl", "/car/rr")


@dataclass
class Segment:
    """One labelled stretch of a programme, samples ``i0 <= i < i1``."""

    i0: int
    i1: int
    kind: str  # warmup, lateral_sweep, longitudinal_sweep, combined_sweep, pause, ...
    label: str
    info: dict[str, Any] = field(default_factory=dict)

    def to_json(self, rate_hz: float) -> dict[str, Any]:
        return {
            "t0_s": self.i0 / rate_hz,
            "t1_s": self.i1 / rate_hz,
            "kind": self.kind,
            "label": self.label,
            **self.info,
        }


@dataclass
class WheelProgramme:
    """Commanded (true) inputs of one wheel, one entry per sample."""

    prefix: str
    kappa: np.ndarray
    alpha: np.ndarray  # rad
    gamma: np.ndarray  # rad
    Fz: np.ndarray  # N
    Vx: np.ndarray  # m/s
    p_set: np.ndarray  # gauge Pa: the pressure the rig regulates to / the tyre was set to
    segments: list[Segment] = field(default_factory=list)
    T_set: np.ndarray | None = None  # degC: the set tyre temperature of an isothermal run


@dataclass
class Programme:
    name: str
    rate_hz: float
    wheels: list[WheelProgramme]
    T_ambient: np.ndarray  # degC
    run: np.ndarray  # int run index per sample (a run = a block between re-set-ups)
    options: dict[str, Any] = field(default_factory=dict)
    # An isothermal programme (a simulation, like an FE model): the tyre is held at each
    # wheel's T_set, the temperature channel is that set temperature, nothing heats.
    isothermal: bool = False
    # effects switched on (with these parameters) unless the caller switches them off
    default_effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    default_omit: tuple[str, ...] = ()  # channels left out unless the caller says otherwise

    @property
    def n(self) -> int:
        return len(self.T_ambient)

    @property
    def duration_s(self) -> float:
        return self.n / self.rate_hz


@dataclass
class TyreInfo:
    """What a programme needs from the property file."""

    FNOMIN: float
    LONGVL: float
    NOMPRES: float
    R0: float

    @classmethod
    def from_params(cls, params: Mapping[str, float]) -> TyreInfo:
        nompres = params.get("INFLPRES") or params.get("NOMPRES") or 2.0e5
        return cls(
            FNOMIN=float(params["FNOMIN"]),
            LONGVL=float(params.get("LONGVL") or 16.7),
            NOMPRES=float(nompres),
            R0=float(params.get("UNLOADED_RADIUS") or 0.3),
        )


# ------------------------------------------------------------------ single-wheel builder


class RigBuilder:
    """Appends segments for one rig wheel; the rig state (load, speed, pressure, camber)
    carries over and every change of state gets a short zero-slip transition."""

    def __init__(
        self, tyre: TyreInfo, rate_hz: float, rate_scale: float = 1.0, ambient_C: float = 25.0
    ):
        self.tyre, self.fs, self.rate_scale, self.ambient = tyre, rate_hz, rate_scale, ambient_C
        self.cols: dict[str, list[np.ndarray]] = {
            k: [] for k in ("kappa", "alpha", "gamma", "Fz", "Vx", "p", "T")
        }
        self.run: list[np.ndarray] = []
        self.segments: list[Segment] = []
        self.state = {
            "Fz": tyre.FNOMIN,
            "Vx": tyre.LONGVL,
            "p": tyre.NOMPRES,
            "gamma": 0.0,
            "T": ambient_C,  # the set tyre temperature (used by isothermal programmes only)
        }
        # what the programme function declares about itself (see ``Programme``)
        self.isothermal = False
        self.default_effects: dict[str, Mapping[str, float]] = {}
        self.default_omit: tuple[str, ...] = ()
        self.n = 0
        self.alpha_hold = 0.0  # slip angle [rad] that set-up transitions keep (drive/brake)
        self.run_index = 0
        self.speed = tyre.LONGVL  # the session's reference belt speed

    # -- primitives
    def _append(
        self,
        kind: str,
        label: str,
        kappa: F64,
        alpha: F64,
        gamma: F64 | None = None,
        Fz: F64 | None = None,
        Vx: F64 | None = None,
        p: F64 | None = None,
        T: F64 | None = None,
        **info: Any,
    ) -> None:
        m = len(kappa)
        if m == 0:
            return
        s = self.state
        full = {
            "kappa": kappa,
            "alpha": alpha,
            "gamma": np.full(m, s["gamma"]) if gamma is None else gamma,
            "Fz": np.full(m, s["Fz"]) if Fz is None else Fz,
            "Vx": np.full(m, s["Vx"]) if Vx is None else Vx,
            "p": np.full(m, s["p"]) if p is None else p,
            "T": np.full(m, s["T"]) if T is None else T,
        }
        for k, v in full.items():
            self.cols[k].append(np.asarray(v, dtype=float))
        self.run.append(np.full(m, self.run_index))
        self.segments.append(Segment(self.n, self.n + m, kind, label, info))
        self.n += m

    def _samples(self, duration_s: float) -> int:
        return max(1, round(duration_s * self.fs))

    def set_state(
        self,
        *,
        Fz: float | None = None,
        Vx: float | None = None,
        p: float | None = None,
        gamma: float | None = None,
        T: float | None = None,
        duration_s: float = 1.5,
    ) -> None:
        """Change load/speed/pressure/camber (and the set temperature of an isothermal
        programme) along a zero-slip transition (rig re-set-up)."""
        new = dict(self.state)
        for k, v in (("Fz", Fz), ("Vx", Vx), ("p", p), ("gamma", gamma), ("T", T)):
            if v is not None:
                new[k] = float(v)
        if new == self.state:
            return
        m = self._samples(duration_s)
        w = 0.5 - 0.5 * np.cos(np.linspace(0.0, math.pi, m))  # smooth ramp
        ramps = {k: self.state[k] + (new[k] - self.state[k]) * w for k in new}
        if new["p"] != self.state["p"]:
            self.run_index += 1  # re-inflation starts a new run (gas law reference is reset)
        zeros = np.zeros(m)
        self._append(
            "transition",
            "set-up",
            zeros,
            np.full(m, self.alpha_hold),
            gamma=ramps["gamma"],
            Fz=ramps["Fz"],
            Vx=ramps["Vx"],
            p=ramps["p"],
            T=ramps["T"],
        )
        self.state = new

    def pause(self, duration_s: float, label: str = "pause") -> None:
        m = self._samples(duration_s)
        self._append("pause", label, np.zeros(m), np.zeros(m))

    def belt_stop(self, duration_s: float) -> None:
        """The belt halted between two runs (speed ramped to zero, held, ramped back), where an
        operator changes or conditions the belt; the tyre stays loaded and cools."""
        speed = self.state["Vx"]
        self.set_state(Vx=0.0, duration_s=3.0)
        self.pause(duration_s, label=BELT_STOP)
        self.set_state(Vx=speed, duration_s=3.0)

    def _path(self, points: list[float], rate_per_s: float) -> np.ndarray:
        """Piecewise-linear path through ``points`` at constant rate, sampled at fs."""
        pts = np.asarray(points, dtype=float)
        t_knots = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(pts)) / rate_per_s)])
        t = np.arange(math.ceil(t_knots[-1] * self.fs) + 1) / self.fs
        return np.interp(t, t_knots, pts)

    def _info(self, **extra: Any) -> dict[str, Any]:
        s = self.state
        return {
            "Fz_N": s["Fz"],
            "Vx_mps": s["Vx"],
            "p_Pa": s["p"],
            "gamma_deg": s["gamma"] / DEG,
            **({"T_set_C": s["T"]} if self.isothermal else {}),
            **extra,
        }

    def lateral_sweep(
        self,
        amplitude_deg: float = 10.0,
        rate_deg_s: float = 3.0,
        reverse: bool = False,
        kappa: float = 0.0,
        label: str = "lateral",
        follow: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """0 -> +A -> -A -> 0 (reverse: 0 -> -A -> +A -> 0) at a constant slip-angle rate.

        ``follow`` = (load fraction, inclination [deg]) that the rig's load and inclination
        move by at full slip angle, proportionally to alpha/A (a compliant rig)."""
        A = amplitude_deg * DEG * (-1.0 if reverse else 1.0)
        rate = rate_deg_s * self.rate_scale * DEG
        alpha = self._path([0.0, A, -A, 0.0], rate)
        share = alpha / abs(A) if A else np.zeros(len(alpha))
        Fz = self.state["Fz"] * (1.0 + follow[0] * share)
        gamma = self.state["gamma"] + follow[1] * DEG * share
        self._append(
            "lateral_sweep",
            label,
            np.full(len(alpha), kappa),
            alpha,
            gamma=gamma,
            Fz=Fz,
            **self._info(amplitude_deg=amplitude_deg, rate_deg_s=rate / DEG, reverse=bool(reverse)),
        )

    def longitudinal_sweep(
        self,
        kappa_max: float = 0.15,
        rate_per_s: float = 0.05,
        reverse: bool = False,
        alpha_deg: float = 0.0,
        label: str = "longitudinal",
    ) -> None:
        """0 -> -k (braking) -> +k (drive) -> 0 (reverse: drive first) at constant rate."""
        k = kappa_max * (1.0 if reverse else -1.0)
        rate = rate_per_s * self.rate_scale
        kappa = self._path([0.0, k, -k, 0.0], rate)
        self._append(
            "longitudinal_sweep",
            label,
            kappa,
            np.full(len(kappa), alpha_deg * DEG),
            **self._info(kappa_max=kappa_max, rate_per_s=rate, reverse=bool(reverse)),
        )

    def hold_slip_angle(self, alpha_deg: float, rate_deg_s: float = 4.0) -> None:
        """Ramp the slip angle to a value that is held (slip-ratio sweeps and set-up
        transitions keep it) until the next call: a drive/brake run's slip-angle block."""
        a = alpha_deg * DEG
        if a == self.alpha_hold:
            return
        ramp = self._path([self.alpha_hold, a], rate_deg_s * DEG)
        self._append("transition", "alpha hold", np.zeros(len(ramp)), ramp)
        self.alpha_hold = a

    def combined_sweep(
        self, alpha_deg: float, kappa_max: float = 0.12, rate_per_s: float = 0.05
    ) -> None:
        """Slip angle ramped to alpha and held while kappa is swept, then ramped back."""
        a = alpha_deg * DEG
        ramp = self._path([0.0, a], 4.0 * DEG)
        kappa = self._path([0.0, -kappa_max, kappa_max, 0.0], rate_per_s * self.rate_scale)
        self._append("transition", "alpha ramp", np.zeros(len(ramp)), ramp)
        self._append(
            "combined_sweep",
            f"combined alpha={alpha_deg:g}deg",
            kappa,
            np.full(len(kappa), a),
            **self._info(alpha_deg=alpha_deg, kappa_max=kappa_max),
        )
        self._append("transition", "alpha ramp", np.zeros(len(ramp)), ramp[::-1].copy())

    def warmup(
        self,
        duration_s: float = 30.0,
        alpha_deg: float = 4.0,
        kappa: float = 0.04,
        period_s: float = 4.0,
    ) -> None:
        """Scrubbing: slip angle and slip ratio sine waves (tyre conditioning)."""
        m = self._samples(duration_s)
        t = np.arange(m) / self.fs
        env = np.minimum(1.0, np.minimum(t, t[-1] - t) / 2.0)  # fade in/out
        alpha = alpha_deg * DEG * np.sin(2 * math.pi * t / period_s) * env
        kap = kappa * np.sin(2 * math.pi * t / (period_s * 0.77)) * env
        self._append("warmup", "warm-up", kap, alpha, **self._info())

    def heat_soak(
        self, duration_s: float = 30.0, alpha_deg: float = 5.0, period_s: float = 3.0
    ) -> None:
        """Sustained scrubbing that raises the carcass (bulk) temperature."""
        m = self._samples(duration_s)
        t = np.arange(m) / self.fs
        env = np.minimum(1.0, np.minimum(t, t[-1] - t) / 1.5)
        alpha = alpha_deg * DEG * np.sign(np.sin(2 * math.pi * t / period_s)) * env
        # smooth the square wave so the slip rate stays rig-like
        k = max(1, int(0.3 * self.fs))
        alpha = np.convolve(alpha, np.ones(k) / k, mode="same")
        self._append("heat_soak", "heat soak", np.zeros(m), alpha, **self._info())

    def steer_sine(
        self,
        freq_hz: float,
        amplitude_deg: float = 2.0,
        cycles: int = 6,
        label: str | None = None,
    ) -> None:
        """Sinusoidal slip angle (frequency response: relaxation lag grows with freq/speed)."""
        m = self._samples(cycles / freq_hz)
        t = np.arange(m) / self.fs
        alpha = amplitude_deg * DEG * np.sin(2 * math.pi * freq_hz * t)
        self._append(
            "steer_sine",
            label or f"steer sine {freq_hz:g} Hz",
            np.zeros(m),
            alpha,
            **self._info(freq_hz=freq_hz, amplitude_deg=amplitude_deg),
        )

    def step_steer(
        self, alpha_deg: float = 2.0, hold_s: float = 3.0, rate_deg_s: float = 40.0
    ) -> None:
        """Fast slip-angle step, held, and back (a relaxation-length test)."""
        a = alpha_deg * DEG
        up = self._path([0.0, a], rate_deg_s * DEG)
        m = self._samples(hold_s)
        alpha = np.concatenate([up, np.full(m, a), up[::-1], np.zeros(m)])
        self._append(
            "step_steer",
            f"step steer {alpha_deg:g} deg",
            np.zeros(len(alpha)),
            alpha,
            **self._info(alpha_deg=alpha_deg, rate_deg_s=rate_deg_s),
        )

    def reference_sweep(self, label: str = "reference") -> None:
        tyre = self.tyre
        self.set_state(Fz=tyre.FNOMIN, Vx=self.speed, p=tyre.NOMPRES, gamma=0.0)
        self.lateral_sweep(label=label)

    def build(self, prefix: str = RIG_PREFIX) -> tuple[WheelProgramme, np.ndarray]:
        cat = {k: np.concatenate(v) for k, v in self.cols.items()}
        wp = WheelProgramme(
            prefix,
            cat["kappa"],
            cat["alpha"],
            cat["gamma"],
            cat["Fz"],
            cat["Vx"],
            cat["p"],
            self.segments,
            cat["T"] if self.isothermal else None,
        )
        return wp, np.concatenate(self.run)


# ------------------------------------------------------------------ rig programmes


def _flat_trac(b: RigBuilder, opt: dict[str, Any]) -> None:
    ty = b.tyre
    A, kmax = opt["amplitude_deg"], opt["kappa_max"]
    F = ty.FNOMIN
    b.warmup(30.0)
    b.pause(3.0)
    for rep in range(opt["repeats"]):
        b.reference_sweep(label=f"reference {rep}a")
        b.pause(3.0)
        for f in (0.5, 1.0, 1.5):  # pure lateral at three loads
            b.set_state(Fz=f * F)
            b.lateral_sweep(A, label=f"lateral Fz={f:g}FNOMIN")
            b.pause(2.0)
        for f in (0.5, 1.0, 1.5):  # pure longitudinal at three loads
            b.set_state(Fz=f * F)
            b.longitudinal_sweep(kmax, label=f"longitudinal Fz={f:g}FNOMIN")
            b.pause(2.0)
        b.set_state(Fz=F)
        if opt["vary_pressure"]:
            # Four pressures (two are needed per side to see the quadratic MF terms), not in
            # monotone order, so that pressure is not confounded with the session's heating.
            for f in (0.8, 1.1, 0.7, 1.2, 0.9):
                b.set_state(p=f * ty.NOMPRES, duration_s=3.0)
                b.lateral_sweep(A, label=f"lateral p={f:g}NOMPRES")
                b.pause(2.0)
                b.longitudinal_sweep(kmax, label=f"longitudinal p={f:g}NOMPRES")
                b.pause(2.0)
            b.set_state(p=ty.NOMPRES, duration_s=3.0)
        if opt["stop_s"] > 0:  # the end of the first run: load/pressure, then the rest
            b.belt_stop(float(opt["stop_s"]))
        for rate in (1.5, 6.0):  # two sweep rates
            b.lateral_sweep(A, rate_deg_s=rate, label=f"lateral rate={rate:g}deg/s")
            b.pause(2.0)
        b.set_state(Vx=0.5 * opt["speed"])  # a second speed
        b.lateral_sweep(A, label="lateral V=0.5V0")
        b.pause(2.0)
        b.set_state(Vx=opt["speed"])
        b.lateral_sweep(A, reverse=True, label="lateral reversed")
        b.pause(2.0)
        for a in (3.0, -6.0):  # combined slip
            b.combined_sweep(a, kappa_max=0.8 * kmax)
            b.pause(2.0)
        for g in (2.0, 4.0, 1.0, -2.0, 3.0):  # camber; five levels, so one can be held out
            b.set_state(gamma=g * DEG)
            b.lateral_sweep(A, label=f"lateral gamma={g:g}deg")
            b.pause(2.0)
        b.set_state(gamma=0.0)
        b.reference_sweep(label=f"reference {rep}b")
        b.heat_soak(float(opt["soak_s"]), alpha_deg=float(opt["soak_deg"]))
        b.reference_sweep(label=f"reference {rep}c (hot)")
        b.pause(30.0, label="cooling pause")
        b.reference_sweep(label=f"reference {rep}d (after pause)")
        b.pause(2.0)


def _lateral_sweeps(b: RigBuilder, opt: dict[str, Any]) -> None:
    F, A = b.tyre.FNOMIN, opt["amplitude_deg"]
    b.warmup(20.0)
    b.pause(3.0)
    for rep in range(opt["repeats"]):
        b.reference_sweep(label=f"reference {rep}a")
        b.pause(3.0)
        for f in (0.5, 1.0, 1.5):
            b.set_state(Fz=f * F)
            b.lateral_sweep(A, label=f"lateral Fz={f:g}FNOMIN")
            b.pause(2.0)
        b.set_state(Fz=F)
        if opt["stop_s"] > 0:
            b.belt_stop(float(opt["stop_s"]))
        for rate in (1.5, 6.0):
            b.lateral_sweep(A, rate_deg_s=rate, label=f"lateral rate={rate:g}deg/s")
            b.pause(2.0)
        b.set_state(Vx=0.5 * opt["speed"])
        b.lateral_sweep(A, label="lateral V=0.5V0")
        b.set_state(Vx=opt["speed"])
        b.lateral_sweep(A, reverse=True, label="lateral reversed")
        b.pause(20.0, label="cooling pause")
        b.reference_sweep(label=f"reference {rep}b (after pause)")
        b.pause(2.0)


def _longitudinal_sweeps(b: RigBuilder, opt: dict[str, Any]) -> None:
    F, k = b.tyre.FNOMIN, opt["kappa_max"]
    b.warmup(20.0)
    b.pause(3.0)
    for rep in range(opt["repeats"]):
        for f in (1.0, 0.5, 1.5):
            b.set_state(Fz=f * F)
            b.longitudinal_sweep(k, label=f"longitudinal Fz={f:g}FNOMIN")
            b.pause(2.0)
        b.set_state(Fz=F)
        for rate in (0.025, 0.1):
            b.longitudinal_sweep(k, rate_per_s=rate, label=f"longitudinal rate={rate:g}/s")
            b.pause(2.0)
        b.longitudinal_sweep(k, reverse=True, label="longitudinal reversed")
        b.pause(20.0, label="cooling pause")
        b.longitudinal_sweep(k, label=f"longitudinal reference {rep}")
        b.pause(2.0)


def _combined(b: RigBuilder, opt: dict[str, Any]) -> None:
    F, A, k = b.tyre.FNOMIN, opt["amplitude_deg"], opt["kappa_max"]
    b.warmup(15.0)
    for _ in range(opt["repeats"]):
        b.lateral_sweep(A, label="lateral pure")
        b.pause(2.0)
        b.longitudinal_sweep(k, label="longitudinal pure")
        b.pause(2.0)
        for f in (1.0, 0.5):
            b.set_state(Fz=f * F)
            for a in (2.0, -4.0, 8.0):
                b.combined_sweep(a, kappa_max=k)
                b.pause(2.0)
        b.set_state(Fz=F)
        b.lateral_sweep(A, kappa=-0.05, label="lateral kappa=-0.05")
        b.pause(2.0)


def _camber(b: RigBuilder, opt: dict[str, Any]) -> None:
    A = opt["amplitude_deg"]
    b.warmup(15.0)
    for _ in range(opt["repeats"]):
        for g in (0.0, 2.0, -2.0, 4.0, 0.0):
            b.set_state(gamma=g * DEG)
            b.lateral_sweep(A, label=f"lateral gamma={g:g}deg")
            b.pause(2.0)
        b.set_state(gamma=3.0 * DEG)
        b.longitudinal_sweep(opt["kappa_max"], label="longitudinal gamma=3deg")
        b.set_state(gamma=0.0)
        b.pause(2.0)


def _pressure(b: RigBuilder, opt: dict[str, Any]) -> None:
    ty = b.tyre
    b.warmup(15.0)
    for _ in range(opt["repeats"]):
        for f in (1.0, 0.7, 1.3, 1.0):
            b.set_state(p=f * ty.NOMPRES, duration_s=3.0)
            for fz in (0.6, 1.3):
                b.set_state(Fz=fz * ty.FNOMIN)
                b.lateral_sweep(opt["amplitude_deg"], label=f"lateral p={f:g} Fz={fz:g}")
                b.pause(2.0)
            b.set_state(Fz=ty.FNOMIN)
            b.longitudinal_sweep(opt["kappa_max"], label=f"longitudinal p={f:g}")
            b.pause(2.0)


def _transient(b: RigBuilder, opt: dict[str, Any]) -> None:
    F = b.tyre.FNOMIN
    b.warmup(15.0)
    b.pause(2.0)
    for _ in range(opt["repeats"]):
        for v in (1.0, 0.5):
            b.set_state(Vx=v * opt["speed"])
            for f in (0.25, 0.5, 1.0, 2.0, 4.0):
                b.steer_sine(f, label=f"steer sine {f:g} Hz V={v:g}V0")
                b.pause(1.0)
            b.step_steer(2.0)
            b.pause(1.0)
        b.set_state(Vx=opt["speed"], Fz=0.5 * F)
        b.step_steer(2.0)
        b.set_state(Fz=F)
        b.lateral_sweep(opt["amplitude_deg"], label="lateral reference")
        b.pause(2.0)


def _sweep_pair(b: RigBuilder, A: float, kmax: float, label: str) -> None:
    """A lateral and a longitudinal sweep at the present conditions, with pauses."""
    b.lateral_sweep(A, label=f"lateral {label}")
    b.pause(2.0)
    b.longitudinal_sweep(kmax, label=f"longitudinal {label}")
    b.pause(2.0)


def _safe_envelope(b: RigBuilder, opt: dict[str, Any]) -> None:
    """What a real Flat-Trac tests safely: loads SAFE_LOADS x FNOMIN at SAFE_PRESSURES x
    NOMPRES, at the lab's ambient, the tyre heating as it runs (no temperature channel by
    default); reference sweeps, a reversed and a slow sweep and a cooling pause let the heating
    be told from other drifts (PHYSICS.md). Slip ratio sweeps go to 1.5 x ``kappa_max``, past
    the force peak at every load."""
    b.default_effects, b.default_omit = {"heating": SEED_TYRE_HEATING}, ("temperature",)
    ty, A, kmax = b.tyre, opt["amplitude_deg"], 1.5 * opt["kappa_max"]
    b.warmup(30.0)
    b.pause(3.0)
    for rep in range(opt["repeats"]):
        b.reference_sweep(label=f"reference {rep}a")
        b.pause(3.0)
        for fp in SAFE_PRESSURES if opt["vary_pressure"] else SAFE_PRESSURES[:1]:
            b.set_state(p=fp * ty.NOMPRES, duration_s=3.0)
            for f in SAFE_LOADS:
                b.set_state(Fz=f * ty.FNOMIN)
                _sweep_pair(b, A, kmax, f"p={fp:g}NOMPRES Fz={f:g}FNOMIN")
        b.set_state(Fz=ty.FNOMIN, p=ty.NOMPRES, duration_s=3.0)
        b.lateral_sweep(A, reverse=True, label="lateral reversed")
        b.pause(2.0)
        b.lateral_sweep(A, rate_deg_s=1.5, label="lateral rate=1.5deg/s")
        b.reference_sweep(label=f"reference {rep}b (hot)")
        b.pause(30.0, label="cooling pause")
        b.reference_sweep(label=f"reference {rep}c (after pause)")
        b.pause(2.0)


def _special_conditions(b: RigBuilder, opt: dict[str, Any]) -> None:
    """What the rig cannot test, run like an FE model: isothermal at set temperatures, with
    sidewall contact in its physics (``Programme.isothermal``). The seed paper's conditions
    (pressures ``p_low_kPa``/``p_mid_kPa``/``p_high_kPa`` at 120 % load; 120/140/160 % load at
    ``p_low_kPa``; ``cold_C``/``warm_C``/``hot_C`` at ``p_high_kPa`` and 120 % load) and the
    rig's own (SAFE_LOADS x SAFE_PRESSURES at the ambient) to compare the two where both
    reach. Lateral sweeps go to 1.5 x ``amplitude_deg`` (past the sidewall contact), slip
    ratio sweeps to 2 x ``kappa_max`` (past the force peak at every load)."""
    b.isothermal = True
    b.default_effects = {"heating": SEED_TYRE_HEATING, "sidewall": {}}
    ty, A, kmax = b.tyre, 1.5 * opt["amplitude_deg"], 2.0 * opt["kappa_max"]
    F, amb = ty.FNOMIN, float(opt["ambient_C"])
    for _ in range(opt["repeats"]):
        for fp in SAFE_PRESSURES:  # the rig's conditions: the overlap
            b.set_state(p=fp * ty.NOMPRES, T=amb, duration_s=3.0)
            for f in SAFE_LOADS:
                b.set_state(Fz=f * F)
                _sweep_pair(b, A, kmax, f"p={fp:g}NOMPRES Fz={f:g}FNOMIN T={amb:g}C")
        b.set_state(Fz=SEED_LOAD * F)
        for key in ("p_high_kPa", "p_mid_kPa", "p_low_kPa"):  # pressure at 120 % load
            b.set_state(p=1e3 * float(opt[key]), duration_s=3.0)
            _sweep_pair(b, A, kmax, f"p={opt[key]:g}kPa Fz={SEED_LOAD:g}FNOMIN")
        for f in SEED_HIGH_LOADS[1:]:  # low pressure, high load
            b.set_state(Fz=f * F)
            _sweep_pair(b, A, kmax, f"p={opt['p_low_kPa']:g}kPa Fz={f:g}FNOMIN")
        b.set_state(Fz=SEED_LOAD * F, p=1e3 * float(opt["p_high_kPa"]), duration_s=3.0)
        for key in ("cold_C", "warm_C", "hot_C"):  # tyre temperature
            b.set_state(T=float(opt[key]), duration_s=3.0)
            _sweep_pair(b, A, kmax, f"T={opt[key]:g}C")
        b.set_state(T=amb, duration_s=3.0)


# Load, inclination and pressure blocks of the TTC-style runs (fractions of FNOMIN and
# NOMPRES, deg), in the order the consortium's runs visit them (not monotone).
TTC_LOADS = (1.0, 0.5, 1.5, 0.75)
TTC_INCLINATIONS_DEG = (0.0, 2.0, 4.0)
TTC_PRESSURES = (1.0, 0.8, 1.2)
TTC_FOLLOW = (0.05, 0.25)  # load fraction, inclination [deg] at full slip angle


def _ttc_pressures(opt: dict[str, Any]) -> tuple[float, ...]:
    return TTC_PRESSURES if opt["vary_pressure"] else TTC_PRESSURES[:1]


def _ttc_cornering(b: RigBuilder, opt: dict[str, Any]) -> None:
    ty, A = b.tyre, opt["amplitude_deg"]
    b.set_state(Fz=ty.FNOMIN, duration_s=1.0)
    for _ in range(2):  # conditioning sweeps at the nominal load
        b.lateral_sweep(A, rate_deg_s=4.0, label="conditioning", follow=TTC_FOLLOW)
    for _ in range(opt["repeats"]):
        for pf in _ttc_pressures(opt):
            b.set_state(p=pf * ty.NOMPRES, duration_s=2.0)
            for g in TTC_INCLINATIONS_DEG:
                for f in TTC_LOADS:
                    b.set_state(Fz=f * ty.FNOMIN, gamma=g * DEG, duration_s=1.0)
                    b.lateral_sweep(
                        A,
                        rate_deg_s=4.0,
                        label=f"cornering p={pf:g} gamma={g:g}deg Fz={f:g}",
                        follow=TTC_FOLLOW,
                    )


def _ttc_drive_brake(b: RigBuilder, opt: dict[str, Any]) -> None:
    ty, k = b.tyre, opt["kappa_max"]
    b.set_state(Fz=ty.FNOMIN, duration_s=1.0)
    b.longitudinal_sweep(k, rate_per_s=0.1, label="conditioning")
    for _ in range(opt["repeats"]):
        for pf in _ttc_pressures(opt):
            b.set_state(p=pf * ty.NOMPRES, duration_s=2.0)
            for g in TTC_INCLINATIONS_DEG[:2]:
                for a in (0.0, -3.0, -6.0):
                    b.hold_slip_angle(a)
                    for f in TTC_LOADS[:3]:
                        b.set_state(Fz=f * ty.FNOMIN, gamma=g * DEG, duration_s=1.0)
                        b.longitudinal_sweep(
                            k,
                            rate_per_s=0.1,
                            alpha_deg=a,
                            label=f"drive/brake p={pf:g} gamma={g:g}deg alpha={a:g}deg Fz={f:g}",
                        )
                b.hold_slip_angle(0.0)


_RIG: dict[str, Callable[[RigBuilder, dict[str, Any]], None]] = {
    "flat_trac": _flat_trac,
    "lateral_sweeps": _lateral_sweeps,
    "longitudinal_sweeps": _longitudinal_sweeps,
    "combined": _combined,
    "camber": _camber,
    "pressure": _pressure,
    "transient": _transient,
    "safe_envelope": _safe_envelope,
    "special_conditions": _special_conditions,
    "ttc_cornering": _ttc_cornering,
    "ttc_drive_brake": _ttc_drive_brake,
}
PROGRAMMES = (*_RIG, "track")

_DEFAULTS = {
    "repeats": 1,
    "rate_scale": 1.0,
    "amplitude_deg": 10.0,
    "kappa_max": 0.15,
    "speed": None,
    "ambient_C": 25.0,
    "vary_pressure": None,
    "laps": 2,
    "soak_s": 25.0,
    "soak_deg": 5.0,
    "stop_s": 0.0,
    "p_low_kPa": 60.0,  # special_conditions: the seed paper's pressures [kPa gauge] ...
    "p_mid_kPa": 140.0,
    "p_high_kPa": 220.0,
    "cold_C": -10.0,  # ... and tyre temperatures [degC]
    "warm_C": 40.0,
    "hot_C": 80.0,
}
# The rig's safe envelope (safe_envelope, and special_conditions' overlap block): loads as
# fractions of FNOMIN, pressures of NOMPRES. The seed paper's special conditions: 120 % load
# (SEED_LOAD) and 120/140/160 % at low pressure.
SAFE_LOADS = (0.4, 0.7, 1.0, 1.2)
SAFE_PRESSURES = (1.0, 0.85, 1.15)
SEED_LOAD = 1.2
SEED_HIGH_LOADS = (1.2, 1.4, 1.6)
# The tyre of safe_envelope and special_conditions heats on the rig and is held at set
# temperatures in the simulation by one law (the ``heating`` effect's parameters). The seed
# paper's tyre: stiffer cold, and from -10 to 80 degC less stiff and less grip as it warms (its
# grip optimum at or below -10 degC, a window wide enough for the range); about 8 % less grip
# at a rig session's hottest tread than at 25 degC.
SEED_TYRE_HEATING = {"T_opt_C": -10.0, "width_hot_K": 150.0, "width_cold_K": 70.0}


def _options(
    tyre: TyreInfo, options: Mapping[str, Any] | None, omit: Collection[str]
) -> dict[str, Any]:
    opt: dict[str, Any] = dict(_DEFAULTS)
    for k, v in (options or {}).items():
        if k not in opt:
            raise ValueError(f"programme option {k!r} unknown (known: {', '.join(sorted(opt))})")
        opt[k] = v
    opt["speed"] = float(opt["speed"] or tyre.LONGVL)
    if opt["vary_pressure"] is None:
        opt["vary_pressure"] = "pressure" not in omit
    opt["repeats"] = int(opt["repeats"])
    opt["laps"] = int(opt["laps"])
    if opt["repeats"] < 1 or opt["laps"] < 1 or float(opt["rate_scale"]) <= 0:
        raise ValueError("programme options: repeats and laps must be >= 1, rate_scale > 0")
    if not 1.0 <= float(opt["soak_s"]) <= 3600.0 or not 0.0 < float(opt["soak_deg"]) <= 20.0:
        raise ValueError("programme options: soak_s must be in [1, 3600] s, soak_deg in (0, 20]")
    if not 0.0 <= float(opt["stop_s"]) <= 3600.0:
        raise ValueError("programme options: stop_s must be in [0, 3600] s")
    for key in ("p_low_kPa", "p_mid_kPa", "p_high_kPa"):
        if not 1.0 <= float(opt[key]) <= 1e4:
            raise ValueError(f"programme options: {key} must be in [1, 10000] kPa")
    for key in ("cold_C", "warm_C", "hot_C", "ambient_C"):
        if not -60.0 <= float(opt[key]) <= 200.0:
            raise ValueError(f"programme options: {key} must be in [-60, 200] degC")
    opt["rate_scale"] = float(opt["rate_scale"])
    return opt


def build_programme(
    name: str,
    params: Mapping[str, float],
    rate_hz: float = 100.0,
    options: Mapping[str, Any] | None = None,
    omit: Collection[str] = (),
) -> Programme:
    """The programme ``name`` for the tyre of ``params`` (FNOMIN, LONGVL, NOMPRES...)."""
    if rate_hz <= 0 or not math.isfinite(rate_hz):
        raise ValueError(f"rate must be a positive number of Hz, got {rate_hz}")
    tyre = TyreInfo.from_params(params)
    opt = _options(tyre, options, omit)
    if name == "track":
        from .track import build_track

        return build_track(tyre, rate_hz, opt)
    if name not in _RIG:
        raise ValueError(f"unknown programme {name!r} (known: {', '.join(PROGRAMMES)})")
    b = RigBuilder(tyre, rate_hz, opt["rate_scale"], opt["ambient_C"])
    b.state["Vx"] = b.speed = opt["speed"]
    _RIG[name](b, opt)
    wp, run = b.build(RIG_PREFIX)
    return Programme(
        name,
        rate_hz,
        [wp],
        np.full(len(run), float(opt["ambient_C"])),
        run,
        opt,
        b.isothermal,
        b.default_effects,
        b.default_omit,
    )
