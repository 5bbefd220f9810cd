"""Split a recording into sweeps: the unit of validation for autocorrelated rig data.

Samples recorded at 100 Hz and more are strongly autocorrelated, so a random choice of
validation rows measures interpolation, not prediction. Validation and significance must work
on whole sweeps. :func:`split_segments` cuts a wheel's samples, in time order, into contiguous
segments of one kind each:

- a monotone ramp of a driver channel: a slip (slip ratio, slip angle), or, while both slips
  are held, a condition (load, inclination, pressure) moving to its next set point,
- a steady part (drivers held, slip away from zero),
- a pause (drivers held, slip near zero),

with a break wherever the time stamps jump (a gap in the recording). Everything is found from
the data, not from a known programme:

- Drivers are smoothed over about 0.2 s; a channel moves only when its smoothed rate exceeds
  both a noise-derived and a range-derived threshold; runs shorter than ``min_duration_s`` are
  absorbed by their neighbours (a brief hold at a sweep's turning point is no segment).
- While a slip is swept, the conditions are not drivers: a real rig's load and inclination
  follow the tyre's forces (a TTC cornering run's load moves by some per cent during each
  sweep), and that must not cut the sweep. Of two slips moving together, one much slower
  than the other (in units of a typical sweep: 0.1 slip ratio, 5 deg) follows it and is
  dropped too.
- Consecutive slip ramps of one slip channel form a sweep (``Segment.sweep``), at most three
  (0 -> +A -> -A -> 0): continuous constant-rate sweeps with no pause between, as the FSAE
  TTC runs them, still come out one by one when a condition changes between them.
- Conditions are levels found by clustering the held segments' medians of each channel (a gap
  wider than ``LEVEL_GAP`` between sorted medians separates two levels); each segment carries
  the levels of the channels held in it (``Segment.condition``: Fz [N], p [Pa], gamma [rad],
  and the slip that is not swept: alpha [rad] of a drive/brake run, kappa [-]).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from tire_model_ros.recording.series import WheelSeries

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]

# Channels whose motion defines a sweep, with the smallest range [unit] that counts as "moving"
# at all (a channel that stays within this band is treated as held constant).
DRIVERS: dict[str, float] = {
    "kappa": 2e-3,  # slip ratio [-]
    "alpha": float(np.deg2rad(0.2)),  # slip angle [rad]
    "Fz": 50.0,  # load [N]
    "gamma": float(np.deg2rad(0.2)),  # inclination [rad]
    "p": 3000.0,  # gauge pressure [Pa]
}
SLIPS = ("kappa", "alpha")
# A typical sweep's amplitude per slip: rates are compared in these units [-, rad].
SLIP_SCALE: dict[str, float] = {"kappa": 0.1, "alpha": float(np.deg2rad(5.0))}
FOLLOW_SHARE = 0.2  # a slip moving slower than this share of the other one follows it
# Slip channels: a held segment with both near zero is a pause.
PAUSE_KAPPA = 5e-3
PAUSE_ALPHA_RAD = float(np.deg2rad(0.3))
MAX_RAMPS_PER_SWEEP = 3  # 0 -> +A -> -A -> 0
# Two condition levels are apart when their sorted segment medians leave a gap wider than
# max(absolute, relative * median |value|) [unit of the channel].
LEVEL_GAP: dict[str, tuple[float, float]] = {
    "kappa": (0.01, 0.0),
    "alpha": (float(np.deg2rad(0.5)), 0.0),
    "Fz": (50.0, 0.05),
    "gamma": (float(np.deg2rad(0.5)), 0.0),
    "p": (3000.0, 0.03),
}


@dataclass(frozen=True)
class Segment:
    """One sweep or segment of a wheel's samples.

    Attributes
    ----------
    index : ndarray of int
        Sample indices, contiguous and increasing.
    kind : str
        ``"ramp"`` (some driver moves monotonically), ``"steady"`` or ``"pause"``.
    direction : dict[str, int]
        For every driver channel that moves in this segment: +1 rising, -1 falling.
    sweep : int
        Number of the slip sweep this segment belongs to (its ramps share it), -1 for none.
    condition : dict[str, float]
        Level of every channel held in the segment (Fz [N], p [Pa], gamma [rad], and a held
        slip: kappa [-], alpha [rad]): the centre of the level the clustering found.
    """

    index: npt.NDArray[np.intp]
    kind: str
    direction: dict[str, int]
    sweep: int = -1
    condition: dict[str, float] = field(default_factory=dict)

    @property
    def label(self) -> str:
        """Short text such as ``"ramp alpha+"`` or ``"pause"``."""
        if self.kind != "ramp":
            return self.kind
        moves = " ".join(f"{k}{'+' if s > 0 else '-'}" for k, s in self.direction.items())
        return f"ramp {moves}"

    @property
    def slips(self) -> tuple[str, ...]:
        """The slip channels this segment sweeps."""
        return tuple(k for k in SLIPS if k in self.direction)


def _moving_mean(x: Floats, w: int) -> Floats:
    """Centred moving average of odd length ``w`` (edges use the available samples)."""
    if w <= 1 or len(x) < 3:
        return x.copy()
    c = np.concatenate(([0.0], np.cumsum(x)))
    n = len(x)
    half = w // 2
    lo = np.clip(np.arange(n) - half, 0, n)
    hi = np.clip(np.arange(n) + half + 1, 0, n)
    out: Floats = (c[hi] - c[lo]) / (hi - lo)
    return out


def noise_sigma(y: npt.ArrayLike) -> float:
    """Robust white-noise level of a sampled signal: MAD of its second differences / sqrt(6).

    Smooth force curves and slip ramps nearly cancel in second differences at rig sample
    rates, the noise does not. NaN samples are skipped; fewer than 5 samples give 0.
    """
    v = np.asarray(y, dtype=np.float64)
    v = v[np.isfinite(v)]
    if len(v) < 5:
        return 0.0
    d2 = np.diff(v, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


def _fill_nan(x: npt.ArrayLike) -> Floats:
    """Carry the last finite value forward (and the first one backward); all-NaN -> zeros."""
    v = np.asarray(x, dtype=np.float64)
    ok = np.isfinite(v)
    if ok.all():
        return v
    if not ok.any():
        return np.zeros_like(v)
    idx = np.where(ok, np.arange(len(v)), 0)
    np.maximum.accumulate(idx, out=idx)
    first = int(np.argmax(ok))
    idx[:first] = first
    out: Floats = v[idx]
    return out


@dataclass(frozen=True)
class _Grid:
    """Sampling constants of one split: window and shortest run [samples], median step [s]."""

    t: Floats
    w: int
    min_len: int
    dt: float


def _direction_state(
    x: Floats, grid: _Grid, min_range: float, min_len: int
) -> tuple[npt.NDArray[np.int8], Floats]:
    """Per-sample direction of channel ``x`` (+1 rising, -1 falling, 0 held) and its smoothed
    rate [unit/s]."""
    x = _fill_nan(x)
    lo, hi = np.percentile(x, [1.0, 99.0])
    span = float(hi - lo)
    n, w = len(x), grid.w
    if span < min_range:
        return np.zeros(n, dtype=np.int8), np.zeros(n)
    xs = _moving_mean(x, w)
    # Rate over one window: difference of two independent window means, so its noise is
    # sigma*sqrt(2/w)/(w*dt) for white noise of level sigma.
    h = w // 2
    i = np.arange(n)
    i_lo, i_hi = np.clip(i - h, 0, n - 1), np.clip(i + h, 0, n - 1)
    dt_win = np.maximum(grid.t[i_hi] - grid.t[i_lo], grid.dt)
    rate: Floats = (xs[i_hi] - xs[i_lo]) / dt_win
    # A slow sensor logged with sample and hold (pressure at 10 Hz beside 100 Hz slip) repeats
    # each value: its noise is that of the distinct values, averaged over fewer of them.
    changes = np.flatnonzero(np.diff(x) != 0) + 1
    hold = n / (len(changes) + 1)
    w_eff = max(1.0, w / hold)
    sigma_rate = noise_sigma(x[np.r_[0, changes]]) * np.sqrt(2.0 / w_eff) / (w * grid.dt)
    thr = max(6.0 * sigma_rate, 0.01 * span)  # 1 % of the range per second counts as held
    state = np.zeros(n, dtype=np.int8)
    state[rate > thr] = 1
    state[rate < -thr] = -1
    # Remove isolated flickers of this channel before it is combined with the others.
    return _absorb_short_runs(state, min_len).astype(np.int8), rate


def _runs(code: npt.NDArray[np.integer]) -> tuple[Ints, Ints]:
    """Start and end (exclusive) indices of runs of equal values."""
    if len(code) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    change = np.flatnonzero(code[1:] != code[:-1]) + 1
    starts = np.concatenate(([0], change)).astype(np.int64)
    ends = np.concatenate((change, [len(code)])).astype(np.int64)
    return starts, ends


def _absorb_short_runs(code: npt.NDArray[np.integer], min_len: int) -> Ints:
    """Give runs shorter than ``min_len`` the code of the preceding long run (else the next)."""
    out = code.astype(np.int64)
    for _ in range(3):  # a few passes settle chains of short runs
        starts, ends = _runs(out)
        short = (ends - starts) < min_len
        if not short.any() or short.all():
            break
        run_code = out[starts]
        keep = np.where(~short, np.arange(len(starts)), -1)
        np.maximum.accumulate(keep, out=keep)  # previous long run
        first_long = int(np.argmax(~short))
        keep[keep < 0] = first_long
        out = np.repeat(run_code[keep], ends - starts)
    return out


def _drop_following(
    states: dict[str, npt.NDArray[np.int8]], rates: Mapping[str, Floats], dt: float
) -> None:
    """Zero the driver states that only follow a swept slip (in place).

    Where both slips move, a slip whose change over that stretch is less than
    ``FOLLOW_SHARE`` of the other's (in units of ``SLIP_SCALE``) follows it (a TTC cornering
    run's slip ratio wanders with the slip angle); two slips swept together (a warm-up's
    sines) both stay. A condition moving while a slip is swept follows the forces (rig
    compliance, load control).
    """
    if all(k in states for k in SLIPS):
        both = ((states["kappa"] != 0) & (states["alpha"] != 0)).astype(np.int8)
        starts, ends = _runs(both)
        for s, e in zip(starts, ends, strict=True):
            if not both[s]:
                continue
            change = {k: abs(float(np.sum(rates[k][s:e]))) * dt / SLIP_SCALE[k] for k in SLIPS}
            for k, other in (("kappa", "alpha"), ("alpha", "kappa")):
                if change[k] < FOLLOW_SHARE * change[other]:
                    states[k][s:e] = 0
    swept = np.zeros(len(next(iter(states.values()))), dtype=bool)
    for k in SLIPS:
        if k in states:
            swept |= states[k] != 0
    for k in states:
        if k not in SLIPS:
            states[k] = np.where(swept, 0, states[k]).astype(np.int8)


def _combine(states: Mapping[str, npt.NDArray[np.int8]], names: Sequence[str], n: int) -> Ints:
    """One code per sample of the directions of ``names`` (base 3)."""
    code = np.zeros(n, dtype=np.int64)
    for k in names:
        code = code * 3 + (states[k].astype(np.int64) + 1)
    return code


def _level_gap(k: str, x: Floats) -> float:
    """The smallest step between two levels of channel ``k`` (``LEVEL_GAP``) [unit]."""
    gap_abs, gap_rel = LEVEL_GAP[k]
    return max(gap_abs, gap_rel * float(np.median(np.abs(x)))) if len(x) else gap_abs


def _set_point_moves(state: npt.NDArray[np.int8], xs: Floats, gap: float) -> npt.NDArray[np.int8]:
    """``state`` without the moves of the smoothed channel ``xs`` smaller than ``gap``: a
    condition changes when it goes to another level, anything less is noise or drift."""
    out = state.copy()
    starts, ends = _runs(state)
    for s, e in zip(starts, ends, strict=True):
        if state[s] != 0 and abs(float(xs[e - 1] - xs[s])) < gap:
            out[s:e] = 0
    return out


def _absorb_within(code: npt.NDArray[np.integer], min_len: int) -> Ints:
    """``_absorb_short_runs`` inside one stretch; a stretch made only of short runs takes its
    most frequent code."""
    out = _absorb_short_runs(code, min_len)
    starts, ends = _runs(out)
    if len(starts) > 1 and np.all(ends - starts < min_len):
        values, counts = np.unique(out, return_counts=True)
        out = np.full(len(out), values[int(np.argmax(counts))], dtype=np.int64)
    return out


def split_segments(
    series: WheelSeries,
    *,
    window_s: float = 0.2,
    min_duration_s: float = 0.5,
    gap_factor: float = 5.0,
) -> list[Segment]:
    """Cut one wheel's samples into labelled segments, in time order.

    Parameters
    ----------
    series : WheelSeries
        Aligned samples of one wheel.
    window_s : float
        Smoothing window [s] for the driver channels.
    min_duration_s : float
        Shortest segment [s]; shorter runs join their neighbour.
    gap_factor : float
        A time step larger than ``gap_factor`` times the median step is a gap.

    Returns
    -------
    list of Segment
        Contiguous, non-overlapping, covering every sample once, increasing in time; each with
        its sweep number and the condition levels of its held channels.
    """
    n = len(series)
    if n == 0:
        return []
    t = np.asarray(series.t, dtype=np.float64)
    if n < 3:
        return [Segment(np.arange(n), "steady", {})]
    dts = np.diff(t)
    dt = float(np.median(dts[dts > 0])) if np.any(dts > 0) else 1.0
    grid = _Grid(t, max(3, round(window_s / dt) | 1), max(3, round(min_duration_s / dt)), dt)
    breaks = np.zeros(n, dtype=np.int64)
    breaks[1:] = dts > gap_factor * dt

    names = [k for k in DRIVERS if getattr(series, k, None) is not None]
    states, rates = {}, {}
    for k in names:
        states[k], rates[k] = _direction_state(
            getattr(series, k), grid, DRIVERS[k], max(3, grid.min_len // 3)
        )
    _drop_following(states, rates, dt)
    slips = [k for k in names if k in SLIPS]
    conditions = [k for k in names if k not in SLIPS]
    # Slip sweeps first; then, inside each stretch where the slips are held, the condition
    # changes (a flicker of one condition must not cut a load change into short pieces that
    # the neighbouring sweeps would swallow).
    slip_code = _absorb_short_runs(_combine(states, slips, n), grid.min_len)
    held = _combine({k: np.zeros(1, dtype=np.int8) for k in slips}, slips, 1)[0]
    starts, ends = _runs(slip_code)
    for k in conditions:
        cond = np.zeros(n, dtype=np.int8)
        xs = _moving_mean(_fill_nan(getattr(series, k)), grid.w)
        gap = _level_gap(k, xs)
        for s, e in zip(starts, ends, strict=True):
            if slip_code[s] == held:
                moves = _set_point_moves(states[k][s:e], xs[s:e], gap)
                cond[s:e] = _absorb_within(moves, grid.min_len)
        states[k] = cond
    cond_code = _combine(states, conditions, n)
    for s, e in zip(starts, ends, strict=True):  # two changes back to back: no sliver between
        cond_code[s:e] = _absorb_within(cond_code[s:e], grid.min_len)
    code = slip_code * 3 ** len(conditions) + cond_code
    # Never one segment across a gap in the time stamps.
    code = code + np.cumsum(breaks) * 3 ** (len(names) + 1)

    starts, ends = _runs(code)
    raw = [
        _segment(series, states, names, int(s), int(e)) for s, e in zip(starts, ends, strict=True)
    ]
    return _with_conditions(series, _with_sweeps(series, raw, breaks, grid.min_len))


def _segment(
    series: WheelSeries,
    states: Mapping[str, npt.NDArray[np.int8]],
    names: Sequence[str],
    s: int,
    e: int,
) -> Segment:
    """The segment of samples s..e-1: its drivers' majority direction and its kind."""
    direction = {}
    for k in names:
        m = float(np.mean(states[k][s:e]))
        if abs(m) > 0.5:
            direction[k] = 1 if m > 0 else -1
    if direction:
        kind = "ramp"
    elif (
        np.median(np.abs(_fill_nan(series.kappa[s:e]))) < PAUSE_KAPPA
        and np.median(np.abs(_fill_nan(series.alpha[s:e]))) < PAUSE_ALPHA_RAD
    ):
        kind = "pause"
    else:
        kind = "steady"
    return Segment(np.arange(s, e), kind, direction)


