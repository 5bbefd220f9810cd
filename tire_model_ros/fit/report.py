"""Fit report: RMSE, NRMSE and R^2 before and after, on fitted and held-out sweeps.

Figures per channel and per operating condition (load, pressure and temperature level), written
as markdown and JSON, plus PNG plots of measured against model (matplotlib, Agg backend).
NRMSE = RMSE / (max - min of the measured channel on the same samples), as in INTERFACE.md.
"""

from __future__ import annotations

import io
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from ..atomic import write_atomic
from ..vocabulary import FORCE_CHANNELS
from .core import evaluate_on, stack_inputs

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from tire_model_ros.model import MFOutput, TireModel
    from tire_model_ros.recording.series import WheelSeries

    from .stages import FitResult
    from .sweeps import Segment

SETS = ("fitted", "heldout")
MIN_LEVEL_FRACTION = 0.005  # condition levels with fewer samples are left out of the tables


def channel_metrics(measured: np.ndarray, predicted: np.ndarray) -> dict[str, float]:
    """rmse [unit], nrmse [-], r2 [-] and n on the finite samples."""
    ok = np.isfinite(measured) & np.isfinite(predicted)
    y, f = measured[ok], predicted[ok]
    if len(y) == 0:
        return {"n": 0, "rmse": math.nan, "nrmse": math.nan, "r2": math.nan}
    d = f - y
    rmse = float(np.sqrt(np.mean(d * d)))
    span = float(np.max(y) - np.min(y))
    sst = float(np.sum((y - y.mean()) ** 2))
    return {
        "n": len(y),
        "rmse": rmse,
        "nrmse": rmse / span if span > 0 else math.nan,
        "r2": 1.0 - float(np.sum(d * d)) / sst if sst > 0 else math.nan,
    }


def _predict(model: TireModel, wheels: Sequence[WheelSeries]) -> list[MFOutput]:
    out = []
    for s in wheels:
        inputs, _, _ = stack_inputs(model, [s], ())
        out.append(evaluate_on(model, inputs))
    return out


def _stack(values: Sequence[np.ndarray | None], lengths: Sequence[int]) -> np.ndarray:
    return np.concatenate(
        [
            np.asarray(v, dtype=np.float64) if v is not None else np.full(n, np.nan)
            for v, n in zip(values, lengths, strict=True)
        ]
    )


def _levels(model: TireModel, wheels: Sequence[WheelSeries]) -> dict[str, tuple[np.ndarray, str]]:
    """Per sample level of each varying condition: (bin centre array, unit label)."""
    P = model.params
    fz0 = float(P["FNOMIN"])
    p0 = float(P.get("NOMPRES", 0.0)) or 1e5
    lengths = [len(s) for s in wheels]
    out = {
        "load": (np.round(_stack([s.Fz for s in wheels], lengths) / (0.1 * fz0)) * 0.1 * fz0, "N")
    }
    if any(s.p is not None for s in wheels):
        out["pressure"] = (
            np.round(_stack([s.p for s in wheels], lengths) / (0.05 * p0)) * 0.05 * p0,
            "Pa",
        )
    if any(s.T is not None for s in wheels):
        out["temperature"] = (
            np.round(_stack([s.T for s in wheels], lengths) / 10.0) * 10.0,
            "degC",
        )
    return out


