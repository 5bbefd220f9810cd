"""The node's /diagnostics statuses (rclpy message types; the rule itself is ROS-free).

Per wheel, per period (the counters' increase since the last report):

- ERROR: slip messages went unanswered and none was answered.
- WARN: slip messages unanswered (any reason of ``UNANSWERED``), inputs out of range in the
  period or still at the last slip (saturated with the limits on, used as they are with them
  off; ``out_of_range.temperature +0 (saturated, still)``), messages that could not be
  read or values rejected, inputs missing for a slip (stale, stamped after it, or a load never
  received), or an input topic subscribed again whose handover ended before every publisher
  was matched (``resubscribe_unmatched``; a lossless handover is counted, not a warning), or
  slips held for their inputs released without them: the wait bound passed, or an input it
  waited for stopped (``released_by_wait``), or the queue was full (``released_by_overflow``).
  Holding a slip until its inputs catch up (``held``, ``released_caught_up``) is normal.
- OK, message "ok": none of these: every output is the model on in-range inputs. Answers on
  inputs outside the envelope the model's fit covered (``outside_envelope``: in range, but
  extrapolated) are said after it: ``ok; outside_envelope +40 (beyond the fitted data)``.

The message lists what happened with its count (``out_of_range.temperature +12 (saturated)``);
the values carry every cumulative counter, the slips held now (``pending``), each input's
newest value and its age in stamp time (the last slip's stamp minus the value's), and the
effects' hidden states.
"""

from __future__ import annotations

from collections.abc import Mapping

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from tire_model_ros.delivery import UNANSWERED
from tire_model_ros.vocabulary import NODE_INPUTS
from tire_model_ros.wheel.state import WheelState

#: Counters whose increase is a warning by itself: a handover that may have lost messages,
#: slips computed before their inputs caught up (:mod:`tire_model_ros.wheel.hold`).
_WARNINGS = ("resubscribe_unmatched", "released_by_wait", "released_by_overflow")
#: Counters said in the message without a warning: the model answered as asked, but beyond
#: the data it was fitted to.
_NOTES = {"outside_envelope": "beyond the fitted data"}


def _is_warning(key: str) -> bool:
    if key.startswith("out_of_range.") or key.endswith((".malformed", ".rejected")):
        return True
    if key.startswith("fallback."):
        return not key.endswith(".never") or key == "fallback.load.never"
    return key in _WARNINGS


def level_and_message(
    delta: Mapping[str, int], limits: bool, outside: tuple[str, ...] = ()
) -> tuple[bytes, str, list[str], list[str]]:
    """(level, message, unanswered keys, warning keys) of one period's counter increases and
    the inputs still ``outside`` their range at the last slip (WARN while they stay there,
    even in a period without slips)."""
    lost = [k for k in UNANSWERED if delta.get(k)]
    warn = [k for k, d in delta.items() if d and _is_warning(k)]
    held = [f"out_of_range.{name}" for name in outside]
    warn += [k for k in held if k not in warn]
    if lost and not delta.get("forces_out"):
        level = DiagnosticStatus.ERROR
    elif lost or warn:
        level = DiagnosticStatus.WARN
    else:
        level = DiagnosticStatus.OK
    how = "saturated" if limits else "limits off: not saturated"
    parts = [
        f"{k} +{delta.get(k, 0)}"
        + (f" ({how}{', still' if k in held else ''})" if k.startswith("out_of_range.") else "")
        for k in lost + warn
    ]
    notes = [f"{k} +{delta[k]} ({why})" for k, why in _NOTES.items() if delta.get(k)]
    head = parts if parts else ["ok"]
    return level, "; ".join(head + notes), lost, warn


def wheel_status(
    name: str,
    w: WheelState,
    delta: Mapping[str, int],
    counts: Mapping[str, int],
    tir_path: str,
    limits: bool,
) -> DiagnosticStatus:
    """The status of one wheel for one period (module docstring)."""
    level, message, _, _ = level_and_message(delta, limits, w.outside)
    st = DiagnosticStatus(name=name, hardware_id=w.prefix, level=level, message=message)
    values = {"tir_file": tir_path, **{k: str(v) for k, v in counts.items()}}
    values["pending"] = str(w.hold.pending)  # a gauge, not a counter: no delta
    for inp in NODE_INPUTS:
        latest = w.inputs[inp].history.latest()
        age = w.input_age_s(inp)
        values[f"{inp}.value"] = "never received" if latest is None else repr(latest[0])
        values[f"{inp}.age_s"] = "" if age is None else f"{age:.3f}"
    if w.effects is not None:  # the hidden states, as an engineer would watch them
        values["effects.tread_C"] = f"{w.effects.temperature_C:.2f}"
        values.update({f"effects.{k}": f"{v:.4g}" for k, v in w.effects.y.items()})
    if w.last_error:
        values["last_model_error"] = w.last_error
    st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
    return st