def _split_at_zero(seg: Segment, x: Floats, min_len: int) -> tuple[Segment, Segment] | None:
    """The halves of a ramp that runs from one extreme of its slip through zero to the other
    (the end of one sweep merged with the start of the next, back to back), cut where it
    crosses zero; None for any other ramp, or if a half would be shorter than ``min_len``."""
    xs = _moving_mean(_fill_nan(x[seg.index]), 5)
    a, b = float(xs[0]), float(xs[-1])
    if a * b >= 0 or min(abs(a), abs(b)) < 0.5 * max(abs(a), abs(b)):
        return None
    cut = int(np.argmax(np.sign(xs) != np.sign(a)))
    if cut < min_len or cut > len(xs) - min_len:
        return None
    return replace(seg, index=seg.index[:cut]), replace(seg, index=seg.index[cut:])


def _with_sweeps(
    series: WheelSeries, segments: Sequence[Segment], breaks: Ints, min_len: int
) -> list[Segment]:
    """Number the sweeps: consecutive ramps of the same slip channel(s), at most
    ``MAX_RAMPS_PER_SWEEP`` (0 -> +A -> -A -> 0). A steady hold between two of its ramps (at a
    turning point) stays inside the sweep; a pause, a condition change or a gap in the stamps
    ends it. The last ramp of a sweep that runs on to the other extreme is the start of the
    next sweep too (no pause between them): it is cut at zero slip."""
    out: list[Segment] = []
    n_sweeps, current, ramps = 0, -1, 0
    slips: tuple[str, ...] = ()
    pending: list[int] = []  # steady holds (in ``out``) that join the sweep if it goes on
    for seg in segments:
        if breaks[seg.index[0]]:
            current, pending = -1, []
        if seg.kind == "ramp" and seg.slips:
            halves = None
            if current >= 0 and seg.slips == slips and ramps >= MAX_RAMPS_PER_SWEEP - 1:
                halves = _split_at_zero(seg, getattr(series, slips[0]), min_len)
            if halves is not None:
                out.append(replace(halves[0], sweep=current))
                seg = halves[1]
            if (
                halves is not None
                or current < 0
                or seg.slips != slips
                or ramps >= MAX_RAMPS_PER_SWEEP
            ):
                current, ramps, slips, pending = n_sweeps, 0, seg.slips, []
                n_sweeps += 1
            for j in pending:
                out[j] = replace(out[j], sweep=current)
            out.append(replace(seg, sweep=current))
            ramps, pending = ramps + 1, []
        elif seg.kind == "steady" and current >= 0:
            pending.append(len(out))
            out.append(seg)
        else:
            current, pending = -1, []
            out.append(seg)
    return out


