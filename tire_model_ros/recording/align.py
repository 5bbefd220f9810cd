"""The one alignment rule of INTERFACE.md, on header-stamp arrays (no bag types, no ROS).

"Samples are aligned on the slip messages by header.stamp: every other channel is taken as its
latest value at or before that stamp; measured_forces: same stamp, else the nearest." The
offline reader applies it to whole recordings (:func:`align_wheel`); the node applies the same
function, :func:`latest_at_or_before`, to a short history of each input for every slip message
(:mod:`tire_model_ros.wheel.history`), so the node and the offline tool pair the same messages.
Decisions this module takes on top of the rule:

- Samples are the slip messages sorted by header stamp (equal stamps keep the given order).
- ``load`` missing before the first slip: those leading samples are dropped
  (``meta["dropped_no_load"]`` counts them).
- An optional channel that starts after the first slip: the leading samples take its FIRST
  value (a zero-order hold backwards; ``meta["backfilled"][attribute]`` counts them).
  Pressure, temperature and speed move slowly and are often logged at a low rate (1-10 Hz);
  dropping samples until the slowest channel's first message would throw away good force data.
- An optional channel without messages is ``None``.
- ``measured_forces``: the message with the same stamp, else the nearest one (ties: the
  earlier). ``meta["forces_exact"]`` counts exact matches, ``meta["forces_max_dt_s"]`` is the
  largest stamp distance used [s].
- ``meta["t_ns"]``: the exact integer slip stamps [ns].
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, overload

import numpy as np
import numpy.typing as npt

from tire_model_ros.recording.series import WheelSeries
from tire_model_ros.vocabulary import (
    NS_PER_S,
    OPTIONAL_SERIES,
    REQUIRED_CHANNELS,
    WRENCH_SERIES,
)

Stamps = npt.NDArray[np.int64]
Indices = npt.NDArray[np.intp]
#: One channel's messages sorted by header stamp: (stamp [ns] (n,), values (n, k)).
Stamped = tuple[Stamps, npt.NDArray[np.float64]]


@overload
def latest_at_or_before(stamps: Stamps, t: Stamps) -> Indices: ...
@overload
def latest_at_or_before(stamps: Stamps, t: np.int64) -> np.intp: ...
def latest_at_or_before(stamps: Stamps, t: Stamps | np.int64) -> Indices | np.intp:
    """Index of the last of ``stamps`` (sorted) that is <= each ``t``; -1 where none.

    THE alignment rule of INTERFACE.md ("the latest value whose header.stamp is at or before
    the slip's stamp"), for the offline reader (arrays of slip stamps) and the node (one slip
    stamp against an input's history). Of equal stamps, the last one.
    """
    return np.searchsorted(stamps, t, side="right") - 1


def nearest(stamps: Stamps, t: Stamps) -> Indices:
    """Index of the entry of ``stamps`` (sorted, non-empty) nearest to each ``t``.

    An exact match wins; of two at the same distance, the earlier one.
    """
    j = np.searchsorted(stamps, t, side="left")
    after = np.minimum(j, len(stamps) - 1)
    before = np.maximum(j - 1, 0)
    take_after = np.abs(stamps[after] - t) < np.abs(t - stamps[before])
    return np.where(take_after, after, before)


def hold_latest(stamps: Stamps, t: Stamps) -> tuple[Indices, int]:
    """Latest entry at or before each ``t``, the first entry before it (a backwards hold).

    Returns the indices into ``stamps`` (sorted, non-empty) and how many ``t`` were held
    backwards.
    """
    i = latest_at_or_before(stamps, t)
    return np.maximum(i, 0), int((i < 0).sum())


def align_wheel(prefix: str, channels: Mapping[str, Stamped]) -> WheelSeries:
    """One wheel's samples on its slip stamps (module docstring: the rules).

    Parameters
    ----------
    prefix : the wheel's topic namespace, e.g. ``/rig/wheel``.
    channels : channel name (``slip``, ``load``, ``measured_forces`` and any of ``pressure``,
        ``temperature``, ``velocity``) -> its messages sorted by stamp: slip values are
        (κ, α [rad], γ [rad]), load and measured_forces the six WrenchStamped values [N, N m],
        the optional ones their value first.

    Raises
    ------
    ValueError
        A required channel without messages, or no slip at or after the first load; the message
        names the topic.
    """
    for c in REQUIRED_CHANNELS:
        if c not in channels or len(channels[c][0]) == 0:
            raise ValueError(f"wheel {prefix}: topic {prefix}/{c} has no messages")
    slip_ns, slip = channels["slip"]
    i_load = latest_at_or_before(channels["load"][0], slip_ns)
    keep = i_load >= 0  # slip is sorted, so the dropped samples are the leading ones
    if not keep.any():
        raise ValueError(
            f"wheel {prefix}: no {prefix}/slip message at or after the first {prefix}/load message"
        )
    t_ns = slip_ns[keep]
    kw: dict[str, Any] = {
        "prefix": prefix,
        "t": t_ns / NS_PER_S,
        "kappa": slip[keep, 0],
        "alpha": slip[keep, 1],
        "gamma": slip[keep, 2],
        "Fz": channels["load"][1][i_load[keep], 2],
    }
    backfilled = {}
    for channel, name in OPTIONAL_SERIES.items():
        if channel in channels and len(channels[channel][0]):
            stamps, values = channels[channel]
            i, backfilled[name] = hold_latest(stamps, t_ns)
            kw[name] = values[i, 0]
    mf_ns, mf = channels["measured_forces"]
    j = nearest(mf_ns, t_ns)
    dt = np.abs(mf_ns[j] - t_ns)
    for k, name in enumerate(WRENCH_SERIES):
        kw[name] = mf[j, k]
    kw["meta"] = {
        "t_ns": t_ns,
        "n_slip": len(slip_ns),
        "dropped_no_load": int(len(keep) - keep.sum()),
        "backfilled": backfilled,
        "forces_exact": int((dt == 0).sum()),
        "forces_max_dt_s": float(dt.max() / NS_PER_S) if len(dt) else 0.0,
    }
    return WheelSeries(**kw)
