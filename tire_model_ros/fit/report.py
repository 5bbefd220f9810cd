"""Fit report: RMSE, NRMSE and R^2 before and after, on fitted and held-out sweeps.

Figures per channel and per operating condition (load, pressure, inclination: the levels the
segmentation found in the data; temperature in 10 degC bins), written as markdown and JSON,
plus PNG plots (matplotlib, Agg backend) as an engineer reads them: each channel against its
slip, one panel per condition (pressure, inclination, held slip) and one colour per load,
measured dots and the fitted and start models' curves, each panel titled with its RMSE start
-> fitted; held-out sweeps; residuals over time.
Every axis carries its unit. Residuals are measured - model everywhere (the diagnosis' sign);
``bias`` is their mean. NRMSE = RMSE / (max - min of the measured channel on the same
samples), as in INTERFACE.md.
"""

from __future__ import annotations

import io
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..atomic import write_atomic
from ..vocabulary import FORCE_CHANNELS, SERIES_UNITS
from .core import evaluate_on, stack_inputs

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..model import MFOutput, TireModel
    from ..recording.series import WheelSeries
    from .stages import FitResult
    from .sweeps import Segment

Floats = npt.NDArray[np.float64]
Panel = tuple[float | None, float | None, float | None]  # p [Pa], gamma [rad], held slip
Members = list[tuple[int, npt.NDArray[np.intp]]]  # (wheel, sample indices)

SETS = ("fitted", "heldout")
MIN_LEVEL_FRACTION = 0.005  # condition levels with fewer samples are left out of the tables
UNIT = {c: SERIES_UNITS[c] for c in FORCE_CHANNELS}
SLIP_OF = {"Fx": "kappa", "My": "kappa", "Fy": "alpha", "Mx": "alpha", "Mz": "alpha"}
# slip -> (axis label, factor from SI)
SLIP_AXIS = {
    "kappa": ("slip ratio kappa [-]", 1.0),
    "alpha": ("slip angle alpha [deg]", 180 / math.pi),
}
# condition table -> (Segment.condition key, unit, factor from SI)
CONDITIONS = {
    "load": ("Fz", "N", 1.0),
    "pressure": ("p", "kPa", 1e-3),
    "inclination": ("gamma", "deg", 180 / math.pi),
}
#: decimals of a condition level in the tables, by its unit: a level is the median of the
#: measured channel, and an inclination of 1e-05 deg is 0.00 deg at the rig's resolution
LEVEL_DECIMALS = {"N": 0, "kPa": 1, "deg": 2, "degC": 0}
TEMPERATURE_BIN_C = 10.0
MAX_PANELS = 12  # conditions drawn per channel (those with the most samples)
MAX_DOTS = 1500  # measured samples drawn per load curve


def channel_metrics(measured: Floats, predicted: Floats) -> dict[str, float]:
    """rmse [unit], bias (mean of measured - model) [unit], nrmse [-], r2 [-] and n on the
    finite samples."""
    ok = np.isfinite(measured) & np.isfinite(predicted)
    y, f = measured[ok], predicted[ok]
    if len(y) == 0:
        return {"n": 0, "rmse": math.nan, "bias": math.nan, "nrmse": math.nan, "r2": math.nan}
    d = y - f
    rmse = float(np.sqrt(np.mean(d * d)))
    span = float(np.max(y) - np.min(y))
    sst = float(np.sum((y - y.mean()) ** 2))
    return {
        "n": len(y),
        "rmse": rmse,
        "bias": float(np.mean(d)),
        "nrmse": rmse / span if span > 0 else math.nan,
        "r2": 1.0 - float(np.sum(d * d)) / sst if sst > 0 else math.nan,
    }


def measured_channels(wheels: Sequence[WheelSeries]) -> list[str]:
    """The force channels with a finite measured value in some wheel: a bag's measured_forces
    carry all six, NaN where nothing was measured (a TTC run's My), and such a channel gets
    no empty table rows or panels."""
    return [
        c
        for c in FORCE_CHANNELS
        if any(getattr(s, c) is not None and np.isfinite(getattr(s, c)).any() for s in wheels)
    ]


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


