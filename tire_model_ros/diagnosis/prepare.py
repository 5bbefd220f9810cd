"""From a recorded wheel to what every effect model reads: inputs, drivers, sweeps, folds.

One :class:`Wheel` per recorded wheel (the diagnosis runs per wheel), and one
:class:`Context` holding the file's model, the noise levels and the session-wide conventions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.signal import savgol_filter

from tire_model_ros.fit.sweeps import Segment, split_segments
from tire_model_ros.model import TireModel
from tire_model_ros.recording.series import WheelSeries
from tire_model_ros.vocabulary import DIAGNOSED_CHANNELS

from .dynamics import cumulative_work_J, frictional_power_W
from .folds import BLOCK_S, assign_folds, block_index

Array = npt.NDArray[np.float64]
Index = npt.NDArray[np.int64]
Mask = npt.NDArray[np.bool_]

CHANNELS = DIAGNOSED_CHANNELS  # the measured channels compared; Fx, Fy are selected on
MIN_SAMPLES = 50
MIN_BLOCKS = 6  # fewer whole sweeps than this: time blocks instead
TIME_BLOCK_S = (2.0, 15.0)  # a time block spans 4 correlation times of the residual, within
SMOOTH_WINDOWS = (7, 9, 11, 15, 21, 31, 41, 61)  # candidate input smoother windows [samples]
SHORTER_WINDOWS = (1, 5)  # ... and below them, which only the forces may ask for (see shorten)
SHORTEN_ROWS = 20000  # samples the forces are compared on when the windows are shortened
# ... and a shorter window's force RMS must be this much lower, else the two tie and the
# cross-validated window stands (the margin of the engine's Occam rule, search.OCCAM_MARGIN)
SHORTEN_MARGIN = 0.02
LEFT_OUT = 1  # neighbours on each side a sample is predicted without (noise correlation)
SMOOTHED = ("kappa", "alpha", "gamma", "Fz", "V")  # recorded inputs smoothed (p, T: not)
FIT_ROWS_PER_FOLD = 1500  # model rows per fold used by the fits (100 Hz rows are redundant)
# Convention for a hidden temperature (PHYSICS.md: the heat gain and the TTX/TTY coefficients
# are not separately identifiable with T hidden): a node's steady rise at the 95th-percentile
# frictional power is THERMAL_RISE_REF_K; the TTX/TTY coefficients are fitted on that scale.
THERMAL_RISE_REF_K = 20.0


@dataclass
class Wheel:
    """One wheel's samples prepared for the diagnosis (full length, time from 0 s)."""

    prefix: str
    t: Array
    inputs: dict[str, Array | None]  # kappa, alpha, gamma, Fz, V, p, T (None: not recorded)
    meas: dict[str, Array]  # measured channels present: Fx, Fy, Mz
    P: Array  # frictional power [W] from the measured forces
    E: Array  # cumulative frictional work [J]
    Vs: Array  # sliding speed [m/s]
    segments: list[Segment]  # time order
    blocks: list[Index]  # whole sweeps (sample indices), the units of validation
    block_id: npt.NDArray[np.int64]  # block number per sample
    fold: npt.NDArray[np.int8]  # 0, 1 (selection folds) or 2 (final held-out) per sample
    scramble: Index  # sample order of a block-shuffled copy of a driver (controls)
    # samples where a recorded input was not finite (bridged, left out of fits and scores),
    # and how many per input
    bridged: Mask
    smoothing: dict[str, int] = field(default_factory=dict)  # input smoother windows [samples]
    gaps: dict[str, int] = field(default_factory=dict)
    dropped: tuple[str, ...] = ()  # optional inputs without a finite sample: not recorded

    @property
    def n(self) -> int:
        return len(self.t)

    def x(self, key: str) -> Array:
        """A recorded input that is always present (kappa, alpha, gamma, Fz, V)."""
        v = self.inputs[key]
        assert v is not None, key
        return v


@dataclass
class Context:
    """What every effect model may read: the file's model, the wheel, the conventions."""

    model: TireModel
    base: dict[str, float]
    wheel: Wheel
    channels: tuple[str, ...]  # fitted and selected on (Fx, Fy; Mz only when alone)
    all_channels: tuple[str, ...]  # every measured channel (reported)
    sigma: dict[str, float]  # noise level per channel [N or N m]
    T_amb: float  # ambient of a hidden thermal node = NOMTEMP [degC]
    k_thermal: float  # K per W of a hidden node (convention above)
    p_nom: float  # nominal gauge pressure [Pa]
    E_ref: float  # the session's total frictional work [J]
    t_end: float  # session length [s]
    V0: float  # LONGVL [m/s]
    informative: dict[str, bool]  # "x" / "y": that slip is swept in every fold
    moving: dict[str, bool]  # "x" / "y": that slip moves at all (transients)
    rows: dict[str, Index] = field(default_factory=dict)  # fit/score rows per fold set
    cache: dict[str, Any] = field(default_factory=dict)  # per-recording precomputations


