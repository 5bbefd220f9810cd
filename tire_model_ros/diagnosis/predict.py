"""The predictor: the file's model with a list of effect models composed on top of it."""

from __future__ import annotations

import functools
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


def session_inputs(
    models: Sequence[EffectModel], x: Array, ctx: Context
) -> dict[str, Array | None]:
    """The session's inputs (every sample) after every effect's ``inputs``."""
    inp = dict(ctx.wheel.inputs)
    for m, xm in zip(models, split_x(models, x), strict=True):
        m.inputs(xm, ctx, inp)
    return inp


def model_inputs(
    models: Sequence[EffectModel], x: Array, ctx: Context, rows: Index
) -> tuple[dict[str, Array | None], Array | None]:
    """The model's inputs at ``rows`` after every effect's transformations, and the friction
    scale there. What acts on each sample alone is computed at the rows only (a fit's rows
    are a tenth of the session's): the states first, then the slips they scale, in the same
    order whichever effect came first."""
    xs = split_x(models, x)
    inp = session_inputs(models, x, ctx)
    at: dict[str, Array | None] = {k: None if v is None else v[rows] for k, v in inp.items()}
    for m, xm in zip(models, xs, strict=True):
        m.per_sample(xm, ctx, at, rows)
    s = None
    for m, xm in zip(models, xs, strict=True):
        mu = m.mu_scale(xm, ctx, rows)
        if mu is not None:
            s = mu if s is None else s * mu
    return at, s


def predict(
    models: Sequence[EffectModel],
    x: Array,
    ctx: Context,
    rows: Index,
    channels: Sequence[str] = ("Fx", "Fy", "Mz"),
) -> dict[str, Array]:
    """Model forces and aligning moment at sample indices ``rows`` for parameters ``x``
    (``channels`` without Mz: the forces alone, the aligning stage not run)."""
    args, s = model_inputs(models, x, ctx, rows)
    out = evaluate(ctx.model, coefficients(models, x, ctx), args, s, "Mz" in channels)
    for m, xm in zip(models, split_x(models, x), strict=True):
        m.output(xm, ctx, out, rows)
    return out


def evaluate(
    model: TireModel,
    upd: dict[str, float],
    a: dict[str, Array | None],
    s: Array | None,
    moments: bool = True,
) -> dict[str, Array]:
    """Fx, Fy (and Mz with ``moments``) of ``model`` with the coefficient updates ``upd`` at
    the inputs ``a``.

    A friction scale ``s`` per sample acts by the similarity method (Pacejka 2012 §4.3.2):
    F = s F0(kappa / s, tan(alpha) / s), the slip stiffnesses kept.
    """
    kappa, alpha, Fz, gamma, V = a["kappa"], a["alpha"], a["Fz"], a["gamma"], a["V"]
    assert kappa is not None and alpha is not None
    assert Fz is not None and gamma is not None and V is not None
    if s is not None:
        s = np.maximum(s, MIN_MU_SCALE)
        kappa, alpha = kappa / s, np.arctan(np.tan(alpha) / s)
    m = updated(model, tuple(upd.items())) if upd else model
    o = m.evaluate(Fz, kappa, alpha, gamma, Vx=V, p=a["p"], T=a["T"], full=False, moments=moments)
    out = {"Fx": np.asarray(o.Fx), "Fy": np.asarray(o.Fy)}
    if moments:
        out["Mz"] = np.asarray(o.Mz)
    if s is not None:
        out = {ch: v * s for ch, v in out.items()}
    return out


@functools.lru_cache(maxsize=16)
def updated(model: TireModel, upd: tuple[tuple[str, float], ...]) -> TireModel:
    """``model`` with the coefficient updates ``upd``, remembered: a fit's difference columns
    of parameters that are not coefficients repeat the same updates, and building and
    checking a model costs as much as evaluating it on a fold."""
    return model.with_params(dict(upd))