def _levels(result: FitResult) -> dict[str, tuple[Floats, str]]:
    """Per sample level of each condition, in its report unit: load, pressure, inclination
    from the segments' condition levels (NaN while the condition changes), temperature in
    ``TEMPERATURE_BIN_C`` bins."""
    wheels = result.wheels
    lengths = [len(s) for s in wheels]
    out = {}
    for dim, (key, unit, factor) in CONDITIONS.items():
        if all(getattr(s, key) is None for s in wheels):
            continue
        parts = []
        for s, segs in zip(wheels, result.segments, strict=True):
            level = np.full(len(s), np.nan)
            for seg in segs:
                if key in seg.condition:
                    level[seg.index] = seg.condition[key] * factor
            parts.append(level)
        out[dim] = (np.concatenate(parts) if parts else np.zeros(0), unit)
    if any(s.T is not None for s in wheels):
        T = _stack([s.T for s in wheels], lengths)
        out["temperature"] = (np.round(T / TEMPERATURE_BIN_C) * TEMPERATURE_BIN_C, "degC")
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
    channels = measured_channels(wheels)
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
    for dim, (level, unit) in _levels(result).items():
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


def level_text(level: float, unit: str) -> str:
    """A condition level with its unit at the tables' resolution, never "-0"."""
    digits = LEVEL_DECIMALS.get(unit, 3)
    return f"{round(level, digits) + 0.0:.{digits}f} {unit}"


