"""Staged field fit of Magic Formula coefficients from recordings.

The order is the field's (PHYSICS.md, "Lessons from real data"): pure longitudinal Fx0, pure
lateral Fy0, aligning moment Mz0, combined slip, then the inflation-pressure terms where the
recording varies pressure and the temperature terms where it records a varying temperature.
Each stage fits only the coefficients the data can identify (load terms need several loads,
camber terms a camber range, quadratic terms a wide spread), is checked for C > 0, D > 0,
E <= 1 on the data afterwards (a new violation rejects the stage), keeps the start values when
its gain does not beat the noise (effective chi-square, corrected for residual autocorrelation,
against n + 3 sqrt(2n) for n coefficients), and is skipped with its reason when its samples are
missing. Peak and curvature coefficients are left out when the slip never passes the force
peak. Every k-th sweep per condition is held out for validation and never fitted.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np
import numpy.typing as npt

from tire_model_ros.blas import one_blas_thread
from tire_model_ros.recording.series import WheelSeries

from .core import evaluate_on, fit_coefficients, stack_inputs
from .sweeps import Segment, holdout_mask, split_segments

if TYPE_CHECKING:
    from tire_model_ros.model import TireModel

Bools = npt.NDArray[np.bool_]

# Sample classes [rad, -]: "pure" means the other slip is within these bands.
PURE_ALPHA_RAD = math.radians(0.5)
PURE_KAPPA = 0.005
COMBINED_ALPHA_RAD = math.radians(1.0)
COMBINED_KAPPA = 0.01
# A stage needs its slip swept at least this far (else its shape is not identifiable).
MIN_KAPPA_SWEEP = 0.02
MIN_ALPHA_SWEEP_DEG = 1.0


@dataclass(frozen=True)
class Stage:
    """One fitting stage: which samples, which channels, which coefficients."""

    name: str
    samples: str  # "pure_long", "pure_lat", "combined", "pure"
    channels: tuple[str, ...]
    base: tuple[str, ...]  # always fitted
    load: tuple[str, ...] = ()  # when the load varies
    load3: tuple[str, ...] = ()  # when there are three or more load levels
    camber: tuple[str, ...] = ()  # when the camber varies
    # Linear pressure/temperature terms fitted along with the pure-slip shape where the
    # recording varies them: otherwise the shape factors absorb the spread of p and T and the
    # later pressure/temperature stages start from biased curves.
    pressure: tuple[str, ...] = ()
    temperature: tuple[str, ...] = ()
    needs: str = ""  # "pressure" or "temperature": skip unless the recording varies it


STAGES: tuple[Stage, ...] = (
    Stage(
        "Fx0",
        "pure_long",
        ("Fx",),
        base=("PCX1", "PDX1", "PEX1", "PEX4", "PKX1", "PHX1", "PVX1"),
        load=("PDX2", "PEX2", "PKX2", "PHX2", "PVX2"),
        load3=("PEX3", "PKX3"),
        camber=("PDX3",),
        pressure=("PPX1", "PPX3"),
        temperature=("TTX1", "TTX3"),
    ),
    Stage(
        "Fy0",
        "pure_lat",
        ("Fy",),
        base=("PCY1", "PDY1", "PEY1", "PEY3", "PKY1", "PHY1", "PVY1"),
        load=("PDY2", "PEY2", "PKY2", "PHY2", "PVY2"),
        camber=("PDY3", "PEY4", "PKY3", "PKY6", "PKY7", "PVY3", "PVY4"),
        pressure=("PPY1", "PPY3"),
        temperature=("TTY1", "TTY3"),
    ),
    Stage(
        "Mz0",
        "pure_lat",
        ("Mz",),
        base=("QBZ1", "QCZ1", "QDZ1", "QEZ1", "QHZ1", "QDZ6", "QBZ10"),
        load=("QBZ2", "QDZ2", "QEZ2", "QHZ2", "QDZ7"),
        load3=("QBZ3", "QDZ3"),
        camber=("QDZ8", "QDZ9", "QHZ3", "QHZ4"),
        pressure=("PPZ1",),
    ),
    Stage(
        "combined",
        "combined",
        ("Fx", "Fy"),
        base=(
            "RBX1",
            "RBX2",
            "RCX1",
            "REX1",
            "RHX1",
            "RBY1",
            "RBY2",
            "RBY3",
            "RCY1",
            "REY1",
            "RHY1",
        ),
        load=("REX2", "REY2", "RHY2"),
        camber=("RBX3", "RBY4"),
    ),
    Stage(
        "pressure",
        "pure",
        ("Fx", "Fy"),
        base=("PDX1", "PKX1", "PDY1", "PKY1", "PPX1", "PPX3", "PPY1", "PPY2", "PPY3"),
        camber=("PPY5",),
        needs="pressure",
    ),
    Stage(
        "temperature",
        "pure",
        ("Fx", "Fy"),
        base=("PDX1", "PKX1", "PDY1", "PKY1", "TTX1", "TTX3", "TTY1", "TTY3"),
        load=("TTY2",),
        needs="temperature",
    ),
)
# Peak and curvature coefficients: identifiable only from samples past the force peak.
PEAK_SHAPE = {
    **dict.fromkeys(("PCX1", "PDX1", "PDX2", "PDX3", "PEX1", "PEX2", "PEX3", "PEX4", "PPX3",
                     "PPX4", "TTX3", "TTX4"), "long"),
    **dict.fromkeys(("PCY1", "PDY1", "PDY2", "PDY3", "PEY1", "PEY2", "PEY3", "PEY4", "PPY3",
                     "PPY4", "TTY3", "TTY4"), "lat"),
}  # fmt: skip
# Quadratic terms join a stage when the spread of their variable is wide enough.
QUADRATIC = {"pressure": ("PPX2", "PPX4", "PPY4"), "temperature": ("TTX2", "TTX4", "TTY4")}
# Pressure terms refitted together with the temperature terms (pressure follows temperature
# through the gas law, so the two must share one fit where both vary).
PRESSURE_IN_TEMPERATURE = ("PPX1", "PPX3", "PPY1", "PPY3")


@dataclass
class FitOptions:
    """Knobs of :func:`fit_recording` (the CLI maps its flags onto these)."""

    holdout_every: int = 4  # hold out every k-th sweep per condition (< 2: none)
    warmup_s: float = 0.0  # drop the first seconds of every wheel (cold tyre)
    min_temperature: float | None = None  # drop samples colder than this [degC]
    stages: Sequence[str] | None = None  # names of the stages to run (default: all)
    fixed: frozenset[str] = frozenset()  # coefficients kept at the start model's values
    max_samples: int = 6_000  # decimation per stage (100 Hz rows are autocorrelated)
    loss: str = "soft_l1"
    progress: bool | None = None  # None: show on a TTY only
    stream: TextIO | None = None  # progress stream (default stderr)


@dataclass
class FitResult:
    """Outcome of :func:`fit_recording`.

    ``report`` is JSON-ready: stages (fitted names, values, standard errors, skipped/rejected
    with reasons), metrics before/after on fitted and held-out samples, per channel and per
    condition. The masks and segments are per wheel, in the order of the input series.
    """

    model: TireModel
    report: dict[str, Any]
    start_model: TireModel
    wheels: list[WheelSeries] = field(default_factory=list)
    train_masks: list[np.ndarray] = field(default_factory=list)
    heldout_masks: list[np.ndarray] = field(default_factory=list)
    segments: list[list[Segment]] = field(default_factory=list)
    predictions: dict[str, list[Any]] = field(default_factory=dict)  # "before"/"after" per wheel


class Progress:
    """One line per stage on stderr; a live counter only on a TTY."""

    def __init__(self, enabled: bool | None = None, stream: TextIO | None = None):
        self.stream = stream or sys.stderr
        tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.live = tty if enabled is None else (enabled and tty)
        self.lines = True if enabled is None else enabled
        self._last = 0.0
        self._stage = ""

    def start(self, stage: str) -> None:
        self._stage = stage
        self._t0 = time.perf_counter()

    def update(self, nfev: int, cost: float) -> None:
        now = time.perf_counter()
        if self.live and now - self._last > 0.2:
            self._last = now
            self.stream.write(f"\rfit {self._stage}: {nfev} evaluations, cost {cost:.4g} ")
            self.stream.flush()

    def done(self, text: str) -> None:
        if self.live:
            self.stream.write("\r\033[K")
        if self.lines:
            dt = time.perf_counter() - self._t0
            self.stream.write(f"fit {self._stage}: {text} ({dt:.1f} s)\n")
            self.stream.flush()


# --- data conditions ------------------------------------------------------------------------


def _spread(x: np.ndarray | None) -> float:
    """Width of the central 90 % of the finite values (0 when absent)."""
    if x is None:
        return 0.0
    x = x[np.isfinite(x)]
    if len(x) < 10:
        return 0.0
    q = np.percentile(x, [5.0, 95.0])
    return float(q[1] - q[0])


def _occupied(x: np.ndarray, step: float, share: float = 0.02) -> np.ndarray:
    """Centres of the bins of width ``step`` holding at least ``share`` of the finite values
    (a sweep at a load of its own is a few per cent of a session)."""
    x = x[np.isfinite(x)]
    if len(x) == 0 or step <= 0:
        return np.zeros(0)
    bins, counts = np.unique(np.round(x / step), return_counts=True)
    return bins[counts >= share * len(x)] * step


def _range(x: np.ndarray) -> float:
    return float(np.ptp(x)) if len(x) else 0.0


def _levels(x: np.ndarray, step: float) -> int:
    """Number of occupied bins of width ``step`` (``_occupied``)."""
    return len(_occupied(x, step))


def _cat_required(series: Sequence[WheelSeries], name: str) -> npt.NDArray[np.float64]:
    """A channel every WheelSeries has (kappa, alpha, gamma, Fz), concatenated."""
    return np.concatenate([getattr(s, name) for s in series])


def _cat(series: Sequence[WheelSeries], name: str) -> np.ndarray | None:
    arrays = [getattr(s, name) for s in series]
    if all(a is None for a in arrays):
        return None
    return np.concatenate([a for a in arrays if a is not None])


def data_conditions(model: TireModel, series: Sequence[WheelSeries]) -> dict[str, Any]:
    """What the data can identify: load, camber, pressure and temperature variation."""
    P = model.params
    fz0 = float(P["FNOMIN"]) * float(P.get("LFZO", 1.0))
    p0 = float(P.get("NOMPRES", 0.0))
    T0 = float(P.get("NOMTEMP", 25.0)) or 25.0
    Fz, gamma = (_cat_required(series, k) for k in ("Fz", "gamma"))
    p, T = (_cat(series, k) for k in ("p", "T"))
    dpi_spread = _spread(p) / p0 if (p is not None and p0 > 0) else 0.0
    dT_spread = _spread(T) / T0 if T is not None else 0.0
    return {
        "load_levels": _levels(Fz, 0.1 * fz0),
        "load_varies": _range(_occupied(Fz, 0.05 * fz0)) > 0.15 * fz0,
        "camber_varies": _spread(gamma) > math.radians(0.5),
        "pressure_varies": dpi_spread > 0.03,
        "pressure_wide": dpi_spread > 0.15 and _levels(p, 0.05 * p0) >= 3
        if p is not None
        else False,
        "temperature_varies": _spread(T) > 3.0,
        "temperature_wide": dT_spread > 0.4,
        "pressure_recorded": p is not None,
        "temperature_recorded": T is not None,
    }


def stage_names(stage: Stage, cond: Mapping[str, Any], model: TireModel) -> list[str]:
    """Coefficients of ``stage`` that the data conditions allow (and the model knows)."""
    names = list(stage.base)
    if cond["load_varies"]:
        names += stage.load
    if cond["load_levels"] >= 3:
        names += stage.load3
    if cond["camber_varies"]:
        names += stage.camber
    if cond["pressure_varies"]:
        names += stage.pressure
    if cond["temperature_varies"]:
        names += stage.temperature
    if stage.needs == "pressure" and cond["pressure_wide"]:
        names += QUADRATIC["pressure"]
    if stage.needs == "temperature":
        if cond["temperature_wide"]:
            names += QUADRATIC["temperature"]
        if cond["pressure_varies"]:
            names += PRESSURE_IN_TEMPERATURE
    seen: list[str] = []
    for k in names:
        if k in model.params and k not in seen:
            seen.append(k)
    return seen


def sample_mask(series: WheelSeries, kind: str) -> Bools:
    """Samples of a class: pure longitudinal, pure lateral, combined, or any pure slip."""
    k = np.abs(np.asarray(series.kappa, dtype=np.float64))
    a = np.abs(np.asarray(series.alpha, dtype=np.float64))
    pure_long = a < PURE_ALPHA_RAD
    pure_lat = k < PURE_KAPPA
    if kind == "pure_long":
        return pure_long
    if kind == "pure_lat":
        return pure_lat
    if kind == "pure":
        return pure_long | pure_lat
    if kind == "combined":
        return (k > COMBINED_KAPPA) & (a > COMBINED_ALPHA_RAD)
    return np.ones(len(series), dtype=bool)


# --- physical checks ------------------------------------------------------------------------


def _sgn(x: npt.ArrayLike) -> npt.NDArray[np.float64]:
    return np.where(np.asarray(x) < 0, -1.0, 1.0)


def physical_checks(
    stage: str, model: TireModel, series: Sequence[WheelSeries]
) -> dict[str, float]:
    """C > 0, D > 0, E <= 1 of the stage's Magic Formula evaluated on the data's operating
    points: condition -> fraction of the samples where it fails (only failing ones listed)."""
    P = model.params

    def g(k: str, d: float = 0.0) -> float:
        return float(P.get(k, d))

    if not series:
        return {}
    Fz, kappa, alpha, gamma = (_cat_required(series, k) for k in ("Fz", "kappa", "alpha", "gamma"))
    fz0 = g("FNOMIN") * g("LFZO", 1.0)
    dfz = (Fz - fz0) / fz0
    msgs: dict[str, float] = {}

    def need(cond: bool | np.ndarray, text: str) -> None:
        if not np.all(cond):
            msgs[text] = 1.0 - float(np.mean(cond)) if np.ndim(cond) else 1.0

    if stage in ("Fx0", "pressure", "temperature"):
        need(g("PCX1") * g("LCX", 1.0) > 0, "Cx = PCX1 > 0 (4.E11)")
        Ex = (
            (g("PEX1") + g("PEX2") * dfz + g("PEX3") * dfz**2)
            * (1 - g("PEX4") * _sgn(kappa))
            * g("LEX", 1.0)
        )
        need(Ex <= 1.0 + 1e-9, "Ex <= 1 (4.E14)")
    if stage in ("Fy0", "pressure", "temperature"):
        need(g("PCY1") * g("LCY", 1.0) > 0, "Cy = PCY1 > 0 (4.E21)")
        Ey = (
            (g("PEY1") + g("PEY2") * dfz)
            * (1 + g("PEY5") * gamma**2 - (g("PEY3") + g("PEY4") * gamma) * _sgn(alpha))
            * g("LEY", 1.0)
        )
        need(Ey <= 1.0 + 1e-9, "Ey <= 1 (4.E24)")
    if stage == "Mz0":
        need(g("QCZ1") > 0, "Ct = QCZ1 > 0 (4.E41)")
        Bt = (g("QBZ1") + g("QBZ2") * dfz + g("QBZ3") * dfz**2) * (
            1 + g("QBZ5") * np.abs(gamma) + g("QBZ6") * gamma**2
        )
        need(Bt > 0, "Bt > 0 (4.E40)")
        SHt = g("QHZ1") + g("QHZ2") * dfz + (g("QHZ3") + g("QHZ4") * dfz) * gamma
        at = np.tan(alpha) + SHt
        Et = (g("QEZ1") + g("QEZ2") * dfz + g("QEZ3") * dfz**2) * (
            1 + (g("QEZ4") + g("QEZ5") * gamma) * (2 / np.pi) * np.arctan(Bt * g("QCZ1") * at)
        )
        need(Et <= 1.0 + 1e-9, "Et <= 1 (4.E44)")
    if stage == "combined":
        need(g("RCX1") > 0, "Cxa = RCX1 > 0 (4.E55)")
        need(g("RCY1") > 0, "Cyk = RCY1 > 0 (4.E63)")
        Bxa = (g("RBX1") + g("RBX3") * gamma**2) * np.cos(np.arctan(g("RBX2") * kappa))
        need(Bxa > 0, "Bxa > 0 (4.E54)")
        Byk = (g("RBY1") + g("RBY4") * gamma**2) * np.cos(
            np.arctan(g("RBY2") * (alpha - g("RBY3")))
        )
        need(Byk > 0, "Byk > 0 (4.E62)")
        need(g("REX1") + g("REX2") * dfz <= 1.0 + 1e-9, "Exa <= 1 (4.E56)")
        need(g("REY1") + g("REY2") * dfz <= 1.0 + 1e-9, "Eyk <= 1 (4.E64)")
    if stage in ("Fx0", "Fy0", "pressure", "temperature"):
        inputs, _, valid = stack_inputs(model, series, ())
        out = evaluate_on(model, inputs)
        loaded = valid & (np.asarray(Fz) > 0)
        for name, attr in (("Dx: mux > 0 (4.E13)", "mux"), ("Dy: muy > 0 (4.E23)", "muy")):
            if (stage == "Fx0" and attr == "muy") or (stage == "Fy0" and attr == "mux"):
                continue
            v = getattr(out, attr, None)
            if v is not None:
                need(np.asarray(v)[loaded] > 0, name)
        for name, attr, sign in (
            ("Kxk > 0 (4.E15)", "Kxk", 1.0),
            ("Kya of the file's sign (4.E25)", "Kya", _sgn(g("PKY1", -1.0))),
        ):
            v = getattr(out, attr, None)
            if v is not None and stage in ("pressure", "temperature"):
                need(np.asarray(v)[loaded] * sign > 0, name)
    return msgs


# --- the staged fit -------------------------------------------------------------------------


def _condition_keys(series: WheelSeries, segs: Sequence[Segment]) -> list[tuple[str, float, float]]:
    """Per segment: (swept slip, load level [N], pressure level [Pa]) as the segmentation found
    them in the data, for sweep-wise hold-out per condition."""
    keys = []
    for seg in segs:
        kind = "+".join(seg.slips) or "+".join(sorted(seg.direction))
        fz = seg.condition.get("Fz")
        if fz is None:
            fz = float(np.nanmedian(series.Fz[seg.index])) if len(seg.index) else 0.0
        p = seg.condition.get("p", 0.0) if series.p is not None else 0.0
        keys.append((kind, round(fz, 1), round(p, 0)))
    return keys


def usable_mask(series: WheelSeries, options: FitOptions) -> Bools:
    """Samples kept for fitting: finite inputs, warm-up dropped."""
    ok = np.isfinite(series.Fz) & np.isfinite(series.kappa) & np.isfinite(series.alpha)
    if options.warmup_s > 0 and len(series):
        ok &= series.t >= series.t[0] + options.warmup_s
    warm_end = series.meta.get("warmup_end_s") if isinstance(series.meta, dict) else None
    if warm_end is not None and len(series):
        ok &= series.t >= series.t[0] + float(warm_end)
    if options.min_temperature is not None and series.T is not None:
        ok &= options.min_temperature <= series.T
    mask: Bools = ok
    return mask


def _has_channel(series: Sequence[WheelSeries], c: str) -> bool:
    for s in series:
        v = getattr(s, c)
        if v is not None and np.any(np.isfinite(v)):
            return True
    return False


@one_blas_thread
def fit_recording(
    wheels: Sequence[WheelSeries] | Mapping[str, WheelSeries],
    model: TireModel,
    options: FitOptions | None = None,
    **kwargs: Any,
) -> FitResult:
    """Staged fit of ``model`` to the wheels of one or more recordings.

    Parameters
    ----------
    wheels : sequence or mapping of WheelSeries
        All wheels are assumed to carry the same tyre (one model is fitted to all).
    model : TireModel
        Start model (its coefficients are the start values).
    options : FitOptions, optional
        Hold-out, warm-up, stage choice, progress; keyword arguments override its fields.

    Returns
    -------
    FitResult
        The fitted model and a JSON-ready report: per stage its status ("fitted", "skipped",
        "rejected", "not significant") with the reason, coefficients, values, standard errors;
        ``report["metrics"]`` holds :func:`report.fit_metrics` (before/after, fitted/held-out).
    """
    from .report import fit_metrics  # local: report imports this module's types

    options = options or FitOptions()
    for k, v in kwargs.items():
        if not hasattr(options, k):
            raise TypeError(f"fit_recording: unknown option {k!r}")
        setattr(options, k, v)
    wheels = list(wheels.values()) if isinstance(wheels, Mapping) else list(wheels)
    if not wheels:
        raise ValueError("no wheels to fit")
    for s in wheels:
        if not (_has_channel([s], "Fx") or _has_channel([s], "Fy") or _has_channel([s], "Mz")):
            raise ValueError(f"wheel {s.prefix}: no finite measured force (Fx, Fy or Mz)")
    progress = Progress(options.progress, options.stream)
    t_start = time.perf_counter()

    segments, train_masks, held_masks = [], [], []
    for s in wheels:
        segs = split_segments(s)
        keys = _condition_keys(s, segs)
        held = holdout_mask(segs, len(s), keys, every=options.holdout_every)
        ok = usable_mask(s, options)
        segments.append(segs)
        held_masks.append(held & ok)
        train_masks.append(~held & ok)
    train = [s.select(m) for s, m in zip(wheels, train_masks, strict=True) if m.any()]
    if not train:
        raise ValueError("no usable samples left after the warm-up and hold-out selection")
    cond = data_conditions(model, train)
    wanted = set(options.stages) if options.stages else None
    if wanted:
        unknown = wanted - {st.name for st in STAGES}
        if unknown:
            raise ValueError(
                f"unknown stage(s): {', '.join(sorted(unknown))}; "
                f"known: {', '.join(st.name for st in STAGES)}"
            )

    start = model
    stage_reports = []
    for st in STAGES:
        entry: dict[str, Any] = {"stage": st.name, "status": "skipped"}
        stage_reports.append(entry)
        progress.start(st.name)
        reason = _skip_reason(st, cond, wanted, train)
        if reason:
            entry["reason"] = reason
            progress.done(f"skipped: {reason}")
            continue
        subset = [s.select(sample_mask(s, st.samples)) for s in train]
        subset = [s for s in subset if len(s)]
        channels = tuple(c for c in st.channels if _has_channel(subset, c))
        names = stage_names(st, cond, model)
        if st.samples == "pure":  # keep the direction(s) the recording sweeps
            swept = slip_swept(train)
            if not swept["long"]:
                channels = tuple(c for c in channels if c != "Fx")
                names = [k for k in names if not k.startswith(("PDX", "PKX", "PPX", "TTX"))]
            if not swept["lat"]:
                channels = tuple(c for c in channels if c != "Fy")
                names = [k for k in names if not k.startswith(("PDY", "PKY", "PPY", "TTY"))]
        beyond = past_peak(model, subset)
        dropped = [k for k in names if k in PEAK_SHAPE and not beyond[PEAK_SHAPE[k]]]
        if dropped:  # friction and curvature are only seen beyond the force peak
            names = [k for k in names if k not in dropped]
            entry["not_identifiable"] = {
                "names": dropped,
                "reason": "the recorded slip does not reach past the force peak",
            }
        fixed = [k for k in names if k in options.fixed]
        if fixed:
            names = [k for k in names if k not in options.fixed]
            entry["fixed"] = fixed
        entry.update({"samples": st.samples, "channels": list(channels), "names": names})
        if not names:
            entry["reason"] = "every coefficient it would fit is fixed"
            progress.done(f"skipped: {entry['reason']}")
            continue
        if not channels:
            entry["reason"] = f"no measured {'/'.join(st.channels)} on its {st.samples} samples"
            progress.done(f"skipped: {entry['reason']}")
            continue
        try:
            fitted, info = fit_coefficients(
                model,
                subset,
                names,
                channels,
                loss=options.loss,
                max_samples=options.max_samples,
                progress=progress.update,
            )
        except ValueError as exc:
            entry["reason"] = str(exc)
            progress.done(f"skipped: {exc}")
            continue
        entry.update(_info_summary(info))
        # Keep the start values unless the fit beats the noise: the gain in effective
        # chi-square must exceed what fitting n free coefficients to pure noise gives
        # (n on average, n + 3 sqrt(2n) rarely).
        n_free = len(names)
        needed = n_free + 3.0 * math.sqrt(2.0 * n_free)
        gain = float(info.get("delta_chi2_eff", math.inf))
        entry["significance"] = {"delta_chi2_eff": gain, "needed": needed}
        if gain < needed:
            entry["status"] = "not significant"
            entry["reason"] = (
                f"the fit gains {gain:.1f} effective chi-square units, less than "
                f"{needed:.1f} expected from fitting noise: start values kept"
            )
            progress.done(entry["reason"])
            continue
        before = physical_checks(st.name, model, subset)
        after = physical_checks(st.name, fitted, subset)
        # A condition the start file already breaks (e.g. E > 1, which the model clips at 1
        # with its limits on) is reported; a new or wider violation rejects the stage.
        worse = {k: f for k, f in after.items() if f > before.get(k, 0.0) + 1e-3}
        kept = {k: f for k, f in after.items() if k not in worse}
        if kept:
            entry["warnings"] = [
                f"{k} fails on {100 * f:.1f} % of the samples, as in the start model"
                for k, f in kept.items()
            ]
        if worse:
            entry["status"] = "rejected"
            entry["reason"] = "; ".join(
                f"{k} fails on {100 * f:.1f} % of the samples "
                f"(start model: {100 * before.get(k, 0.0):.1f} %)"
                for k, f in worse.items()
            )
            progress.done(f"rejected: {entry['reason']}")
            continue
        entry["status"] = "fitted"
        model = fitted
        rb, ra = info["rmse_before"], info["rmse_after"]
        progress.done(
            f"{len(names)} coefficients on {info['n_rows']} samples, {info['nfev']} evaluations, "
            + ", ".join(f"{c} rmse {rb[c]:.4g} -> {ra[c]:.4g}" for c in channels)
        )

    report = {
        "stages": stage_reports,
        "conditions": {
            k: (bool(v) if isinstance(v, (bool, np.bool_)) else v) for k, v in cond.items()
        },
        "holdout_every": options.holdout_every,
        "n_samples": int(sum(len(s) for s in wheels)),
        "n_train": int(sum(int(m.sum()) for m in train_masks)),
        "n_heldout": int(sum(int(m.sum()) for m in held_masks)),
        "n_sweeps": int(sum(len({g.sweep for g in segs if g.sweep >= 0}) for segs in segments)),
        "n_ramps": int(sum(sum(1 for g in segs if g.kind == "ramp") for segs in segments)),
        "wheels": [_wheel_name(s) for s in wheels],
        "changed": _changed(start, model),
    }
    statuses = {st["status"] for st in stage_reports}
    if "fitted" not in statuses and "not significant" in statuses:
        report["note"] = (
            "no stage improved on the start model by more than fitting the noise would: the "
            "start model already explains the data, and is the result unchanged"
        )
    result = FitResult(model, report, start, wheels, train_masks, held_masks, segments)
    report["metrics"] = fit_metrics(result)
    report["time_s"] = time.perf_counter() - t_start
    return result


def _skip_reason(
    st: Stage, cond: Mapping[str, Any], wanted: set[str] | None, train: Sequence[WheelSeries]
) -> str:
    if wanted is not None and st.name not in wanted:
        return "not requested"
    if st.needs == "pressure" and not cond["pressure_varies"]:
        return (
            "no pressure channel in the recording"
            if not cond["pressure_recorded"]
            else "the recorded pressure does not vary (< 3 % of NOMPRES)"
        )
    if st.needs == "temperature" and not cond["temperature_varies"]:
        return (
            "no temperature channel in the recording"
            if not cond["temperature_recorded"]
            else "the recorded temperature does not vary (< 3 degC)"
        )
    if not any(sample_mask(s, st.samples).any() for s in train):
        return f"no {st.samples.replace('_', ' ')} samples"
    swept = slip_swept(train)
    if st.samples in ("pure_long", "combined") and not swept["long"]:
        return f"no slip-ratio sweep (|kappa| < {MIN_KAPPA_SWEEP:g} on 95 % of the samples)"
    if st.samples in ("pure_lat", "combined") and not swept["lat"]:
        return f"no slip-angle sweep (|alpha| < {MIN_ALPHA_SWEEP_DEG:g} deg on 95 % of the samples)"
    if st.samples == "pure" and not (swept["long"] or swept["lat"]):
        return "no slip sweep at all"
    return ""


def past_peak(model: TireModel, series: Sequence[WheelSeries]) -> dict[str, bool]:
    """Whether the samples reach past the pure-slip force peak of ``model``: some samples
    beyond 1.2 times the peak slip (the slip of maximum |Fx0| or |Fy0| at each sample's load)."""
    out = {"long": False, "lat": False}
    if not series:
        return out
    Fz = _cat_required(series, "Fz")
    kappa = np.abs(_cat_required(series, "kappa"))
    alpha = np.abs(_cat_required(series, "alpha"))
    ok = np.isfinite(Fz) & np.isfinite(kappa) & np.isfinite(alpha) & (Fz > 0)
    if not ok.any():
        return out
    fz = np.percentile(Fz[ok], [10.0, 50.0, 90.0])
    k_grid = np.linspace(0.0, 0.6, 121)
    a_grid = np.radians(np.linspace(0.0, 25.0, 126))
    for name, grid, slip, is_long in (("long", k_grid, kappa, True), ("lat", a_grid, alpha, False)):
        FZ, X = np.meshgrid(fz, grid, indexing="ij")
        out_ = model.evaluate(FZ, X if is_long else 0.0, 0.0 if is_long else X)
        force = np.abs(np.asarray(out_.Fx if is_long else out_.Fy))
        peak = float(np.max(grid[np.argmax(force, axis=1)]))
        beyond = slip[ok] > 1.2 * peak
        # a handful of samples past the peak is enough: sweeps spend little time there
        out[name] = peak > 0 and int(np.sum(beyond)) >= 20
    return out


def slip_swept(train: Sequence[WheelSeries]) -> dict[str, bool]:
    """Whether the pure-slip samples sweep the slip ratio ("long") and the slip angle ("lat")."""
    out = {"long": False, "lat": False}
    for s in train:
        k = np.abs(s.kappa[sample_mask(s, "pure_long") & np.isfinite(s.kappa)])
        a = np.abs(s.alpha[sample_mask(s, "pure_lat") & np.isfinite(s.alpha)])
        out["long"] |= len(k) > 20 and float(np.percentile(k, 95)) > MIN_KAPPA_SWEEP
        out["lat"] |= len(a) > 20 and float(np.percentile(a, 95)) > math.radians(
            MIN_ALPHA_SWEEP_DEG
        )
    return out


def _wheel_name(s: WheelSeries) -> str:
    """``bag:prefix`` when the series knows its bag, else the prefix."""
    bag = s.meta.get("bag") if isinstance(s.meta, dict) else None
    return f"{bag}:{s.prefix}" if bag else s.prefix


def _info_summary(info: Mapping[str, Any]) -> dict[str, Any]:
    keep = (
        "cost",
        "cost_start",
        "delta_chi2_eff",
        "nfev",
        "success",
        "message",
        "n_used",
        "n_rows",
        "rho1",
        "tau_int",
        "at_bound",
        "rmse_before",
        "rmse_after",
        "sigma",
        "time_s",
    )
    out = {k: info[k] for k in keep if k in info}
    out["values"] = dict(zip(info["names"], info["x"], strict=True))
    out["start"] = dict(zip(info["names"], info["x0"], strict=True))
    out["stderr"] = info["stderr"]
    return out


def _changed(before: TireModel, after: TireModel) -> dict[str, list[float]]:
    """Coefficients whose value changed: name -> [before, after]."""
    out: dict[str, list[float]] = {}
    for k, v in after.params.items():
        v0 = before.params.get(k)
        if isinstance(v, (int, float)) and v0 is not None and v0 != v:
            out[k] = [float(v0), float(v)]
    return out