def fit_metrics(result: FitResult) -> dict[str, Any]:
    """Metrics of a FitResult (fills ``result.predictions``); JSON-ready."""
    wheels = result.wheels
    lengths = [len(s) for s in wheels]
    result.predictions = {
        "before": _predict(result.start_model, wheels),
        "after": _predict(result.model, wheels),
    }
    masks = {
        "fitted": np.concatenate(result.train_masks),
        "heldout": np.concatenate(result.heldout_masks),
    }
    channels = [c for c in FORCE_CHANNELS if any(getattr(s, c) is not None for s in wheels)]
    measured = {c: _stack([getattr(s, c) for s in wheels], lengths) for c in channels}
    pred = {
        k: {c: np.concatenate([np.asarray(getattr(o, c)) for o in outs]) for c in channels}
        for k, outs in result.predictions.items()
    }
    overall: dict[str, Any] = {}
    for set_name, m in masks.items():
        overall[set_name] = {
            model_name: {
                c: channel_metrics(measured[c][m], pred[model_name][c][m]) for c in channels
            }
            for model_name in ("before", "after")
        }
    by_condition: dict[str, Any] = {}
    for dim, (level, unit) in _levels(result.start_model, wheels).items():
        rows = []
        finite = np.isfinite(level)
        values, counts = np.unique(level[finite], return_counts=True)
        for v, n in zip(values, counts, strict=True):
            if n < MIN_LEVEL_FRACTION * len(level):
                continue
            at = finite & (level == v)
            row: dict[str, Any] = {"level": float(v), "unit": unit, "n": int(n)}
            for set_name, m in masks.items():
                sel = at & m
                row[set_name] = {
                    model_name: {
                        c: channel_metrics(measured[c][sel], pred[model_name][c][sel])
                        for c in channels
                    }
                    for model_name in ("before", "after")
                }
            rows.append(row)
        by_condition[dim] = rows
    return {"channels": channels, "overall": overall, "by_condition": by_condition}


# --- writing ---------------------------------------------------------------------------------


def _fmt(x: float | None, digits: int = 4) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.{digits}g}"


def markdown(result: FitResult) -> str:
    """The report as markdown text."""
    rep = result.report
    met = rep["metrics"]
    lines = ["# Magic Formula fit report", ""]
    lines.append(
        f"Samples: {rep['n_samples']} ({rep['n_train']} fitted, {rep['n_heldout']} "
        f"held out: every {rep['holdout_every']}th sweep per condition; "
        f"{rep['n_sweeps']} sweeps). Wheels: {', '.join(rep['wheels'])}. "
        f"Fit time {rep.get('time_s', 0):.1f} s."
    )
    lines += [
        "",
        "## Stages",
        "",
        "| stage | status | coefficients | samples | detail |",
        "| --- | --- | --- | --- | --- |",
    ]
    for st in rep["stages"]:
        detail = st.get("reason", "")
        if st["status"] == "fitted":
            detail = ", ".join(
                f"{c} rmse {_fmt(st['rmse_before'][c])} -> {_fmt(st['rmse_after'][c])}"
                for c in st["channels"]
            )
        if st.get("not_identifiable"):
            ni = st["not_identifiable"]
            detail += f"; not fitted ({ni['reason']}): {', '.join(ni['names'])}"
        for w in st.get("warnings", []):
            detail += f"; warning: {w}"
        lines.append(
            f"| {st['stage']} | {st['status']} | {', '.join(st.get('names', []))} | "
            f"{st.get('n_rows', '')} | {detail} |"
        )
    lines += [
        "",
        "## Coefficients changed",
        "",
        "| name | start | fitted | std. error |",
        "| --- | --- | --- | --- |",
    ]
    se: dict[str, float] = {}
    for st in rep["stages"]:
        if st["status"] == "fitted":
            se.update(st["stderr"])
    for k, (a, b) in rep["changed"].items():
        lines.append(f"| {k} | {_fmt(a, 6)} | {_fmt(b, 6)} | {_fmt(se.get(k), 3)} |")
    lines += [
        "",
        "## Accuracy",
        "",
        "| set | channel | rmse before | rmse after | nrmse before | "
        "nrmse after | R2 before | R2 after | n |",
        "| --- " * 9 + "|",
    ]
    for set_name in SETS:
        for c in met["channels"]:
            b, a = met["overall"][set_name]["before"][c], met["overall"][set_name]["after"][c]
            lines.append(
                f"| {set_name} | {c} | {_fmt(b['rmse'])} | {_fmt(a['rmse'])} | "
                f"{_fmt(b['nrmse'], 3)} | {_fmt(a['nrmse'], 3)} | {_fmt(b['r2'], 4)} | "
                f"{_fmt(a['r2'], 4)} | {a['n']} |"
            )
    for dim, rows in met["by_condition"].items():
        lines += [
            "",
            f"## By {dim} level (held out / fitted; rmse before -> after, nrmse after)",
            "",
            "| level | channel | held-out rmse | held-out nrmse | fitted rmse | n |",
            "| --- " * 6 + "|",
        ]
        for row in rows:
            for c in met["channels"]:
                h, f = row["heldout"], row["fitted"]
                lines.append(
                    f"| {_fmt(row['level'], 5)} {row['unit']} | {c} | "
                    f"{_fmt(h['before'][c]['rmse'])} -> {_fmt(h['after'][c]['rmse'])} | "
                    f"{_fmt(h['after'][c]['nrmse'], 3)} | "
                    f"{_fmt(f['before'][c]['rmse'])} -> {_fmt(f['after'][c]['rmse'])} | "
                    f"{row['n']} |"
                )
    lines.append("")
    return "\n".join(lines)