def markdown(result: FitResult) -> str:
    """The report as markdown text."""
    rep = result.report
    met = rep["metrics"]
    lines = ["# Magic Formula fit report", ""]
    if rep.get("note"):
        lines += [f"**Note:** {rep['note']}", ""]
    lines.append(
        f"Samples: {rep['n_samples']} ({rep['n_train']} fitted, {rep['n_heldout']} "
        f"held out: every {rep['holdout_every']}th ramp per condition; "
        f"{rep['n_sweeps']} sweeps in {rep.get('n_ramps', '?')} ramps). "
        f"Wheels: {', '.join(rep['wheels'])}. "
        f"Fit time {rep.get('time_s', 0):.1f} s. Residuals are measured - model; bias is "
        "their mean."
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
        "| set | channel | rmse before | rmse after | bias before | bias after | "
        "nrmse before | nrmse after | R2 before | R2 after | n |",
        "| --- " * 11 + "|",
    ]
    for set_name in SETS:
        for c in met["channels"]:
            b, a = met["overall"][set_name]["before"][c], met["overall"][set_name]["after"][c]
            lines.append(
                f"| {set_name} | {c} [{UNIT[c]}] | {_fmt(b['rmse'])} | {_fmt(a['rmse'])} | "
                f"{_fmt(b['bias'])} | {_fmt(a['bias'])} | "
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
                    f"| {level_text(row['level'], row['unit'])} | {c} | "
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
    import matplotlib.pyplot as plt

    for name, fig in figures(result).items():
        _save(fig, d / name)
        plt.close(fig)


def figures(result: FitResult) -> dict[str, Figure]:
    """The report's matplotlib figures by file name (Agg backend; the caller closes them)."""
    import matplotlib

    matplotlib.use("Agg")
    channels = result.report["metrics"]["channels"]
    out = {f"fit_{c}.png": _plot_conditions(result, c) for c in channels}
    out["fit_sweeps.png"] = _plot_sweeps(result, channels)
    out["fit_residual_time.png"] = _plot_residuals(result, channels)
    return out


def _condition_samples(result: FitResult, c: str) -> dict[Panel, dict[float, Members]]:
    """Samples of the sweeps of channel ``c``'s slip, by panel (pressure, inclination, held
    slip levels) and load level: {panel: {load: [(wheel, indices)]}}."""
    slip = SLIP_OF[c]
    other = "alpha" if slip == "kappa" else "kappa"
    out: dict[Panel, dict[float, Members]] = {}
    for w, segs in enumerate(result.segments):
        for seg in segs:
            cond = seg.condition
            if seg.kind != "ramp" or seg.slips != (slip,) or "Fz" not in cond:
                continue
            panel = (cond.get("p"), cond.get("gamma"), cond.get(other))
            out.setdefault(panel, {}).setdefault(cond["Fz"], []).append((w, seg.index))
    return out


def _panel_title(panel: Panel, slip: str) -> str:
    p, gamma, held = panel
    other = "alpha" if slip == "kappa" else "kappa"
    parts = []
    if p is not None:
        parts.append(f"p {p / 1000:.0f} kPa")
    if gamma is not None:
        parts.append(f"gamma {_deg(gamma)} deg")
    if held is not None and abs(held) > (0.005 if other == "kappa" else math.radians(0.3)):
        parts.append(f"alpha {_deg(held)} deg" if other == "alpha" else f"kappa {held:.3f}")
    return ", ".join(parts) or "all samples"


def _deg(rad: float) -> str:
    """An angle [rad] in degrees with one decimal, never "-0.0"."""
    return f"{round(math.degrees(rad), 1) + 0.0:.1f}"


def _panel_rmse(result: FitResult, c: str, groups: Mapping[float, Members]) -> str:
    """RMSE of measured - model of channel ``c`` on a panel's samples, start -> fitted model:
    the improvement per condition, which one cloud of all samples would hide."""
    rmse = []
    for name in ("before", "after"):
        d = np.concatenate(
            [
                getattr(result.wheels[w], c)[i]
                - np.asarray(getattr(result.predictions[name][w], c))[i]
                for members in groups.values()
                for w, i in members
            ]
        )
        d = d[np.isfinite(d)]  # none finite: a channel not measured on this panel
        rmse.append(float(np.sqrt(np.mean(d * d))) if d.size else math.nan)
    return f"{c} rmse {_fmt(rmse[0], 3)} -> {_fmt(rmse[1], 3)} {UNIT[c]}"


def _curve(
    model: TireModel, wheels: Sequence[WheelSeries], members: Members, slip: str, grid: Floats
) -> MFOutput:
    """The model's force on a slip grid at the median inputs of ``members``' samples."""

    def med(name: str) -> float | None:
        vals = [getattr(wheels[w], name) for w, _ in members]
        if any(v is None for v in vals):
            return None
        return float(
            np.nanmedian(np.concatenate([v[i] for v, (_, i) in zip(vals, members, strict=True)]))
        )

    args: dict[str, Floats | None] = {}
    for k in ("Fz", "kappa", "alpha", "gamma", "Vx", "p", "T"):
        v = med(k)
        args[k] = None if v is None else np.full(len(grid), v)
    args[slip] = grid
    out: MFOutput = evaluate_on(model, args)
    return out


def _plot_conditions(result: FitResult, c: str) -> Figure:
    """Channel ``c`` against its slip: a panel per condition, a colour per load level."""
    import matplotlib.pyplot as plt

    slip = SLIP_OF[c]
    label, factor = SLIP_AXIS[slip]
    groups = _condition_samples(result, c)
    size = {k: sum(len(i) for v in g.values() for _, i in v) for k, g in groups.items()}
    panels = sorted(
        sorted(groups, key=lambda k: -size[k])[:MAX_PANELS],
        key=lambda k: tuple(-1e99 if v is None else v for v in k),
    )
    if not panels or all(getattr(s, c) is None for s in result.wheels):
        fig, ax = plt.subplots(figsize=(6, 3))
        ax.text(0.5, 0.5, f"no {slip} sweep with measured {c} in the recording", ha="center")
        ax.set_axis_off()
        return fig
    ncol = min(3, len(panels))
    nrow = -(-len(panels) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.6 * nrow + 0.8), squeeze=False)
    cmap = plt.get_cmap("viridis")
    loads = sorted({fz for g in groups.values() for fz in g})
    rng = np.random.default_rng(0)
    for ax, panel in zip(axes.ravel(), panels, strict=False):
        for fz, members in sorted(groups[panel].items()):
            colour = cmap(loads.index(fz) / max(1, len(loads) - 1))
            x = np.concatenate([getattr(result.wheels[w], slip)[i] for w, i in members])
            y = np.concatenate([getattr(result.wheels[w], c)[i] for w, i in members])
            pick = rng.choice(len(x), min(len(x), MAX_DOTS), replace=False)
            # the dots above the curves: the measurement is what the reader checks them on
            ax.plot(x[pick] * factor, y[pick], ".", ms=2, color=colour, alpha=0.35, zorder=3)
            grid = np.linspace(np.nanmin(x), np.nanmax(x), 121)
            for model, style in ((result.start_model, "--"), (result.model, "-")):
                f = np.asarray(getattr(_curve(model, result.wheels, members, slip, grid), c))
                ax.plot(
                    grid * factor,
                    f,
                    style,
                    lw=1.2 if style == "-" else 0.8,
                    color=colour,
                    label=f"Fz {fz:.0f} N" if style == "-" else None,
                )
        rmse = _panel_rmse(result, c, groups[panel])
        ax.set_title(f"{_panel_title(panel, slip)}\n{rmse} (start -> fitted)", fontsize=9)
        ax.set_xlabel(label)
        ax.set_ylabel(f"{c} [{UNIT[c]}]")
        ax.legend(fontsize=7)
    for ax in axes.ravel()[len(panels) :]:
        ax.set_axis_off()
    left = len(groups) - len(panels)
    fig.suptitle(
        f"{c} per condition: measured (dots), fitted model (solid), start model (dashed); "
        "model at each load's median inputs"
        + (f"; {left} more conditions not drawn" if left > 0 else ""),
        fontsize=9,
    )
    fig.tight_layout()
    return fig