def bridge(t: Array, x: Array) -> tuple[Array, Mask]:
    """A recorded input (at least one sample finite: :func:`prepare_wheel` drops or refuses a
    channel without one) with its non-finite samples bridged linearly in time (held at the
    ends), and where they were.

    A NaN in a message (a sensor's dropout flag, a failed conversion) is no value: filled with
    zero, a load dropout would become a zero-load stretch and the smoother would spread the step
    to zero into its good neighbours; filled with the channel's median, a temperature would
    step to it and back, and a lag of it (a carcass) would carry the steps on.
    """
    bad = ~np.isfinite(x)
    if not bad.any():
        return x, bad
    return np.where(bad, np.interp(t, t[~bad], x[~bad]), x), bad


def _left_out_kernel(w: int) -> Array:
    """The weights that predict a sample from a quadratic least-squares fit over a window of
    ``w`` samples without it and its LEFT_OUT neighbours on each side."""
    j = np.arange(w, dtype=np.float64) - (w - 1) // 2
    keep = np.abs(j) > LEFT_OUT
    k = np.zeros(w)
    k[keep] = np.linalg.pinv(np.vander(j[keep], 3, increasing=True))[0]
    return k


def cv_window(x: Array) -> int:
    """The Savitzky-Golay window [samples] of a recorded input, chosen from the channel
    itself by cross-validation (1: none fits).

    Recorded slip carries sensor noise; through the slip stiffness it is as large as the force
    noise. Left in, any model that low-passes the inputs (relaxation, a delay's filter) would
    gain by denoising rather than by physics. Smoothed too much, a fast input (a car's load
    transfer, a brake's slip) is distorted, and every model inherits that error as a floor. The
    window whose quadratic fit best predicts each sample from the others leaves the least of
    either, per channel: a rig's slow sweeps take long windows, a car's fast load and slip
    short ones. A DAQ's anti-alias filter correlates the noise of neighbouring samples, which
    leave-one-out (or generalised) cross-validation reads as signal, keeping the shortest
    window (Chu and Marron 1991; Opsomer, Wang and Yang 2001): each sample is predicted
    without its LEFT_OUT neighbours on each side too. A quadratic fit keeps ramps exact and
    the filter shifts nothing in time.
    """
    best, best_cv = 1, math.inf
    for w in SMOOTH_WINDOWS:
        if len(x) <= 2 * w:
            break
        r = x[(w - 1) // 2 : len(x) - (w - 1) // 2] - np.convolve(x, _left_out_kernel(w), "valid")
        cv = float(np.mean(r * r))
        if cv < best_cv:
            best, best_cv = w, cv
    return best


def savgol(x: Array, w: int) -> Array:
    """Zero-phase quadratic Savitzky-Golay smoothing over ``w`` samples (1: a copy)."""
    if w <= 1 or len(x) <= w:
        return x.copy()
    return np.asarray(savgol_filter(x, w, 2, mode="interp"), dtype=np.float64)


def shorten(
    raw: dict[str, Array],
    windows: dict[str, int],
    model: TireModel,
    meas: dict[str, Array],
    optional: dict[str, Array | None],
    bridged: Mask,
) -> dict[str, int]:
    """Each input's window shortened where the file model's forces ask for it (compared on
    the samples where no input was ``bridged``).

    The cross-validation of :func:`cv_window` weighs an input's error alike everywhere and, by
    predicting each sample without its neighbours, favours long windows where the input moves
    fast. The forces weigh it by the tyre's sensitivity, which is largest there (a car's load
    transfer, a brake's slip): the file model's Fx and Fy against the measured ones (whose own
    noise does not depend on the window) tell how much each window distorts and lets through.
    Channel by channel, the shorter window that predicts those forces best is taken when it
    predicts them better by SHORTEN_MARGIN of their RMS (a car's loads: 8 % better unsmoothed;
    the file model was 13 N off its own true Fx on true inputs smoothed with the windows of
    the cross-validation, most of it from the loads' 70 ms; a Flat-Trac's load
    steps 2.2 % better over 21 samples than over 61); within that the two tie and the
    cross-validated window stands (its camber steps: 0.000 %, which, shortened anyway, tipped
    a near-tie of camber and pressure).
    Never a longer one: a longer window's zero-phase smoothing would take a relaxation's or a
    delay's filtering out of the forces before any model of it is tried.
    """
    forces = [ch for ch in ("Fx", "Fy") if ch in meas]
    if not forces:
        return windows
    ok = np.all([np.isfinite(meas[ch]) for ch in forces], axis=0) & ~bridged
    rows = np.flatnonzero(ok)
    rows = rows[:: max(1, len(rows) // SHORTEN_ROWS)]
    if len(rows) == 0:
        return windows
    out = dict(windows)
    smoothed = {k: savgol(raw[k], w)[rows] for k, w in out.items()}
    opt = {k: (None if v is None else v[rows]) for k, v in optional.items()}

    def sse(inputs: dict[str, Array]) -> float:
        o = model.evaluate(inputs["Fz"], inputs["kappa"], inputs["alpha"], inputs["gamma"],
                           Vx=inputs["V"], p=opt["p"], T=opt["T"], full=False,
                           moments=False)  # fmt: skip
        return float(sum(np.sum((np.asarray(getattr(o, ch)) - meas[ch][rows]) ** 2)
                         for ch in forces))  # fmt: skip

    current = sse(smoothed)
    for key in SMOOTHED:
        shorter = [w for w in (*SHORTER_WINDOWS, *SMOOTH_WINDOWS) if w < out[key]]
        trials = {w: {**smoothed, key: savgol(raw[key], w)[rows]} for w in shorter}
        errs = {w: sse(x) for w, x in trials.items()}
        if not errs:
            continue
        w = min(errs, key=errs.__getitem__)
        if math.sqrt(errs[w]) <= (1.0 - SHORTEN_MARGIN) * math.sqrt(current):
            current, out[key], smoothed = errs[w], w, trials[w]
    return out


def prepare_wheel(
    s: WheelSeries,
    model: TireModel,
    rng: np.random.Generator,
    windows: dict[str, int] | None = None,
) -> Wheel:
    """The diagnosis' view of one recorded wheel (``windows``: its inputs' smoother windows,
    chosen from the recording when not given).

    Raises
    ------
    ValueError
        Too few samples, a slip, camber or load without a finite sample, or no measured force
        or moment.
    """
    n = len(s.t)
    if n < MIN_SAMPLES:
        raise ValueError(f"{s.prefix}: only {n} samples, too few to diagnose")
    for k in ("kappa", "alpha", "gamma", "Fz"):
        if not np.isfinite(np.asarray(getattr(s, k), float)).any():
            raise ValueError(f"{s.prefix}: {k} has no finite sample")
    optional = {"V": s.Vx, "p": s.p, "T": s.T}
    dropped = tuple(
        k for k, v in optional.items() if v is not None and not np.isfinite(np.asarray(v)).any()
    )
    given = {k: None if k in dropped else v for k, v in optional.items()}
    P = model.params
    V = np.asarray(given["V"], float) if given["V"] is not None else np.full(n, float(P["LONGVL"]))
    meas = {}
    for ch in CHANNELS:
        v = getattr(s, ch)
        if v is not None and np.isfinite(v).mean() > 0.5:
            meas[ch] = np.where(np.isfinite(v), v, np.nan)
    if not meas:
        raise ValueError(f"{s.prefix}: no measured Fx, Fy or Mz")
    t = np.asarray(s.t, float) - float(s.t[0])
    raw = {"kappa": s.kappa, "alpha": s.alpha, "gamma": s.gamma, "Fz": s.Fz, "V": V}
    inputs: dict[str, Array | None] = {"p": None, "T": None}
    rawf, gap = {}, {}
    for k in SMOOTHED:
        rawf[k], gap[k] = bridge(t, np.asarray(raw[k], float))
    for k in ("p", "T"):
        if given[k] is not None:
            inputs[k], gap[k] = bridge(t, np.asarray(given[k], float))
    bridged = np.any(list(gap.values()), axis=0)
    if windows is None:
        windows = {k: cv_window(rawf[k]) for k in SMOOTHED}
        windows = shorten(rawf, windows, model, meas, inputs, bridged)
    for key in SMOOTHED:
        inputs[key] = savgol(rawf[key], windows[key])
    kappa, alpha = inputs["kappa"], inputs["alpha"]
    assert kappa is not None and alpha is not None
    zero = np.zeros(n)
    Pw = frictional_power_W(
        np.nan_to_num(meas.get("Fx", zero)),
        np.nan_to_num(meas.get("Fy", zero)),
        rawf["V"],
        kappa,
        alpha,
    )
    segments, block_s = split_segments(s), BLOCK_S
    if len(block_index(segments, t)) < MIN_BLOCKS:
        block_s = time_block_s(s, model, t, meas)
    bl = block_index(segments, t, block_s)
    block_id = np.empty(n, dtype=np.int64)
    for i, idx in enumerate(bl):
        block_id[idx] = i
    fold = assign_folds(segments, t, rng, inputs, block_s)
    order = rng.permutation(len(bl))
    scramble = np.concatenate([bl[i] for i in order])
    return Wheel(
        s.prefix,
        t,
        inputs,
        meas,
        Pw,
        cumulative_work_J(Pw, t),
        np.abs(V) * np.hypot(kappa, np.tan(alpha)),
        segments,
        bl,
        block_id,
        fold,
        scramble,
        bridged,
        windows,
        {k: int(g.sum()) for k, g in gap.items() if g.any()},
        dropped,
    )


def time_block_s(s: WheelSeries, model: TireModel, t: Array, meas: dict[str, Array]) -> float:
    """The block length [s] where the recording has too few sweeps for BLOCK_S (a short
    session, or driving with no pause): about four correlation times of the file model's
    residual, so that neighbouring blocks are nearly independent, and at least nine blocks."""
    o = model.evaluate(np.nan_to_num(s.Fz), np.nan_to_num(s.kappa), np.nan_to_num(s.alpha),
                       np.nan_to_num(s.gamma), Vx=s.Vx, p=s.p, T=s.T, full=False)  # fmt: skip
    tau = max(correlation_time(meas[ch] - np.asarray(getattr(o, ch)), t) for ch in meas)
    return min(float(np.clip(4.0 * tau, *TIME_BLOCK_S)), float(t[-1]) / 9.0)


def correlation_time(r: Array, t: Array) -> float:
    """Lag [s] at which the autocorrelation of ``r`` first falls below 1/e."""
    r = np.nan_to_num(r - np.nanmean(r))
    if len(r) < 8 or not np.any(r):
        return 0.0
    f = np.fft.rfft(r, 2 * len(r))
    acf = np.fft.irfft(f * np.conj(f))[: len(r)]
    below = np.flatnonzero(acf < acf[0] / np.e)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    return float(below[0]) * dt if len(below) else float(t[-1] - t[0])


def swept(w: Wheel, key: str, level: float) -> bool:
    """A slip channel is swept beyond ``level`` in enough whole sweeps of both selection folds
    to be cross-validated (one in each, four in all)."""
    x = np.abs(w.x(key))
    per_fold = [0, 0, 0]
    for idx in w.blocks:
        if np.max(x[idx]) > level:
            per_fold[int(w.fold[idx[0]])] += 1
    return min(per_fold[:2]) >= 1 and sum(per_fold) >= 4


def fold_rows(w: Wheel, folds: tuple[int, ...], stride: int) -> Index:
    """Rows of ``folds`` where every measured channel is finite and no input was bridged,
    every ``stride``-th."""
    ok = ~w.bridged
    for v in w.meas.values():
        ok &= np.isfinite(v)
    return np.flatnonzero(np.isin(w.fold, folds) & ok)[::stride]


def make_context(w: Wheel, model: TireModel) -> Context:
    """The conventions of one wheel's diagnosis (noise levels are set by the engine)."""
    P = dict(model.params)
    chans = tuple(ch for ch in CHANNELS if ch in w.meas)
    # Selection and fitting use the forces; Mz (pneumatic trail, effect-specific) is reported
    # and refitted on the chosen forces, but only selected on when no force was recorded.
    fit_chans = tuple(ch for ch in chans if ch != "Mz") or chans
    inf_x = "Fx" in w.meas and swept(w, "kappa", 0.02)
    inf_y = "Fy" in w.meas and swept(w, "alpha", np.radians(2.0))
    p95 = float(np.percentile(w.P[w.P > 0], 95)) if np.any(w.P > 0) else 1.0
    stride = max(1, int(w.n / 3 / FIT_ROWS_PER_FOLD))
    ctx = Context(
        model=model,
        base=P,
        wheel=w,
        channels=fit_chans,
        all_channels=chans,
        sigma=dict.fromkeys(chans, 1.0),
        T_amb=float(P.get("NOMTEMP", 25.0)),
        k_thermal=THERMAL_RISE_REF_K / max(p95, 1e-6),
        p_nom=float(P.get("INFLPRES") or P.get("NOMPRES") or 2e5),
        E_ref=max(float(w.E[-1]), 1e-6),
        t_end=max(float(w.t[-1]), 1e-3),
        V0=float(P.get("LONGVL", 16.7)),
        informative={"x": inf_x, "y": inf_y},
        moving={
            "x": inf_x
            or ("Fx" in w.meas and float(np.percentile(np.abs(w.x("kappa")), 95)) > 0.01),
            "y": inf_y
            or ("Fy" in w.meas and float(np.percentile(np.abs(w.x("alpha")), 95)) > np.radians(1)),
        },
    )
    ctx.rows = {
        "a": fold_rows(w, (0,), stride),
        "b": fold_rows(w, (1,), stride),
        "ab": fold_rows(w, (0, 1), stride),
        "c": fold_rows(w, (2,), 1),
        "all": np.arange(w.n),
    }
    ctx.cache["stride"] = stride
    return ctx