def _clean(obj: Any) -> Any:
    """JSON-safe copy: numpy scalars to Python, NaN/inf to None."""
    if isinstance(obj, Mapping):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer, int)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(obj) else None
    return obj


def _write_atomic(path: Path, data: bytes | str) -> None:
    write_atomic(path, data, overwrite=True)  # the report folder was checked as a whole


REPORT_FILES = ("fit_report.md", "fit_report.json")


def _plot_files(channels: Sequence[str]) -> list[str]:
    return [f"fit_{c}.png" for c in channels] + ["fit_sweeps.png", "fit_residual_time.png"]


def report_paths(
    out_dir: str | os.PathLike[str], channels: Sequence[str] = FORCE_CHANNELS
) -> list[Path]:
    """Every file :func:`write_fit_report` may write in ``out_dir``."""
    d = Path(out_dir)
    return [d / n for n in (*REPORT_FILES, *_plot_files(channels))]


def write_fit_report(
    result: FitResult, out_dir: str | os.PathLike[str], *, overwrite: bool = False
) -> Path:
    """Write fit_report.md, fit_report.json and PNG plots into ``out_dir``; returns the md path.

    Raises FileExistsError (an OSError) naming the file when one exists and not ``overwrite``.
    """
    d = Path(out_dir)
    channels = result.report["metrics"]["channels"]
    if not overwrite:
        for p in report_paths(d, channels):
            if p.exists():
                raise FileExistsError(f"{p}: exists (use --force to overwrite)")
    d.mkdir(parents=True, exist_ok=True)
    _write_atomic(d / "fit_report.json", json.dumps(_clean(result.report), indent=1))
    _write_atomic(d / "fit_report.md", markdown(result))
    _plots(result, d)
    return d / "fit_report.md"


