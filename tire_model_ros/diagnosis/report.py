"""The human side of a diagnosis: ``report.md`` plus PNG plots in one directory.

An engineer should get the finding in a minute: one sentence per effect (what, concealed or
not, where it sits, the evidence, the fitted parameters with their uncertainty), then the fit
table (RMSE / NRMSE before and after, on the fitted and the held-out sweeps), then the plots:

- ``residual_time_<wheel>.png``  measured - model over time, before and after, held-out shaded
- ``residual_slip_<wheel>.png``  the same residuals over slip (kappa for Fx, alpha for Fy, Mz)
- ``fit_<wheel>.png``            measured force over slip against the model before and after
- ``inferred_<wheel>.png``       a concealed state (e.g. the tyre temperature) over time, when the
                                 diagnosis inferred one

The directory is written atomically: everything goes into a hidden sibling temp directory that
is renamed into place at the end, so a reader never sees half a report. Clobber rule: a missing
or empty ``out_dir`` is (re)created; an existing non-empty one is refused with
``FileExistsError`` unless ``overwrite=True``, which replaces it as a whole (the old directory
is renamed aside first and removed only after the new one is in place).
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tire_model_ros.atomic import replace_path
from tire_model_ros.vocabulary import DIAGNOSED_CHANNELS, TOLD_APART_BY

# The channels the diagnosis compares, in report order; each is plotted over its own slip.
CHANNELS = DIAGNOSED_CHANNELS
SLIP_OF_CHANNEL: dict[str, tuple[str, str, float]] = {
    # channel -> (WheelSeries attribute, axis label, scale to the plotted unit)
    "Fx": ("kappa", "slip ratio κ [-]", 1.0),
    "Fy": ("alpha", "slip angle α [deg]", 180.0 / math.pi),
    "Mz": ("alpha", "slip angle α [deg]", 180.0 / math.pi),
}
UNIT_OF_CHANNEL = {"Fx": "N", "Fy": "N", "Mz": "N m"}
# Plot at most this many points per series: 100 Hz sessions run to tens of thousands of
# samples, and more points make a slower PNG, not a clearer one.
MAX_PLOT_POINTS = 6000
# What an inferred state is, for the axis label of the inferred plot.
INFERRED_LABELS = {
    "T": "inferred tyre temperature [°C]",
    "p": "inferred inflation pressure [kPa]",
    "wear": "inferred wear state [-]",
}
INFERRED_SCALE = {"p": 1e-3}  # Pa -> kPa for the plot


# --------------------------------------------------------------------------- small helpers


def _wheel_map(wheels: Any) -> dict[str, Any]:
    """``wheels`` as prefix -> WheelSeries (accepts that mapping or a sequence of series)."""
    if isinstance(wheels, Mapping):
        return dict(wheels)
    return {w.prefix: w for w in wheels}


def _slug(prefix: str) -> str:
    """A file-name-safe name for a wheel prefix: ``/rig/wheel`` -> ``rig_wheel``."""
    slug = re.sub(r"[^A-Za-z0-9]+", "_", prefix).strip("_")
    return slug or "wheel"


def fmt_num(x: float, sig: int = 3) -> str:
    """``x`` with ``sig`` significant digits, plain notation for ordinary magnitudes."""
    if x is None or not np.isfinite(x):
        return "n/a"
    if x == 0:
        return "0"
    mag = math.floor(math.log10(abs(x)))
    if -4 <= mag < 6:
        decimals = max(sig - 1 - mag, 0)
        return f"{x:.{decimals}f}"
    return f"{x:.{sig - 1}e}"


def fmt_param(name: str, value: float, sigma: float | None) -> str:
    """``NAME = value ± sigma`` with the value rounded to the precision its sigma supports."""
    if sigma is None or not np.isfinite(sigma) or sigma <= 0:
        return f"{name} = {fmt_num(value)}"
    # Two significant digits of sigma; the value to the same last decimal.
    mag = math.floor(math.log10(sigma))
    decimals = max(1 - mag, 0)
    if abs(value) >= 1e6 or (abs(value) < 1e-4 and value != 0) or decimals > 8:
        return f"{name} = {value:.3g} ± {sigma:.2g}"
    return f"{name} = {value:.{decimals}f} ± {sigma:.{decimals}f}"


def _get(obj: Any, key: str, default: Any = None) -> Any:
    """Attribute or mapping item ``key`` of ``obj``."""
    if isinstance(obj, Mapping):
        return obj.get(key, default)
    return getattr(obj, key, default)


def _metric(fit: Mapping[str, Any], block: str, channel: str, what: str) -> float:
    """``fit[block][channel][what]`` or NaN when the diagnosis did not report it."""
    try:
        return float(fit[block][channel][what])
    except (KeyError, TypeError, ValueError):
        return float("nan")


def _thin(n: int) -> np.ndarray:
    """Indices of at most MAX_PLOT_POINTS evenly spread samples out of ``n``."""
    if n <= MAX_PLOT_POINTS:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, MAX_PLOT_POINTS).astype(int))


# --------------------------------------------------------------------------- text


def effect_sentence(effect: Any) -> str:
    """One Markdown list item for one effect: a lead sentence, then where and evidence.

    The lead sentence says what (name, concealed or not, channel) and what was fitted (with
    one-sigma uncertainty); the indented lines below it carry the diagnosis' own words on where
    the mismatch sits and why this model of it was accepted.
    """
    name = _get(effect, "name", "?")
    where = (_get(effect, "where", "") or "").strip().rstrip(".")
    evidence = (_get(effect, "evidence", "") or "").strip().rstrip(".")
    if name == "none":
        lead = (
            "**none**: nothing significant is left; the model explains the recording to its noise."
        )
    else:
        concealed = bool(_get(effect, "concealed", False))
        channel = _get(effect, "channel", "") or "?"
        params = dict(_get(effect, "parameters", {}) or {})
        sigmas = dict(_get(effect, "uncertainty", {}) or {})
        state = "concealed: no channel for it in the recording" if concealed else "not concealed"
        fitted = ", ".join(fmt_param(k, float(v), sigmas.get(k)) for k, v in params.items())
        explained = _get(effect, "explained")
        share = (
            f"explains {float(explained):.0%} of the baseline's held-out mean square error "
            "of Fx and Fy; "
            if explained is not None and np.isfinite(explained)
            else ""
        )
        wheels = _get(effect, "wheels", []) or []
        on = f" on {', '.join(f'`{w}`' for w in wheels)}" if wheels else ""
        lead = f"**{name}** ({state}) in {channel}{on}; {share}" + (
            f"fitted {fitted} (± one sigma)." if fitted else "no parameters fitted."
        )
    lines = [lead]
    if where:
        lines.append(f"   - where: {where}.")
    if evidence:
        lines.append(f"   - evidence: {evidence}.")
    return "\n".join(lines)


def look_alike_summary(alike: Mapping[str, float]) -> str:
    """One line naming the look-alikes of a diagnosis ('' when there are none)."""
    if not alike:
        return ""
    listed = ", ".join(f"{w} ({share:.0%} alone)" for w, share in alike.items())
    return f"look-alikes (better than the baseline alone, not beside the named): {listed}"


def look_alike_lines(
    alike: Mapping[str, float] | Sequence[Mapping[str, Any]], named: Sequence[str] = ()
) -> list[str]:
    """The words this recording does not tell from the named effects (a diagnosis' dict, or
    its JSON list), as a paragraph, with what would tell each apart (of the look-alikes and of
    the ``named`` words, :data:`~tire_model_ros.vocabulary.TOLD_APART_BY`); none: no lines."""
    if isinstance(alike, Mapping):
        pairs = list(alike.items())
    else:
        pairs = [(str(_get(a, "name", "?")), _get(a, "explained_alone")) for a in alike]
    if not pairs:
        return []
    listed = ", ".join(
        f"`{w}` ({share:.0%} of the baseline's error alone)"
        if isinstance(share, (int, float)) and math.isfinite(share)
        else f"`{w}`"
        for w, share in pairs
    )
    lines = [
        "",
        f"Look-alikes: {listed}. Each predicted the held-out sweeps better than the baseline "
        "alone, but nothing beyond the effects above: this recording does not tell it from "
        "them. What would:",
        "",
    ]
    return lines + [f"- {line}" for line in told_apart([w for w, _ in pairs], named, "`")]


def told_apart(alike: Sequence[str], named: Sequence[str], quote: str = "") -> list[str]:
    """What in a programme would show each look-alike and each named word (one line each)."""
    words = [(w, "") for w in alike] + [(w, " (named)") for w in named if w not in alike]
    return [
        f"{quote}{w}{quote}{tag}: {TOLD_APART_BY[w]}." for w, tag in words if w in TOLD_APART_BY
    ]


def fit_table(fit: Mapping[str, Any]) -> list[str]:
    """The Markdown fit table: before/after on the fitted and on the held-out sweeps."""
    channels = [c for c in CHANNELS if c in (fit.get("baseline") or {})]
    channels += [c for c in (fit.get("baseline") or {}) if c not in channels]
    lines = [
        "| channel | fitted: RMSE before | NRMSE before | RMSE after | NRMSE after "
        "| held-out: RMSE before | RMSE after | held-out after/before |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for c in channels:
        hb = _metric(fit, "heldout_baseline", c, "rmse")
        hi = _metric(fit, "heldout_improved", c, "rmse")
        ratio = hi / hb if np.isfinite(hb) and hb > 0 and np.isfinite(hi) else float("nan")
        unit = UNIT_OF_CHANNEL.get(c, "")
        lines.append(
            f"| {c} [{unit}] | {fmt_num(_metric(fit, 'baseline', c, 'rmse'))} "
            f"| {fmt_num(_metric(fit, 'baseline', c, 'nrmse'))} "
            f"| {fmt_num(_metric(fit, 'improved', c, 'rmse'))} "
            f"| {fmt_num(_metric(fit, 'improved', c, 'nrmse'))} "
            f"| {fmt_num(hb)} | {fmt_num(hi)} | {fmt_num(ratio, 2)} |"
        )
    return lines


WORSE_HELDOUT = 1.05  # held-out RMSE after / before above which the report warns


def heldout_warnings(fit: Mapping[str, Any]) -> list[str]:
    """A sentence per channel the improved model predicts worse on the final held-out sweeps
    (which chose nothing): what the selection folds could not see, said, not hidden."""
    out = []
    for c in DIAGNOSED_CHANNELS:
        hb = _metric(fit, "heldout_baseline", c, "rmse")
        hi = _metric(fit, "heldout_improved", c, "rmse")
        if np.isfinite(hb) and np.isfinite(hi) and hi > WORSE_HELDOUT * hb:
            unit = UNIT_OF_CHANNEL.get(c, "")
            out.append(
                f"Warning: on the final held-out sweeps the improved model predicts {c} worse "
                f"({fmt_num(hb)} -> {fmt_num(hi)} {unit}): an effect above does not carry over "
                "to some conditions held out (e.g. a corner past those it was fitted on)."
            )
    return out


def summary_line(effects: Sequence[Any]) -> str:
    """The first line an engineer reads: what is missing from the model, strongest first."""
    named = [e for e in effects if _get(e, "name") != "none"]
    if not named:
        return (
            "**Finding: nothing significant is missing** — the model explains the recording "
            "to its noise."
        )
    words = []
    for e in named:
        word = f"`{_get(e, 'name')}`"
        if _get(e, "concealed", False):
            word += " (concealed)"
        words.append(word)
    return f"**Finding: the model misses {', '.join(words)}** (strongest first)."


def _markdown(
    diag: Any, wheels: dict[str, Any], plots: dict[str, list[tuple[str, str]]], source: str | None
) -> str:
    effects = list(_get(diag, "effects", []) or [])
    fit = _get(diag, "fit", {}) or {}
    lines = ["# Tyre model diagnosis", ""]
    if source:
        lines += [f"Recording: `{source}`", ""]
    lines += [summary_line(effects), ""]
    lines += ["## Effects", ""]
    lines += [f"{i}. {effect_sentence(e)}" for i, e in enumerate(effects, 1)] or ["(none listed)"]
    named = [str(_get(e, "name", "")) for e in effects]
    lines += look_alike_lines(_get(diag, "look_alikes", {}) or {}, named)
    per_wheel = _get(diag, "wheels", {}) or {}
    if len(per_wheel) > 1:  # a car: each wheel's own diagnosis under the summary
        lines += ["", "### Per wheel", ""]
        for prefix, wd in per_wheel.items():
            found = [e for e in _get(wd, "effects", []) if _get(e, "name") != "none"]
            lines.append(f"- `{prefix}`: {summary_line(found)}")
            lines += [f"   {i}. {effect_sentence(e)}" for i, e in enumerate(found, 1)]
    lines += ["", "## Fit", ""]
    lines += fit_table(fit)
    warnings = heldout_warnings(fit)
    lines += ["", *warnings] if warnings else []
    lines += [
        "",
        "RMSE in N (N m for Mz); NRMSE = RMSE / (max − min of the measured channel). "
        "*Before* is the given .tir model, *after* the model with the effects above. "
        "Held-out figures are on whole sweeps the fit did not see. "
        "The effects are chosen and fitted on Fx and Fy (on Mz only when no force was "
        "recorded). Each model's trail and residual-torque coefficients (QBZ, QCZ, QDZ, "
        "QEZ, QHZ) are then refitted to the measured Mz on the same training sweeps, its "
        "forces held: the .tir temperature terms have no aligning-moment term, so the effects "
        "reach Mz only through the forces.",
        "",
        "## Wheels",
        "",
    ]
    for prefix, series in wheels.items():
        t = np.asarray(series.t, dtype=float)
        dur = float(t[-1] - t[0]) if len(t) > 1 else 0.0
        recorded = [c for c in ("p", "T", "Vx") if getattr(series, c, None) is not None]
        held = _get(diag, "heldout_mask", {}) or {}
        n_held = int(np.count_nonzero(held[prefix])) if prefix in held else 0
        lines.append(
            f"- `{prefix}`: {len(t)} samples over {dur:.1f} s; optional channels recorded: "
            f"{', '.join(recorded) if recorded else 'none'}; held-out samples: {n_held}."
        )
    lines += ["", "## Plots", ""]
    for prefix, items in plots.items():
        for fname, caption in items:
            lines += [f"**{prefix}** — {caption}", "", f"![{caption}]({fname})", ""]
    return "\n".join(lines).rstrip() + "\n"


# --------------------------------------------------------------------------- plots


def _measured(series: Any, channel: str) -> np.ndarray | None:
    value = getattr(series, channel, None)
    return None if value is None else np.asarray(value, dtype=float)


def _plotted_channels(preds: Mapping[str, np.ndarray], series: Any) -> list[str]:
    """Channels with a measurement and both predictions, in report order."""
    n = len(series.t)
    out = []
    for c in CHANNELS:
        meas = _measured(series, c)
        b, i = preds.get(f"baseline_{c}"), preds.get(f"improved_{c}")
        if meas is None or b is None or i is None:
            continue
        if len(b) != n or len(i) != n:
            continue
        out.append(c)
    return out


def _shade_heldout(ax: Any, t: np.ndarray, mask: np.ndarray | None) -> None:
    """Grey spans where the samples are held out (not seen by the fit)."""
    if mask is None or len(mask) != len(t) or not np.any(mask):
        return
    m = np.asarray(mask, dtype=bool).astype(np.int8)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], m, [0]))))
    for k, (a, b) in enumerate(zip(edges[::2], edges[1::2], strict=True)):
        ax.axvspan(t[a], t[b - 1], color="0.85", zorder=0, label="held out" if k == 0 else None)


def _plot_wheel(plt: Any, tmp: Path, diag: Any, prefix: str, series: Any) -> list[tuple[str, str]]:
    preds = (_get(diag, "predictions", {}) or {}).get(prefix, {})
    channels = _plotted_channels(preds, series)
    slug = _slug(prefix)
    t = np.asarray(series.t, dtype=float)
    t = t - t[0] if len(t) else t
    held = (_get(diag, "heldout_mask", {}) or {}).get(prefix)
    idx = _thin(len(t))
    made: list[tuple[str, str]] = []
    if channels:
        made.append(_plot_residual_time(plt, tmp, slug, t, idx, held, series, preds, channels))
        made.append(_plot_residual_slip(plt, tmp, slug, idx, series, preds, channels))
        made.append(_plot_fit(plt, tmp, slug, idx, series, preds, channels, diag, prefix))
    inferred = (_get(diag, "inferred", {}) or {}).get(prefix, {}) or {}
    # Only physical states (temperature, pressure, wear) are plotted; drivers such as the
    # cumulative frictional work are intermediate quantities, not findings.
    inferred = {
        k: np.asarray(v, dtype=float)
        for k, v in inferred.items()
        if k in INFERRED_LABELS and v is not None and np.ndim(v) == 1 and len(v) == len(t)
    }
    if inferred:
        made.append(_plot_inferred(plt, tmp, slug, t, idx, series, inferred))
    return made


def _plot_residual_time(
    plt: Any,
    tmp: Path,
    slug: str,
    t: npt.NDArray[np.float64],
    idx: npt.NDArray[np.int64],
    held: np.ndarray | None,
    series: Any,
    preds: Mapping[str, npt.NDArray[np.float64]],
    channels: list[str],
) -> tuple[str, str]:
    fig, axes = plt.subplots(
        len(channels), 1, figsize=(10, 2.6 * len(channels) + 0.6), sharex=True, squeeze=False
    )
    for ax, c in zip(axes[:, 0], channels, strict=True):
        meas = _measured(series, c)
        assert meas is not None  # _plotted_channels: only measured channels
        _shade_heldout(ax, t, held)
        ax.plot(
            t[idx],
            (meas - preds[f"baseline_{c}"])[idx],
            lw=0.6,
            color="tab:red",
            label="before (given .tir)",
        )
        ax.plot(
            t[idx],
            (meas - preds[f"improved_{c}"])[idx],
            lw=0.6,
            color="tab:blue",
            label="after (with effects)",
        )
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(f"{c} residual [{UNIT_OF_CHANNEL[c]}]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=8, ncol=3)
    axes[0, 0].set_title("Residual measured − model over time")
    axes[-1, 0].set_xlabel("time from start [s]")
    return _save(
        plt,
        fig,
        tmp / f"residual_time_{slug}.png",
        "residual over time, before and after (grey: held-out sweeps)",
    )


def _plot_residual_slip(
    plt: Any,
    tmp: Path,
    slug: str,
    idx: npt.NDArray[np.int64],
    series: Any,
    preds: Mapping[str, npt.NDArray[np.float64]],
    channels: list[str],
) -> tuple[str, str]:
    fig, axes = plt.subplots(
        1, len(channels), figsize=(4.2 * len(channels) + 0.8, 3.8), squeeze=False
    )
    for ax, c in zip(axes[0], channels, strict=True):
        attr, label, scale = SLIP_OF_CHANNEL[c]
        x = np.asarray(getattr(series, attr), dtype=float)[idx] * scale
        meas = _measured(series, c)
        assert meas is not None  # _plotted_channels: only measured channels
        ax.scatter(
            x,
            (meas - preds[f"baseline_{c}"])[idx],
            s=2,
            color="tab:red",
            alpha=0.4,
            label="before",
            rasterized=True,
        )
        ax.scatter(
            x,
            (meas - preds[f"improved_{c}"])[idx],
            s=2,
            color="tab:blue",
            alpha=0.4,
            label="after",
            rasterized=True,
        )
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_xlabel(label)
        ax.set_ylabel(f"{c} residual [{UNIT_OF_CHANNEL[c]}]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8, markerscale=4)
    fig.suptitle("Residual measured − model over slip")
    return _save(
        plt, fig, tmp / f"residual_slip_{slug}.png", "residual over slip, before and after"
    )


def _worst_sweep(
    diag: Any,
    prefix: str,
    series: Any,
    preds: Mapping[str, npt.NDArray[np.float64]],
    channel: str,
) -> np.ndarray:
    """Indices of the sweep the given model fits worst, preferring held-out sweeps.

    The whole-session scatter shows the shape; a single sweep drawn as lines shows the size of
    the mismatch, which is a few per cent of the force and invisible at session scale.
    """
    n = len(series.t)
    sweeps = [np.asarray(s) for s in (_get(diag, "sweeps", {}) or {}).get(prefix, []) or []]
    sweeps = [s for s in sweeps if s.size >= 5 and s.max() < n]
    if not sweeps:  # no segmentation given: windows of a tenth of the session
        sweeps = [a for a in np.array_split(np.arange(n), 10) if a.size]
    held = (_get(diag, "heldout_mask", {}) or {}).get(prefix)
    if held is not None and len(held) == n:
        held_sweeps = [s for s in sweeps if np.mean(np.asarray(held)[s]) > 0.5]
        sweeps = held_sweeps or sweeps
    meas = _measured(series, channel)
    assert meas is not None  # _plotted_channels: only measured channels
    r = meas - preds[f"baseline_{channel}"]
    return max(sweeps, key=lambda s: float(np.sqrt(np.mean(r[s] ** 2))))


def _plot_fit(
    plt: Any,
    tmp: Path,
    slug: str,
    idx: npt.NDArray[np.int64],
    series: Any,
    preds: Mapping[str, npt.NDArray[np.float64]],
    channels: list[str],
    diag: Any = None,
    prefix: str = "",
) -> tuple[str, str]:
    fig, axes = plt.subplots(
        2, len(channels), figsize=(4.2 * len(channels) + 0.8, 7.4), squeeze=False
    )
    t0 = float(series.t[0])
    for col, c in enumerate(channels):
        attr, label, scale = SLIP_OF_CHANNEL[c]
        slip = np.asarray(getattr(series, attr), dtype=float) * scale
        meas = _measured(series, c)
        assert meas is not None  # _plotted_channels: only measured channels
        ax = axes[0, col]
        ax.scatter(
            slip[idx], meas[idx], s=3, color="0.35", alpha=0.5, label="measured", rasterized=True
        )
        ax.scatter(
            slip[idx],
            preds[f"baseline_{c}"][idx],
            s=1,
            color="tab:red",
            alpha=0.5,
            label="before",
            rasterized=True,
        )
        ax.scatter(
            slip[idx],
            preds[f"improved_{c}"][idx],
            s=1,
            color="tab:blue",
            alpha=0.5,
            label="after",
            rasterized=True,
        )
        ax.set_xlabel(label)
        ax.set_ylabel(f"{c} [{UNIT_OF_CHANNEL[c]}], whole session")
        ax.grid(alpha=0.3)
        s = _worst_sweep(diag, prefix, series, preds, c)
        ax = axes[1, col]
        ax.plot(slip[s], meas[s], ".", ms=2, color="0.35", label="measured")
        ax.plot(slip[s], preds[f"baseline_{c}"][s], lw=1.2, color="tab:red", label="before")
        ax.plot(slip[s], preds[f"improved_{c}"][s], lw=1.2, color="tab:blue", label="after")
        ax.set_xlabel(label)
        ax.set_ylabel(f"{c} [{UNIT_OF_CHANNEL[c]}]")
        ta, tb = float(series.t[s[0]]) - t0, float(series.t[s[-1]]) - t0
        ax.set_title(f"worst-fitted segment, {ta:.0f}–{tb:.0f} s", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8, markerscale=4)
    axes[1, 0].legend(loc="best", fontsize=8)
    fig.suptitle("Measured against the model before and after")
    return _save(
        plt,
        fig,
        tmp / f"fit_{slug}.png",
        "measured against the model before and after (whole session; worst segment)",
    )


def _plot_inferred(
    plt: Any,
    tmp: Path,
    slug: str,
    t: npt.NDArray[np.float64],
    idx: npt.NDArray[np.int64],
    series: Any,
    inferred: dict[str, npt.NDArray[np.float64]],
) -> tuple[str, str]:
    fig, axes = plt.subplots(
        len(inferred), 1, figsize=(10, 2.6 * len(inferred) + 0.6), sharex=True, squeeze=False
    )
    for ax, (key, values) in zip(axes[:, 0], inferred.items(), strict=True):
        scale = INFERRED_SCALE.get(key, 1.0)
        ax.plot(t[idx], values[idx] * scale, color="tab:orange", lw=1.0, label=f"inferred {key}")
        recorded = getattr(series, key, None) if key in ("T", "p") else None
        if recorded is not None:
            ax.plot(
                t[idx],
                np.asarray(recorded, dtype=float)[idx] * scale,
                color="0.3",
                lw=0.8,
                label=f"recorded {key}",
            )
        ax.set_ylabel(INFERRED_LABELS.get(key, f"inferred {key}"))
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    axes[0, 0].set_title("State inferred by the diagnosis (not in the recording)")
    axes[-1, 0].set_xlabel("time from start [s]")
    what = ", ".join(INFERRED_LABELS.get(k, k).split(" [")[0] for k in inferred)
    return _save(plt, fig, tmp / f"inferred_{slug}.png", f"{what} over time")


def _save(plt: Any, fig: Any, path: Path, caption: str) -> tuple[str, str]:
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path.name, caption


# --------------------------------------------------------------------------- the directory


def _check_target(out: Path, overwrite: bool) -> None:
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{out}: exists and is not a directory; not writing a report there")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise FileExistsError(
            f"{out}: report directory exists and is not empty; refusing to overwrite it "
            "(pass overwrite=True / --force to replace it)"
        )


def write_report(
    diag: Any,
    wheels: Any,
    out_dir: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    source: str | None = None,
) -> Path:
    """Write the diagnosis report directory and return the path of its ``report.md``.

    Parameters
    ----------
    diag : Diagnosis
        The result of :func:`tire_model_ros.diagnosis.diagnose`.
    wheels : Sequence[WheelSeries] or Mapping[str, WheelSeries]
        The recording's wheels that were diagnosed (measured channels for the plots).
    out_dir : path
        The report directory. Created if missing; an existing empty directory is used.
    overwrite : bool
        Replace an existing non-empty ``out_dir`` (otherwise ``FileExistsError``).
    source : str, optional
        Name of the recording, shown at the top of the report.

    Returns
    -------
    Path
        ``out_dir/report.md``. Beside it: the PNG plots and ``diagnosis.json``.
    """
    import matplotlib

    matplotlib.use("Agg", force=True)  # files only: never needs a display
    import matplotlib.pyplot as plt

    out = Path(out_dir).absolute()
    wheel_map = _wheel_map(wheels)
    _check_target(out, overwrite)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        plots = {
            prefix: _plot_wheel(plt, tmp, diag, prefix, series)
            for prefix, series in wheel_map.items()
        }
        (tmp / "report.md").write_text(_markdown(diag, wheel_map, plots, source), encoding="utf-8")
        to_json = getattr(diag, "to_json", None)
        if callable(to_json):
            (tmp / "diagnosis.json").write_text(
                json.dumps(to_json(), indent=2) + "\n", encoding="utf-8"
            )
        os.chmod(tmp, 0o755)  # mkdtemp makes 0700; a report is for reading
        _check_target(out, overwrite)  # again: someone may have written there meanwhile
        replace_path(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        plt.close("all")
        raise
    return out / "report.md"