def _plot_residuals(result: FitResult, channels: Sequence[str]) -> Figure:
    """Measured - model over time, start and fitted model."""
    import matplotlib.pyplot as plt

    wheels = result.wheels
    lengths = [len(s) for s in wheels]
    pred = {
        k: {c: np.concatenate([np.asarray(getattr(o, c)) for o in outs]) for c in channels}
        for k, outs in result.predictions.items()
    }
    t = np.concatenate([s.t - s.t[0] if len(s) else s.t for s in wheels])
    fig, axes = plt.subplots(
        len(channels), 1, figsize=(10, 2.2 * len(channels) + 0.5), squeeze=False
    )
    step = max(1, len(t) // 20000)
    for ax, c in zip(axes[:, 0], channels, strict=True):
        y = _stack([getattr(s, c) for s in wheels], lengths)
        ax.plot(t[::step], (y - pred["before"][c])[::step], ",", color="0.6", label="start model")
        ax.plot(t[::step], (y - pred["after"][c])[::step], ",", color="tab:blue", label="fitted")
        ax.set_ylabel(f"{c} measured - model [{UNIT[c]}]", fontsize=8)
        ax.set_xlabel("time since start of each wheel [s]", fontsize=8)
        ax.legend(fontsize=7, markerscale=10, loc="upper right")
    fig.tight_layout()
    return fig


def _plot_sweeps(result: FitResult, channels: Sequence[str]) -> Figure:
    """Force against slip on a few held-out sweeps: measured, start and fitted model."""
    import matplotlib.pyplot as plt

    picks = []
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
        label, factor = SLIP_AXIS[x_name]
        x = getattr(s, x_name)[seg.index] * factor
        y = getattr(s, c)
        if y is None:
            ax.set_axis_off()
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
        ax.set_xlabel(label)
        ax.set_ylabel(f"{c} [{UNIT[c]}]")
        ax.legend(fontsize=7)
    if not sel:
        axes[0, 0].text(0.5, 0.5, "no held-out slip sweep", ha="center")
        axes[0, 0].set_axis_off()
    fig.tight_layout()
    return fig


def _save(fig: Figure, path: Path) -> None:
    """Atomic PNG write."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    write_atomic(path, buf.getvalue(), overwrite=True)
