"""What is in a recording: topics, wheels, duration, rates and channel ranges (JSON-ready)."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from tire_model_ros.recording import cdr
from tire_model_ros.recording.errors import RecordingError
from tire_model_ros.recording.read import RawBag, find_wheels, read_raw, wheels_from_raw
from tire_model_ros.vocabulary import CHANNEL_TYPES, NS_PER_S, SERIES_UNITS


def _rate_hz(stamps_ns: np.ndarray) -> float | None:
    """Mean message rate [Hz] from header stamps; None for fewer than two distinct stamps."""
    if len(stamps_ns) < 2 or stamps_ns[-1] == stamps_ns[0]:
        return None
    return float((len(stamps_ns) - 1) * NS_PER_S / (stamps_ns[-1] - stamps_ns[0]))


def _range(values: np.ndarray | None) -> list[float] | None:
    if values is None or len(values) == 0:
        return None
    finite = values[np.isfinite(values)]
    return [float(finite.min()), float(finite.max())] if len(finite) else None


def summarize(path: str | os.PathLike[str], *, salvage: bool = False) -> dict[str, Any]:
    """Summary of a bag; raises RecordingError when it cannot be read (``salvage``: see
    ``read_raw``).

    Topics of the known fixed-layout types get header-stamp ranges and rates; a bag without a
    complete wheel still gets its topic list, with ``wheels_error`` saying what is missing.
    """
    return summarize_raw(read_raw(path, salvage=salvage))


def summarize_raw(bag: RawBag) -> dict[str, Any]:
    """``summarize`` of a bag already read with every topic selected."""
    topics = {}
    first, last = [], []
    for name, (msgtype, announced) in sorted(bag.all_topics.items()):
        raw = bag.topics.get(name)
        entry: dict[str, Any] = {"type": msgtype, "count": len(raw) if raw is not None else 0}
        if announced != entry["count"]:
            entry["count_announced"] = announced
        if raw is not None and len(raw):
            log = raw.log_ns
            stamps = None
            little_endian = np.all(raw.lens >= 16) and np.all(raw.buf[raw.starts + 1] == 1)
            if msgtype in cdr.LAYOUTS and little_endian:
                stamps = np.sort(cdr.header_stamps(raw.buf, raw.starts))
            times = stamps if stamps is not None else np.sort(log)
            first.append(times[0])
            last.append(times[-1])
            entry["first_s"] = times[0] / NS_PER_S
            entry["last_s"] = times[-1] / NS_PER_S
            entry["rate_hz"] = _rate_hz(times)
            entry["time_source"] = "header.stamp" if stamps is not None else "log time"
        topics[name] = entry
    out: dict[str, Any] = {
        "path": str(bag.path),
        "storage": bag.storage,
        "messages": bag.messages_read,
        "messages_announced": bag.message_count,
        "reader_fallback": bag.fallback,
        "damages": [d.describe() for d in bag.damages],
        "start_s": min(first) / NS_PER_S if first else None,
        "end_s": max(last) / NS_PER_S if last else None,
        "duration_s": (max(last) - min(first)) / NS_PER_S if first else 0.0,
        "topics": topics,
        "wheels": {},
    }
    complete, partial = find_wheels(bag.all_topics)
    try:
        wheels = wheels_from_raw(bag) if complete else {}
    except RecordingError as exc:
        out["wheels_error"] = str(exc)
        wheels = {}
    if not complete:
        out["wheels_error"] = "no wheel (a wheel needs P/slip, P/load and P/measured_forces)" + (
            ": " + "; ".join(f"{p} lacks {', '.join(m)}" for p, m in partial.items())
            if partial
            else ""
        )
    for prefix, w in wheels.items():
        meta = w.meta
        out["wheels"][prefix] = {
            "samples": len(w),
            "duration_s": float(w.t[-1] - w.t[0]) if len(w) else 0.0,
            "rate_hz": _rate_hz(meta["t_ns"]),
            "channels": {
                name: {"unit": unit, "range": _range(getattr(w, name))}
                for name, unit in SERIES_UNITS.items()
                if getattr(w, name) is not None
            },
            "absent": [name for name in ("p", "T", "Vx") if getattr(w, name) is None],
            "dropped_no_load": meta["dropped_no_load"],
            "backfilled": meta["backfilled"],
            "forces_exact": meta["forces_exact"],
            "forces_max_dt_s": meta["forces_max_dt_s"],
            "topics": sorted(
                t
                for t in topics
                if t.rpartition("/")[0] == prefix and t.rpartition("/")[2] in CHANNEL_TYPES
            ),
        }
    return out


def _fmt(x: float | None, spec: str = ".6g") -> str:
    return "-" if x is None else format(x, spec)


def format_summary(info: dict[str, Any]) -> str:
    """Human-readable text of ``summarize``'s result."""
    lines = [
        f"bag:       {info['path']} ({info['storage']})",
        f"messages:  {info['messages']}"
        + (
            f" (metadata says {info['messages_announced']})"
            if info["messages"] != info["messages_announced"]
            else ""
        ),
        f"duration:  {_fmt(info['duration_s'], '.3f')} s  (start {_fmt(info['start_s'], '.9f')} s)",
        "topics:",
    ]
    if info["damages"]:
        lines[2:2] = [f"damage:    {d}" for d in info["damages"]]
    width = max((len(t) for t in info["topics"]), default=0)
    for name, t in info["topics"].items():
        lines.append(
            f"  {name:<{width}}  {t['type']:<34} {t['count']:>8}  "
            f"{_fmt(t.get('rate_hz'), '.1f'):>8} Hz"
        )
    lines.append("wheels:" + ("" if info["wheels"] else "    none"))
    if "wheels_error" in info:
        lines.append(f"  ({info['wheels_error']})")
    for prefix, w in info["wheels"].items():
        lines.append(
            f"  {prefix}: {w['samples']} samples, {_fmt(w['duration_s'], '.3f')} s, "
            f"{_fmt(w['rate_hz'], '.1f')} Hz"
        )
        for name, c in w["channels"].items():
            lo, hi = c["range"] if c["range"] else (None, None)
            lines.append(f"    {name:<8} [{c['unit']:>4}]  min {_fmt(lo):>12}  max {_fmt(hi):>12}")
        if w["absent"]:
            lines.append(f"    not recorded: {', '.join(w['absent'])}")
        notes = []
        if w["dropped_no_load"]:
            notes.append(f"{w['dropped_no_load']} leading samples dropped (no load yet)")
        for name, k in w["backfilled"].items():
            if k:
                notes.append(f"{k} leading samples of {name} take its first value")
        if w["forces_exact"] != w["samples"]:
            notes.append(
                f"measured_forces: {w['samples'] - w['forces_exact']} samples matched to the "
                f"nearest stamp (max {w['forces_max_dt_s'] * 1e3:.3f} ms)"
            )
        lines.extend(f"    note: {n}" for n in notes)
    return "\n".join(lines)