def _levels(medians: Floats, weights: Floats, gap: float) -> Floats:
    """Centres of the clusters of ``medians`` (weighted means) split where sorted neighbours
    are more than ``gap`` apart."""
    order = np.argsort(medians)
    v, wt = medians[order], weights[order]
    cut = np.flatnonzero(np.diff(v) > gap) + 1
    return np.array(
        [
            float(np.average(a, weights=b))
            for a, b in zip(np.split(v, cut), np.split(wt, cut), strict=True)
        ]
    )


def _with_conditions(series: WheelSeries, segments: Sequence[Segment]) -> list[Segment]:
    """Attach to every segment the level of each channel it holds (clustered over the wheel)."""
    levels: dict[str, Floats] = {}
    medians: dict[str, Floats] = {}
    for k in LEVEL_GAP:
        x = getattr(series, k, None)
        if x is None:
            continue
        med = np.array(
            [
                np.nanmedian(x[g.index]) if np.isfinite(x[g.index]).any() else np.nan
                for g in segments
            ]
        )
        held = np.array([k not in g.direction for g in segments]) & np.isfinite(med)
        if not held.any():
            continue
        weights = np.array([len(g.index) for g in segments], dtype=np.float64)
        levels[k] = _levels(med[held], weights[held], _level_gap(k, med[held]))
        medians[k] = med
    out = []
    for i, g in enumerate(segments):
        cond = {}
        for k, lv in levels.items():
            m = medians[k][i]
            if k not in g.direction and np.isfinite(m):
                cond[k] = float(lv[int(np.argmin(np.abs(lv - m)))])
        out.append(replace(g, condition=cond))
    return out


def split_sweeps(series: WheelSeries, **kwargs: float) -> list[npt.NDArray[np.intp]]:
    """Index arrays, one per sweep/segment, in time order (see :func:`split_segments`).

    Every sample belongs to exactly one array; each array is contiguous and increasing.
    """
    return [seg.index for seg in split_segments(series, **kwargs)]


def holdout_mask(
    segments: Sequence[Segment],
    n: int,
    condition_keys: Sequence[object] | None = None,
    every: int = 4,
    offset: int = 1,
) -> npt.NDArray[np.bool_]:
    """Boolean mask of held-out samples: every ``every``-th ramp per condition.

    Ramps are counted separately for each condition key (e.g. load/pressure level), so each
    condition keeps sweeps on both sides. Pauses and steady parts are never held out; with
    ``every`` < 2 nothing is held out.
    """
    mask = np.zeros(n, dtype=bool)
    if every < 2:
        return mask
    counts: dict[object, int] = {}
    for i, seg in enumerate(segments):
        if seg.kind != "ramp":
            continue
        key = condition_keys[i] if condition_keys is not None else None
        c = counts.get(key, 0)
        counts[key] = c + 1
        if c % every == offset % every:
            mask[seg.index] = True
    return mask
