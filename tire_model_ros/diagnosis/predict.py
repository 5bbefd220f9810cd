"""The predictor: the file's model with a list of effect models composed on top of it."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from tire_model_ros.model import TireModel

from .effects.base import Array, EffectModel, Index
from .prepare import Context

MIN_MU_SCALE = 0.05  # as the node's effect states (model.states)


def split_x(models: Sequence[EffectModel], x: Array) -> list[Array]:
    """``x`` cut into each model's parameters."""
    out, i = [], 0
    for m in models:
        out.append(np.asarray(x[i : i + m.n], dtype=np.float64))
        i += m.n
    return out


def coefficients(models: Sequence[EffectModel], x: Array, ctx: Context) -> dict[str, float]:
    """The .tir coefficient updates of ``models`` at ``x``."""
    upd: dict[str, float] = {}
    for m, xm in zip(models, split_x(models, x), strict=True):
        upd.update(m.coef(xm, ctx))
    return upd


def model_inputs(
    models: Sequence[EffectModel], x: Array, ctx: Context
) -> tuple[dict[str, Array | None], Array | None]:
    """The model's inputs after every effect's transformation, and the friction scale."""
    inp = dict(ctx.wheel.inputs)
    xs = split_x(models, x)
    for m, xm in zip(models, xs, strict=True):
        m.inputs(xm, ctx, inp)
    s = None
    for m, xm in zip(models, xs, strict=True):
        mu = m.mu_scale(xm, ctx)
        if mu is not None:
            s = mu if s is None else s * mu
    return inp, s


def predict(models: Sequence[EffectModel], x: Array, ctx: Context, rows: Index) -> dict[str, Array]:
    """Model forces and aligning moment at sample indices ``rows`` for parameters ``x``."""
    inp, s = model_inputs(models, x, ctx)
    args: dict[str, Array | None] = {k: None if v is None else v[rows] for k, v in inp.items()}
    out = evaluate(ctx.model, coefficients(models, x, ctx), args, None if s is None else s[rows])
    for m, xm in zip(models, split_x(models, x), strict=True):
        m.output(xm, ctx, out, rows)
    return out


def evaluate(
    model: TireModel, upd: dict[str, float], a: dict[str, Array | None], s: Array | None
) -> dict[str, Array]:
    """Fx, Fy, Mz of ``model`` with the coefficient updates ``upd`` at the inputs ``a``.

    A friction scale ``s`` per sample acts by the similarity method (Pacejka 2012 §4.3.2):
    F = s F0(kappa / s, tan(alpha) / s), the slip stiffnesses kept.
    """
    kappa, alpha, Fz, gamma, V = a["kappa"], a["alpha"], a["Fz"], a["gamma"], a["V"]
    assert kappa is not None and alpha is not None
    assert Fz is not None and gamma is not None and V is not None
    if s is not None:
        s = np.maximum(s, MIN_MU_SCALE)
        kappa, alpha = kappa / s, np.arctan(np.tan(alpha) / s)
    m = model.with_params(upd) if upd else model
    o = m.evaluate(Fz, kappa, alpha, gamma, Vx=V, p=a["p"], T=a["T"], full=False)
    out = {"Fx": np.asarray(o.Fx), "Fy": np.asarray(o.Fy), "Mz": np.asarray(o.Mz)}
    if s is not None:
        out = {ch: v * s for ch, v in out.items()}
    return out
