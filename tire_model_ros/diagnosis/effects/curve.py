"""The file model's force curves at each recorded sample: how stiff and how saturated.

Shared by the effects whose physics depends on where on the curve a sample lies (relaxation
lengths shorten as the curve flattens; sidewall contact acts beyond the force peak).
"""

from __future__ import annotations

import numpy as np

from ..prepare import Context
from .base import Array


def curve_shapes(ctx: Context) -> dict[str, Array]:
    """Per sample, from the file's model: the slip stiffness against its value at FNOMIN
    (load shape) and the local slope of the force curve against the slip stiffness (slip
    shape), for alpha and kappa. Computed once per recording."""
    if "curve_shapes" in ctx.cache:
        return ctx.cache["curve_shapes"]  # type: ignore[no-any-return]
    w, m = ctx.wheel, ctx.model
    Fz = np.maximum(w.x("Fz"), 1.0)
    a, k, V = w.x("alpha"), w.x("kappa"), w.x("V")
    ref = m.evaluate(np.array([ctx.base["FNOMIN"]]), 0.0, 0.0, 0.0)
    o = m.evaluate(Fz, 0.0, 0.0, 0.0)
    out: dict[str, Array] = {}
    h = {"alpha": 1e-3, "kappa": 1e-3}
    for key, K_raw, K0_raw, ch in (
        ("alpha", o.Kya, ref.Kya, "Fy"),
        ("kappa", o.Kxk, ref.Kxk, "Fx"),
    ):
        K, K0 = np.abs(np.asarray(K_raw)), abs(float(np.asarray(K0_raw)[0]))
        out[f"load_{key}"] = np.clip(np.nan_to_num(K / max(K0, 1e-9), nan=1.0), 0.05, 3.0)
        hi = {"alpha": a, "kappa": k} | {key: (a if key == "alpha" else k) + h[key]}
        lo = {"alpha": a, "kappa": k} | {key: (a if key == "alpha" else k) - h[key]}
        f_hi = getattr(m.evaluate(Fz, hi["kappa"], hi["alpha"], w.x("gamma"), Vx=V), ch)
        f_lo = getattr(m.evaluate(Fz, lo["kappa"], lo["alpha"], w.x("gamma"), Vx=V), ch)
        slope = np.abs(np.asarray(f_hi) - np.asarray(f_lo)) / (2 * h[key])
        out[f"slip_{key}"] = np.clip(np.nan_to_num(slope / np.maximum(K, 1e-9)), 0.02, 1.5)
    ctx.cache["curve_shapes"] = out
    return out
