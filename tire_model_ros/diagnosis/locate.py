"""Where the mismatch sits: channels, time spans, slip range, load, sweep direction, energy.

All statistics are on the residual r = measured - model of the baseline (the file's model with
its scaling factors refitted), reasoned per sweep where it matters: autocorrelated 100 Hz rows
are not independent, so every count is also given as an effective sample size.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..fit.sweeps import noise_sigma
from .prepare import Array, Context

PAUSE_KINDS = ("pause",)


def residual_sigma(r: Array) -> float:
    """White-noise level of a residual (:func:`noise_sigma`); plain std for very short ones."""
    r = r[np.isfinite(r)]
    if len(r) < 8:
        return float(np.std(r)) if len(r) else 0.0
    return noise_sigma(r)


def n_effective(r: Array) -> float:
    """Effective sample size n (1 - rho1) / (1 + rho1) from the lag-1 autocorrelation."""
    r = r[np.isfinite(r)] - np.nanmean(r)
    n = len(r)
    if n < 3 or float(r @ r) == 0.0:
        return float(n)
    rho = float(r[1:] @ r[:-1]) / float(r @ r)
    rho = min(max(rho, 0.0), 0.999)
    return n * (1.0 - rho) / (1.0 + rho)


def _span(t: Array) -> str:
    return f"t = {t[0]:.0f}-{t[-1]:.0f} s" if len(t) else "nowhere"


def channel_summary(ctx: Context, resid: dict[str, Array], ch: str) -> dict[str, Any]:
    """Numbers and words locating the residual ``resid[ch]`` of one channel."""
    slip_key = "alpha" if ch in ("Fy", "Mz") else "kappa"
    unit = "deg" if slip_key == "alpha" else ""
    r_all: list[Array]
    slip_all: list[Array]
    seg_rms: list[float]
    out_back: dict[str, list[float]]
    e_seg: list[tuple[float, float]]
    fz_all: list[Array]
    v_all: list[Array]
    r_all, slip_all, seg_rms, seg_t, out_back = [], [], [], [], {"out": [], "back": []}
    e_seg, fz_all, v_all = [], [], []
    for w in [ctx.wheel]:
        if ch not in w.meas or ch not in resid:
            continue
        r = resid[ch]
        slip = w.x(slip_key)
        r_all.append(r)
        slip_all.append(np.abs(slip))
        fz_all.append(w.x("Fz"))
        v_all.append(w.x("V"))
        sgn = np.sign(w.meas[ch])
        for seg in w.segments:
            idx = seg.index
            rr = r[idx]
            seg_rms.append(float(np.sqrt(np.nanmean(rr**2))))
            seg_t.append((w.t[idx[0]], w.t[idx[-1]]))
            d = seg.direction.get(slip_key)
            if seg.kind == "ramp" and d is not None:
                grow = d * np.sign(np.nanmedian(slip[idx]))  # +1: |slip| increasing ("out")
                big = np.abs(slip[idx]) > 0.3 * np.nanmax(np.abs(slip))
                if big.any():
                    key = "out" if grow > 0 else "back"
                    # r * sign(F) > 0: measured stronger than the model.
                    out_back[key].append(np.nanmean((rr * sgn[idx])[big]))
            if seg.kind != "pause":
                e_seg.append((w.E[idx[0]], float(np.nanmean(rr * sgn[idx]))))
    if not r_all:
        return {}
    r = np.concatenate(r_all)
    slip = np.concatenate(slip_all)
    sigma = ctx.sigma[ch]
    rmse = float(np.sqrt(np.nanmean(r**2)))
    info: dict[str, Any] = {"rmse": rmse, "sigma": sigma, "n": len(r), "n_eff": n_effective(r)}
    # Time span of the sweeps whose residual is clearly above the noise.
    rms = np.asarray(seg_rms)
    hot = np.flatnonzero(rms > max(2.0 * sigma, 0.5 * np.max(rms)))
    if len(hot):
        info["time"] = (
            f"t = {seg_t[hot[0]][0]:.0f}-{seg_t[hot[-1]][1]:.0f} s "
            f"({len(hot)} of {len(seg_rms)} segments)"
        )
    # Slip range holding most of the squared residual.
    edges = np.quantile(slip, np.linspace(0, 1, 6))
    idx = np.clip(np.searchsorted(edges, slip, side="right") - 1, 0, 4)
    ms = np.array([np.nanmean(r[idx == b] ** 2) if np.any(idx == b) else np.nan for b in range(5)])
    b = int(np.nanargmax(ms))
    scale = np.degrees(1.0) if unit == "deg" else 1.0
    others = np.delete(ms, b)
    low = np.sqrt(np.nanmean(others)) if np.isfinite(others).any() else float("nan")
    info["slip"] = (
        f"largest at |{slip_key}| {edges[b] * scale:.2f}-{edges[b + 1] * scale:.2f}{unit} "
        f"(rms {np.sqrt(ms[b]):.0f} N vs {low:.0f} N at other slip)"
    )
    fz = np.concatenate(fz_all)
    if np.ptp(fz) > 0.1 * np.mean(np.abs(fz)):
        lo = fz < np.median(fz)
        info["load"] = (
            f"rms {np.sqrt(np.nanmean(r[lo] ** 2)):.0f} below / "
            f"{np.sqrt(np.nanmean(r[~lo] ** 2)):.0f} above Fz = {np.median(fz):.0f} N"
        )
    if out_back["out"] and out_back["back"]:
        o, k = float(np.mean(out_back["out"])), float(np.mean(out_back["back"]))
        info["out_back"] = (o, k)
        word = "weaker" if k < o else "stronger"
        info["direction"] = f"way back {word} than way out by {abs(k - o):.0f} N"
    if len(e_seg) >= 4:
        e, m = np.asarray(e_seg).T
        if np.std(e) > 0 and np.std(m) > 0:
            info["energy_corr"] = float(np.corrcoef(e, m)[0, 1])
    zero = np.concatenate(
        [
            (np.abs(w.x("kappa")) < 5e-3) & (np.abs(w.x("alpha")) < np.radians(0.3))
            for w in [ctx.wheel]
            if ch in w.meas
        ]
    )
    if zero.sum() > 20:
        info["zero_slip_mean"] = float(np.nanmean(r[zero]))
    return info


def where_text(info: dict[str, Any], ch: str, what: str = "residual") -> str:
    """A sentence saying where the mismatch (or an effect's part of the model) sits."""
    if not info:
        return f"{ch}: not recorded"
    parts = [f"{ch} {what}"]
    for key in ("time", "slip", "direction", "load"):
        if key in info:
            parts.append(info[key])
    if "energy_corr" in info:
        parts.append(f"sweep mean vs energy put in before it: r = {info['energy_corr']:+.2f}")
    if "zero_slip_mean" in info and abs(info["zero_slip_mean"]) > 2 * info["sigma"]:
        parts.append(f"mean {info['zero_slip_mean']:+.0f} N at zero slip")
    parts.append(
        f"{what} rms {info['rmse']:.0f} vs noise {info['sigma']:.0f}, "
        f"n_eff {info['n_eff']:.0f} of {info['n']}"
    )
    return "; ".join(parts)
