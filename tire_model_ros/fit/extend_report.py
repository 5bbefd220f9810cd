"""The report of ``fit --extend``: what informed which region, and the seed paper's figures.

Written into the fit's report folder beside the final fit's own report (``fit_report.md``, the
rig's levels) and the simulation's (``simulation/``):

- ``extension.md`` / ``extension.json``: the sources, how the rig differs from the simulation
  (the diagnosis' words) and what was corrected, the sidewall contact, the ranges before and
  after, the envelope by source;
- ``envelope.png``: the operating envelope, a map over load and pressure per temperature
  cell of which source informed each cell;
- ``seed_pressure.png``, ``seed_load.png``, ``seed_temperature.png``: the seed paper's
  figures for the extended model, Fx against slip ratio and Fy against slip angle, the
  simulation's samples against the fused model: 60/140/220 kPa at 120 % load, 120/140/160 %
  load at 60 kPa, -10/40/80 degC at 220 kPa and 120 % load (the nominal temperature unless
  varied).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..model.envelope import RIG, SIMULATION, SOURCE_NAMES, Envelope
from .core import nominal_inputs
from .extend import ExtendResult, sources
from .report import _clean, _save, _write_atomic, report_paths, write_fit_report

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from tire_model_ros.model import TireModel
    from tire_model_ros.recording.series import WheelSeries

F64 = npt.NDArray[np.float64]

EXTENSION_FILES = (
    "extension.md",
    "extension.json",
    "envelope.png",
    "seed_pressure.png",
    "seed_load.png",
    "seed_temperature.png",
)
SIMULATION_DIR = "simulation"
COLOURS = {RIG: "tab:blue", SIMULATION: "tab:orange", RIG | SIMULATION: "tab:green"}
PURE_KAPPA = 0.005  # a lateral sample: |kappa| below this
PURE_ALPHA_RAD = math.radians(0.3)  # a longitudinal one: |alpha| below this
# How near a sample must be to a figure's condition: load [FNOMIN], pressure [-], T [K].
NEAR = (0.04, 0.05, 2.0)
MAX_DOTS = 600  # per curve


@dataclass(frozen=True)
class Condition:
    """One curve of a seed figure: load [FNOMIN], pressure [kPa], temperature [degC] (None:
    the model's nominal)."""

    load: float
    p_kPa: float
    T_C: float | None
    label: str


# The seed paper's three figures (Figs 8, 9, 11 of the paper).
SEED_FIGURES: dict[str, tuple[str, tuple[Condition, ...]]] = {
    "seed_pressure.png": (
        "inflation pressure at 120 % load",
        tuple(Condition(1.2, p, None, f"{p:g} kPa") for p in (60.0, 140.0, 220.0)),
    ),
    "seed_load.png": (
        "load at 60 kPa",
        tuple(Condition(f, 60.0, None, f"{100 * f:.0f} % load") for f in (1.2, 1.4, 1.6)),
    ),
    "seed_temperature.png": (
        "tyre temperature at 220 kPa, 120 % load",
        tuple(Condition(1.2, 220.0, T, f"{T:g} degC") for T in (-10.0, 40.0, 80.0)),
    ),
}


def extension_paths(out_dir: str | os.PathLike[str]) -> list[Path]:
    """Every file :func:`write_extension_report` may write (beside the fit's own)."""
    d = Path(out_dir)
    return [
        *report_paths(d),
        *(d / n for n in EXTENSION_FILES),
        *report_paths(d / SIMULATION_DIR),
    ]


def write_extension_report(result: ExtendResult, out_dir: str | os.PathLike[str]) -> Path:
    """The whole report of ``fit --extend`` into ``out_dir``; returns extension.md's path."""
    d = Path(out_dir)
    write_fit_report(result.fit, d, overwrite=True)
    write_fit_report(result.sim_fit, d / SIMULATION_DIR, overwrite=True)
    _write_atomic(d / "extension.json", json.dumps(_clean(summary(result)), indent=1))
    _write_atomic(d / "extension.md", markdown(result))
    plot_envelope(result.envelope, result.model, d / "envelope.png")
    for name, (title, conditions) in SEED_FIGURES.items():
        plot_seed_figure(result, title, conditions, d / name)
    return d / "extension.md"


# --- numbers -------------------------------------------------------------------------------


def summary(result: ExtendResult) -> dict[str, Any]:
    """The JSON of the report."""
    comp = result.comparison
    env = result.envelope
    return {
        "sources": sources(result),
        "comparison": {
            "diagnosis": comp.diagnosis.to_json(),
            "words": comp.words,
            "heating_scale": comp.heating_scale,
            "rig_ambient_C": comp.T_ambient_C,
            "rig_temperature_C": _span(comp.rig_T),
            "rms_rig_against_simulation_N": comp.rms,
            "rig_in_simulation_cells": comp.overlap,
            "rig_at_simulated_load_and_pressure": comp.overlap_load_pressure,
            "rig_friction_of_simulation": comp.friction,
        },
        "sidewall": None if result.sidewall is None else result.sidewall.to_json(),
        "ranges": {k: {"start": a, "fused": b} for k, (a, b) in result.ranges.items()},
        "envelope": {
            "cells": len(env.cells),
            "by_source": {
                SOURCE_NAMES[s]: sum(1 for v in env.cells.values() if v == s) for s in COLOURS
            },
            "steps": [env.fz_step_N, env.p_step_Pa, env.T_step_K],
        },
        "fused_stages": [
            {k: e.get(k) for k in ("stage", "status", "names", "fixed", "reason")}
            for e in result.fit.report["stages"]
        ],
        "notes": result.notes,
    }


def _span(arrays: Sequence[F64 | None]) -> list[float] | None:
    vals = [a for a in arrays if a is not None]
    if not vals:
        return None
    return [float(min(np.min(a) for a in vals)), float(max(np.max(a) for a in vals))]


def markdown(result: ExtendResult) -> str:
    """extension.md."""
    comp, src = result.comparison, sources(result)
    lines = [
        "# Fit extended beyond the rig (`fit --extend`)",
        "",
        f"Rig: {src['rig_samples']} samples; simulation: {src['simulation_samples']} samples, "
        f"{src['simulation_in_rig_cells']} of them in cells the rig reaches (compared, the rig "
        f"prevails there), {src['sidewall_corner']} in the sidewall-contact corner (left out of "
        "the lateral fit).",
        "",
        "## Where rig and simulation differ",
        "",
        "The rig diagnosed against the simulation's model: "
        f"{100 * comp.overlap_load_pressure:.0f} % of the rig's sweep samples lie at loads and "
        f"pressures the simulation covers, {100 * comp.overlap:.0f} % at its temperatures too "
        "(the rig's tyre as estimated below). The diagnosis names:",
        "",
        *[
            f"- **{e.name}**{' (concealed)' if e.concealed else ''} in {e.channel}: {e.where}"
            for e in comp.diagnosis.effects
        ],
        "",
        *_correction_lines(result),
        *_sidewall_lines(result),
        "## Ranges of OUT.tir (the fitted conditions, no more)",
        "",
        "| range | start | fused |",
        "| --- | --- | --- |",
        *[f"| {k} | {a:g} | {b:g} |" for k, (a, b) in result.ranges.items()],
        "",
        "## Operating envelope: which source informed each region",
        "",
        *_envelope_lines(result.envelope),
        "![envelope](envelope.png)",
        "",
        "## The seed paper's figures: simulation against the fused model",
        "",
        *[f"![{t}]({n})" for n, (t, _) in SEED_FIGURES.items()],
        "",
        "The final fit (the rig's levels, the simulation's trends kept) is in "
        "[fit_report.md](fit_report.md); the simulation's own fit in "
        f"[{SIMULATION_DIR}/fit_report.md]({SIMULATION_DIR}/fit_report.md).",
    ]
    if result.notes:
        lines += ["", "Notes: " + "; ".join(result.notes) + "."]
    return "\n".join(lines) + "\n"


def _correction_lines(result: ExtendResult) -> list[str]:
    comp = result.comparison
    rms = comp.rms
    out = []
    if comp.heating_scale is not None:
        span = _span(comp.rig_T) or [comp.T_ambient_C, comp.T_ambient_C]
        out += [
            "Corrected: the rig's tyre heats as it runs and has no temperature channel, the "
            "simulation is isothermal at known set temperatures. The rig's hidden temperature "
            f"takes the shape the diagnosis inferred, scaled by {comp.heating_scale:.3g} with the "
            "simulation's temperature terms: "
            f"{span[0]:.1f} ... {span[1]:.1f} degC from the ambient {comp.T_ambient_C:g} degC.",
            "",
        ]
    else:
        out += ["No hidden temperature to correct (recorded, or none found).", ""]
    if comp.friction is not None:
        fx, fy = comp.friction["LMUX"], comp.friction["LMUY"]
        out += [
            f"Friction: the rig's is {fx:.3f} x (longitudinal) and {fy:.3f} x (lateral) the "
            "simulation's (fitted with the heating's scale). The fused model takes the rig's "
            "friction, so at the force peaks of the seed figures below its lines lie about "
            f"{100 * (fx - 1):+.1f} % (Fx) and {100 * (fy - 1):+.1f} % (Fy) from the "
            "simulation's dots.",
            "",
        ]
    others = [e.name for e in comp.diagnosis.effects if e.name not in ("temperature", "none")]
    if others:
        out += [
            f"Not corrected: {', '.join(others)}. Beyond the rig the simulation's trends are "
            "kept; where the rig reaches, its own levels (below) are fitted.",
            "",
        ]
    out += [
        "| rig - simulation's model, RMS [N] | Fx | Fy |",
        "| --- | --- | --- |",
        *[f"| {k} | {v['Fx']:.1f} | {v['Fy']:.1f} |" for k, v in rms.items()],
        "",
        "Where both reach the rig's recordings set the levels (friction, shifts, aligning "
        "moment, combined slip); the curves' shapes and how they change with load, pressure "
        "and temperature follow the simulation.",
        "",
    ]
    return out


def _sidewall_lines(result: ExtendResult) -> list[str]:
    sw = result.sidewall
    if sw is None or not sw.named:
        return ["No sidewall contact in the simulation.", ""]
    th, a_c, drop = sw.params
    return [
        f"**sidewall_contact** in the simulation: beyond |alpha| = {math.degrees(a_c):.1f} deg "
        f"at a relative deflection above {th:.2f}, Fy falls by {drop:.2f} per rad (the node's "
        f"effects-file form); it removes {sw.rms_before:.0f} -> {sw.rms_after:.0f} N of the "
        f"mismatch on {sw.n_corner} lateral samples. The Magic Formula has no such term: those "
        "samples are left out of the lateral fit.",
        "",
    ]


def _envelope_lines(env: Envelope) -> list[str]:
    counts = {s: sum(1 for v in env.cells.values() if v == s) for s in COLOURS}
    return [
        f"{len(env.cells)} cells of {env.fz_step_N:.0f} N x {env.p_step_Pa / 1e3:g} kPa x "
        f"{env.T_step_K:g} K: "
        + ", ".join(f"{SOURCE_NAMES[s]} {n}" for s, n in counts.items())
        + ". OUT.tir carries them as `[FIT_ENVELOPE]`; `eval` and the node count inputs "
        "outside.",
        "",
    ]


# --- figures --------------------------------------------------------------------------------


def plot_envelope(env: Envelope, model: TireModel, path: Path) -> None:
    """One panel per temperature cell: load against pressure, each cell coloured by source."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch, Rectangle

    temps = sorted({k for _, _, k in env.cells})
    cols = min(4, len(temps))
    rows = math.ceil(len(temps) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.3 * cols, 2.9 * rows + 0.6), squeeze=False)
    fz0 = float(model.params["FNOMIN"])
    for ax, k in zip(axes.ravel(), temps, strict=False):
        for (i, j, kk), s in env.cells.items():
            if kk != k:
                continue
            x0, y0 = (i - 0.5) * env.fz_step_N / fz0 * 100, (j - 0.5) * env.p_step_Pa / 1e3
            ax.add_patch(Rectangle((x0, y0), env.fz_step_N / fz0 * 100, env.p_step_Pa / 1e3,
                                   color=COLOURS[s], alpha=0.8, lw=0))  # fmt: skip
        ax.set_xlim(*_lims(env, 0, 100 / fz0))
        ax.set_ylim(*_lims(env, 1, 1e-3))
        title = "temperature unknown" if env.T_step_K == 0 else f"T = {k * env.T_step_K:g} degC"
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("load Fz [% FNOMIN]")
        ax.set_ylabel("pressure p [kPa gauge]")
    for ax in axes.ravel()[len(temps) :]:
        ax.axis("off")
    handles = [Patch(color=c, label=SOURCE_NAMES[s]) for s, c in COLOURS.items()]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=8)
    fig.suptitle("operating envelope: which source informed each cell", fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 0.96))
    _save(fig, path)
    plt.close(fig)


def _lims(env: Envelope, axis: int, scale: float) -> tuple[float, float]:
    step = (env.fz_step_N, env.p_step_Pa)[axis]
    lo, hi = env.bounds(axis)
    return (lo - step) * scale, (hi + step) * scale


def plot_seed_figure(
    result: ExtendResult, title: str, conditions: Sequence[Condition], path: Path
) -> None:
    """Fx against kappa and Fy against alpha at each condition: simulation dots, fused model
    lines (the sidewall corner's samples hollow: not fitted)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_x, ax_y) = plt.subplots(1, 2, figsize=(11, 4.4))
    hollow = {False: False, True: False}  # per panel: sidewall-corner samples drawn
    for n, cond in enumerate(conditions):
        colour = f"C{n}"
        for ax, lateral in ((ax_x, False), (ax_y, True)):
            hollow[lateral] |= _seed_curve(ax, result, cond, lateral, colour)
    ax_x.set_xlabel("slip ratio kappa [-]")
    ax_x.set_ylabel("longitudinal force Fx [N]")
    ax_y.set_xlabel("slip angle alpha [deg]")
    ax_y.set_ylabel("lateral force Fy [N]")
    from matplotlib.lines import Line2D

    keys = [
        Line2D([], [], color="grey", ls="-", lw=1.5, label="fused model"),
        Line2D([], [], color="grey", ls="", marker=".", label="simulation"),
    ]
    corner_key = Line2D([], [], color="grey", ls="", marker="o", ms=4, mfc="none",
                        label="simulation in the sidewall contact (not fitted)")  # fmt: skip
    for ax, lateral in ((ax_x, False), (ax_y, True)):
        ax.grid(alpha=0.3)
        handles, _ = ax.get_legend_handles_labels()
        ax.legend(handles=[*handles, *keys, *([corner_key] if hollow[lateral] else [])],
                  fontsize=7)  # fmt: skip
    fig.suptitle(f"{title}: simulation (dots) against the fused model (lines)", fontsize=10)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


def _seed_curve(
    ax: Axes, result: ExtendResult, cond: Condition, lateral: bool, colour: str
) -> bool:
    """One condition's simulation samples and model curve; whether sidewall-corner samples
    were drawn (hollow)."""
    model = result.model
    fz0 = float(model.params["FNOMIN"])
    T = nominal_inputs(model)["T"] if cond.T_C is None else cond.T_C
    Fz, p = cond.load * fz0, cond.p_kPa * 1e3
    x, y, corner = _near_samples(result, Fz, p, T, lateral)
    if len(x):
        ax.plot(x[~corner], y[~corner], ".", ms=2.5, color=colour, alpha=0.5)
        if corner.any():
            ax.plot(x[corner], y[corner], "o", ms=3, mfc="none", color=colour, alpha=0.5)
        lim = float(np.max(np.abs(x)))
    else:
        lim = 15.0 if lateral else 0.3
    grid = np.linspace(-lim, lim, 201)
    g = np.radians(grid) if lateral else grid
    zero = np.zeros_like(grid)
    out = model.evaluate(
        np.full_like(grid, Fz), zero if lateral else g, g if lateral else zero, 0.0, None,
        np.full_like(grid, p), np.full_like(grid, T),
    )  # fmt: skip
    label = cond.label + ("" if len(x) else " (model only: no simulation samples)")
    ax.plot(grid, out.Fy if lateral else out.Fx, "-", color=colour, lw=1.5, label=label)
    return bool(len(x) and corner.any())


def _near_samples(
    result: ExtendResult, Fz: float, p: float, T: float, lateral: bool
) -> tuple[F64, F64, npt.NDArray[np.bool_]]:
    """Pure-slip samples of the simulation near a condition: slip (deg for alpha), force,
    and whether each lies in the sidewall corner."""
    fz0 = float(result.model.params["FNOMIN"])
    xs, ys, cs = [], [], []
    for s, corner in zip(result.sim, result.sim_corner, strict=True):
        force = s.Fy if lateral else s.Fx
        if force is None:
            continue
        near = _near(s, Fz, p, T, fz0) & np.isfinite(force)
        near &= (np.abs(s.kappa) < PURE_KAPPA) if lateral else (np.abs(s.alpha) < PURE_ALPHA_RAD)
        idx = np.flatnonzero(near)[:: max(1, int(near.sum()) // MAX_DOTS)]
        xs.append(np.degrees(s.alpha[idx]) if lateral else s.kappa[idx])
        ys.append(force[idx])
        cs.append(corner[idx])
    if not xs:
        return np.zeros(0), np.zeros(0), np.zeros(0, dtype=bool)
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(cs)


def _near(s: WheelSeries, Fz: float, p: float, T: float, fz0: float) -> npt.NDArray[np.bool_]:
    ok = np.abs(s.Fz - Fz) < NEAR[0] * fz0
    if s.p is not None:
        ok &= np.abs(s.p - p) < NEAR[1] * p
    if s.T is not None:
        ok &= np.abs(s.T - T) < NEAR[2]
    out: npt.NDArray[np.bool_] = ok
    return out