def _plots(result: FitResult, d: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    wheels = result.wheels
    lengths = [len(s) for s in wheels]
    channels = result.report["metrics"]["channels"]
    train = np.concatenate(result.train_masks)
    held = np.concatenate(result.heldout_masks)
    rng = np.random.default_rng(0)
    pred = {
        k: {c: np.concatenate([np.asarray(getattr(o, c)) for o in outs]) for c in channels}
        for k, outs in result.predictions.items()
    }
    t = np.concatenate([s.t - s.t[0] if len(s) else s.t for s in wheels])
    for c in channels:
        y = _stack([getattr(s, c) for s in wheels], lengths)
        fig, ax = plt.subplots(figsize=(6, 6))
        for mask, label, color in ((train, "fitted", "tab:blue"), (held, "held out", "tab:red")):
            idx = np.flatnonzero(mask & np.isfinite(y))
            if len(idx) > 4000:
                idx = np.sort(rng.choice(idx, 4000, replace=False))
            ax.plot(
                y[idx],
                pred["before"][c][idx],
                ".",
                ms=1.5,
                color="0.7",
                label=f"start model ({label})",
            )
            ax.plot(
                y[idx],
                pred["after"][c][idx],
                ".",
                ms=1.5,
                color=color,
                label=f"fitted model ({label})",
            )
        lim = np.nanpercentile(y, [0.5, 99.5]) if np.any(np.isfinite(y)) else [0, 1]
        ax.plot(lim, lim, "k-", lw=0.8)
        ax.set_xlabel(f"measured {c}")
        ax.set_ylabel(f"model {c}")
        ax.set_title(f"{c}: model against measurement")
        ax.legend(fontsize=7, markerscale=6)
        fig.tight_layout()
        _save(fig, d / f"fit_{c}.png")
        plt.close(fig)
    _plot_sweeps(result, d, channels, plt)
    fig, axes = plt.subplots(
        len(channels), 1, figsize=(10, 2.2 * len(channels) + 0.5), squeeze=False
    )
    step = max(1, len(t) // 20000)
    for ax, c in zip(axes[:, 0], channels, strict=True):
        y = _stack([getattr(s, c) for s in wheels], lengths)
        ax.plot(t[::step], (pred["before"][c] - y)[::step], ",", color="0.6", label="start")
        ax.plot(t[::step], (pred["after"][c] - y)[::step], ",", color="tab:blue", label="fitted")
        ax.set_ylabel(f"{c} model - measured")
    axes[-1, 0].set_xlabel("time since start of each wheel [s]")
    fig.tight_layout()
    _save(fig, d / "fit_residual_time.png")
    plt.close(fig)


def _plot_sweeps(result: FitResult, d: Path, channels: Sequence[str], plt: ModuleType) -> None:
    """Force against slip on a few held-out sweeps: measured, start and fitted model."""
    picks: list[tuple[int, Segment]] = []
    for w, (_s, segs, held) in enumerate(
        zip(result.wheels, result.segments, result.heldout_masks, strict=True)
    ):
        for seg in segs:
            if (
                seg.kind == "ramp"
                and held[seg.index].all()
                and ("kappa" in seg.direction or "alpha" in seg.direction)
            ):
                picks.append((w, seg))
    chosen: dict[str, list[tuple[int, Segment]]] = {}
    for w, seg in picks:  # one of each slip kind first
        key = "kappa" if "kappa" in seg.direction else "alpha"
        chosen.setdefault(key, []).append((w, seg))
    sel = [v for lst in chosen.values() for v in lst[:2]][:4]
    fig, axes = plt.subplots(
        1, max(1, len(sel)), figsize=(4.5 * max(1, len(sel)), 4), squeeze=False
    )
    for ax, (w, seg) in zip(axes[0], sel, strict=False):
        s = result.wheels[w]
        x_name = "kappa" if "kappa" in seg.direction else "alpha"
        c = (
            "Fx"
            if x_name == "kappa" and "Fx" in channels
            else ("Fy" if "Fy" in channels else channels[0])
        )
        x = getattr(s, x_name)[seg.index]
        y = getattr(s, c)
        if y is None:
            continue
        ax.plot(x, y[seg.index], ".", ms=2, color="0.3", label="measured")
        ax.plot(
            x,
            np.asarray(getattr(result.predictions["before"][w], c))[seg.index],
            "-",
            color="0.6",
            label="start model",
        )
        ax.plot(
            x,
            np.asarray(getattr(result.predictions["after"][w], c))[seg.index],
            "-",
            color="tab:red",
            label="fitted model",
        )
        fz = float(np.nanmedian(s.Fz[seg.index]))
        ax.set_title(f"held-out {seg.label}, Fz {fz:.0f} N", fontsize=9)
        ax.set_xlabel(x_name)
        ax.set_ylabel(c)
        ax.legend(fontsize=7)
    if not sel:
        axes[0, 0].text(0.5, 0.5, "no held-out slip sweep", ha="center")
    fig.tight_layout()
    _save(fig, d / "fit_sweeps.png")
    plt.close(fig)


def _save(fig: Figure, path: Path) -> None:
    """Atomic PNG write."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    write_atomic(path, buf.getvalue(), overwrite=True)
