"""Split a recording into sweeps: the unit of validation for autocorrelated rig data.

Samples recorded at 100 Hz and more are strongly autocorrelated, so a random choice of
validation rows measures interpolation, not prediction. Validation and significance must work
on whole sweeps. :func:`split_sweeps` cuts a wheel's samples, in time order, into contiguous
segments of one kind each:

- a monotone ramp of a driver channel (slip ratio, slip angle, load, camber, pressure),
- a steady part (drivers held, slip away from zero),
- a pause (drivers held, slip near zero),

with a break wherever the time stamps jump (a gap in the recording). The cut is robust to
sensor noise: drivers are smoothed over a window of about 0.2 s, a channel counts as moving only
when its smoothed rate exceeds both a noise-derived and a range-derived threshold, and runs
shorter than ``min_duration_s`` are absorbed by their neighbours (a brief hold at the turning
point of a sweep does not become a segment of its own).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from tire_model_ros.recording.series import WheelSeries

# Channels whose motion defines a sweep, with the smallest range [unit] that counts as "moving"
# at all (a channel that stays within this band is treated as held constant).
DRIVERS: dict[str, float] = {
    "kappa": 2e-3,  # slip ratio [-]
    "alpha": np.deg2rad(0.2),  # slip angle [rad]
    "Fz": 50.0,  # load [N]
    "gamma": np.deg2rad(0.2),  # inclination [rad]
    "p": 3000.0,  # gauge pressure [Pa]
}
# Slip channels: a held segment with both near zero is a pause.
PAUSE_KAPPA = 5e-3
PAUSE_ALPHA_RAD = np.deg2rad(0.3)


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
    """

    index: np.ndarray
    kind: str
    direction: dict[str, int]

    @property
    def label(self) -> str:
        """Short text such as ``"ramp alpha+"`` or ``"pause"``."""
        if self.kind != "ramp":
            return self.kind
        moves = " ".join(f"{k}{'+' if s > 0 else '-'}" for k, s in self.direction.items())
        return f"ramp {moves}"


def _moving_mean(x: np.ndarray, w: int) -> np.ndarray:
    """Centred moving average of odd length ``w`` (edges use the available samples)."""
    if w <= 1 or len(x) < 3:
        return x.copy()
    c = np.concatenate(([0.0], np.cumsum(x)))
    n = len(x)
    half = w // 2
    lo = np.clip(np.arange(n) - half, 0, n)
    hi = np.clip(np.arange(n) + half + 1, 0, n)
    mean: npt.NDArray[np.float64] = (c[hi] - c[lo]) / (hi - lo)
    return mean


def noise_sigma(y: np.ndarray) -> float:
    """Robust white-noise level of a sampled signal: MAD of its second differences / sqrt(6).

    Smooth force curves and slip ramps nearly cancel in second differences at rig sample
    rates, the noise does not. NaN samples are skipped; fewer than 5 samples give 0.
    """
    y = np.asarray(y, dtype=np.float64)
    y = y[np.isfinite(y)]
    if len(y) < 5:
        return 0.0
    d2 = np.diff(y, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


def _fill_nan(x: np.ndarray) -> np.ndarray:
    """Carry the last finite value forward (and the first one backward); all-NaN -> zeros."""
    x = np.asarray(x, dtype=np.float64)
    ok = np.isfinite(x)
    if ok.all():
        return x
    if not ok.any():
        return np.zeros_like(x)
    idx = np.where(ok, np.arange(len(x)), 0)
    np.maximum.accumulate(idx, out=idx)
    first = int(np.argmax(ok))
    idx[:first] = first
    return x[idx]


def _direction_state(
    x: np.ndarray, t: np.ndarray, w: int, min_range: float, dt: float, min_len: int
) -> np.ndarray:
    """Per-sample direction of channel ``x``: +1 rising, -1 falling, 0 held."""
    x = _fill_nan(x)
    lo, hi = np.percentile(x, [1.0, 99.0])
    span = hi - lo
    if span < min_range:
        return np.zeros(len(x), dtype=np.int8)
    xs = _moving_mean(x, w)
    # Rate over one window: difference of two independent window means, so its noise is
    # sigma*sqrt(2/w)/(w*dt) for white noise of level sigma.
    n, h = len(x), w // 2
    i = np.arange(n)
    lo, hi = np.clip(i - h, 0, n - 1), np.clip(i + h, 0, n - 1)
    dt_win = np.maximum(t[hi] - t[lo], dt)
    rate = (xs[hi] - xs[lo]) / dt_win
    sigma_rate = noise_sigma(x) * np.sqrt(2.0 / w) / (w * dt)
    thr = max(6.0 * sigma_rate, 0.01 * span)  # 1 % of the range per second counts as held
    state = np.zeros(len(x), dtype=np.int8)
    state[rate > thr] = 1
    state[rate < -thr] = -1
    # Remove isolated flickers of this channel before it is combined with the others.
    return _absorb_short_runs(state, min_len).astype(np.int8)


def _runs(code: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) indices of runs of equal values."""
    if len(code) == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    change = np.flatnonzero(code[1:] != code[:-1]) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [len(code)]))
    return starts, ends


def _absorb_short_runs(code: np.ndarray, min_len: int) -> np.ndarray:
    """Give runs shorter than ``min_len`` the code of the preceding long run (else the next)."""
    code = code.copy()
    for _ in range(3):  # a few passes settle chains of short runs
        starts, ends = _runs(code)
        short = (ends - starts) < min_len
        if not short.any() or short.all():
            break
        run_code = code[starts].astype(np.int64)
        keep = np.where(~short, np.arange(len(starts)), -1)
        np.maximum.accumulate(keep, out=keep)  # previous long run
        first_long = int(np.argmax(~short))
        keep[keep < 0] = first_long
        new = run_code[keep]
        code = np.repeat(new, ends - starts).astype(code.dtype)
    return code


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
        Contiguous, non-overlapping, covering every sample once, increasing in time.
    """
    n = len(series)
    if n == 0:
        return []
    t = np.asarray(series.t, dtype=np.float64)
    if n < 3:
        return [Segment(np.arange(n), "steady", {})]
    dts = np.diff(t)
    dt = float(np.median(dts[dts > 0])) if np.any(dts > 0) else 1.0
    w = max(3, round(window_s / dt) | 1)
    min_len = max(3, round(min_duration_s / dt))
    breaks = np.zeros(n, dtype=np.int64)
    breaks[1:] = dts > gap_factor * dt

    names = [k for k in DRIVERS if getattr(series, k, None) is not None]
    states = {
        k: _direction_state(getattr(series, k), t, w, DRIVERS[k], dt, max(3, min_len // 3))
        for k in names
    }
    code = np.zeros(n, dtype=np.int64)
    for k in names:
        code = code * 3 + (states[k].astype(np.int64) + 1)
    code = _absorb_short_runs(code, min_len)
    # Never one segment across a gap in the time stamps.
    code = code + np.cumsum(breaks) * 3 ** (len(names) + 1)

    kappa = _fill_nan(series.kappa)
    alpha = _fill_nan(series.alpha)
    segments = []
    starts, ends = _runs(code)
    for s, e in zip(starts, ends, strict=True):
        idx = np.arange(s, e)
        direction = {}
        for k in names:
            # The segment's direction is the majority of its samples' states.
            m = float(np.mean(states[k][s:e]))
            if abs(m) > 0.5:
                direction[k] = 1 if m > 0 else -1
        if direction:
            kind = "ramp"
        elif (
            np.median(np.abs(kappa[s:e])) < PAUSE_KAPPA
            and np.median(np.abs(alpha[s:e])) < PAUSE_ALPHA_RAD
        ):
            kind = "pause"
        else:
            kind = "steady"
        segments.append(Segment(idx, kind, direction))
    return segments


def split_sweeps(series: WheelSeries, **kwargs: Any) -> list[np.ndarray]:
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
) -> np.ndarray:
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
