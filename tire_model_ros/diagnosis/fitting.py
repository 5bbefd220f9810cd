"""Fitting a composed model on some rows and scoring it on others.

Residuals are normalised by each channel's noise level, so a score of 1 per sample is
"explained to the noise". Fits are bounded least squares (trust-region reflective) over every
model's parameters, from the current model's values plus the newest model's alternative
starts (its non-convex directions, e.g. a time constant).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from .effects.base import Array, EffectModel, Index, Mask
from .predict import predict, split_x
from .prepare import Context

MAX_NFEV = 40
DIFF_STEP = 1e-4  # relative forward-difference step of the Jacobians
BAD_RESIDUAL = 1e3  # a non-finite model output counts as this many noise sigmas


@dataclass
class Fit:
    models: list[EffectModel]
    x: Array
    cost: float  # half the sum of squared normalised residuals
    m: int  # number of residuals
    jac: Array | None = None  # of the free parameters
    free: Mask | None = None  # the parameters that were fitted (None: all)


@dataclass
class Score:
    """Normalised squared residuals on a set of rows, per channel [N^2] and per block."""

    total: float  # sum over channels and rows, noise units
    n: int
    sse: dict[str, float]  # sum of squared residual per channel [N^2 or (N m)^2]
    count: dict[str, int]
    per_block: dict[tuple[str, int], float] = field(default_factory=dict)  # (wheel, block)

    @property
    def rms(self) -> float:
        return float(np.sqrt(self.total / max(self.n, 1)))

    def rmse(self, ch: str) -> float:
        return float(np.sqrt(self.sse[ch] / max(self.count[ch], 1)))

    def mse_forces(self) -> float:
        """Mean square error of Fx and Fy together [N^2] (INTERFACE.md's ``explained``)."""
        ss = sum(self.sse.get(ch, 0.0) for ch in ("Fx", "Fy"))
        nn = sum(self.count.get(ch, 0) for ch in ("Fx", "Fy"))
        return ss / max(nn, 1)


def errors(models: Sequence[EffectModel], x: Array, ctx: Context, rows: Index) -> dict[str, Array]:
    """Model minus measured per fitted channel at ``rows`` [N or N m] (non-finite: huge)."""
    out = predict(models, x, ctx, rows, ctx.channels)
    w = ctx.wheel
    e = {}
    for ch in ctx.channels:
        d = out[ch] - w.meas[ch][rows]
        e[ch] = np.where(np.isfinite(d), d, BAD_RESIDUAL * ctx.sigma[ch])
    return e


def residuals(models: Sequence[EffectModel], x: Array, ctx: Context, rows: Index) -> Array:
    """Stacked normalised residuals over the fitted channels, and the models' penalties."""
    e = errors(models, x, ctx, rows)
    parts = [e[ch] / ctx.sigma[ch] for ch in ctx.channels]
    i = 0
    for m in models:
        parts.append(m.penalty(np.asarray(x[i : i + m.n], dtype=np.float64), ctx))
        i += m.n
    return np.concatenate(parts)


def bounds(models: Sequence[EffectModel]) -> tuple[Array, Array]:
    lo = np.array([p.lo for m in models for p in m.params], dtype=np.float64)
    hi = np.array([p.hi for m in models for p in m.params], dtype=np.float64)
    return lo, hi


def _fitted(models: Sequence[EffectModel]) -> Mask:
    """Per parameter: whether a fit moves it (the others are set by ``settle``)."""
    return np.array([p.fitted for m in models for p in m.params], dtype=bool)


def _stages(models: Sequence[EffectModel]) -> npt.NDArray[np.int64]:
    """Per parameter: its stage (``Param.stage``)."""
    return np.array([p.stage for m in models for p in m.params], dtype=np.int64)


def _scales(models: Sequence[EffectModel]) -> Array:
    """Per parameter: its typical scale (the optimiser's x_scale)."""
    return np.array([p.scale for m in models for p in m.params], dtype=np.float64)


def fit(
    models: Sequence[EffectModel],
    ctx: Context,
    rows: Index,
    x0: Array | None = None,
    max_nfev: int = MAX_NFEV,
    free: Mask | None = None,
    stage: int = 0,
) -> Fit:
    """Bounded least squares of the models' parameters on ``rows``, then each model settled
    on them (``EffectModel.settle``).

    ``free``: which parameters are fitted (None: all that are ``fitted``); the others keep
    their ``x0`` values (``Fit.x`` is always the whole vector). Alternative starts are those of
    the last model. Models with refinements are fitted in two stages (``Param.stage``; the
    second from the first's handover, without alternative starts).
    """
    models = list(models)
    if x0 is None:
        x0 = np.concatenate([m.x0 for m in models]) if models else np.zeros(0)
    lo, hi = bounds(models)
    x0 = np.clip(np.asarray(x0, float), lo, hi)
    free = np.ones(len(x0), dtype=bool) if free is None else np.asarray(free, dtype=bool)
    free = free & _fitted(models)
    stages = _stages(models)
    if stage == 0 and (stages[free] == 2).any():  # a guide first, then its refinement
        first = fit(models, ctx, rows, x0, max_nfev, free & (stages != 2), 1)
        x1 = np.concatenate(
            [m.handover(xm, ctx) for m, xm in zip(models, split_x(models, first.x), strict=True)]
        )
        return fit(models, ctx, rows, x1, max_nfev, free & (stages != 1), 2)
    if not free.any():
        r = residuals(models, x0, ctx, rows)
        return Fit(models, x0, 0.5 * float(r @ r), len(r), free=free)
    scale = _scales(models)[free]

    def full(xt: Array) -> Array:
        x = x0.copy()
        x[free] = xt
        return x

    def fun(xt: Array) -> Array:
        return residuals(models, full(xt), ctx, rows)

    names = [p.name for m in models for p in m.params]
    starts = models[-1].starts if stage < 2 else []
    res = _least_squares(fun, x0, free, lo, hi, scale, names, starts, max_nfev)
    # a model whose parameters were all held here (a tyre's, settled on every wheel) keeps them
    x = settle(models, full(res.x), [(ctx, rows)])
    parts = zip(
        split_x(models, x),
        split_x(models, x0),
        split_x(models, free.astype(np.float64)),
        strict=True,
    )
    x = np.concatenate([xs if f.any() else xk for xs, xk, f in parts])
    return Fit(models, x, float(res.cost), len(res.fun), res.jac, free)


def fit_shared(
    parts: Sequence[tuple[Sequence[EffectModel], Context, Index, Array, Mask]],
    max_nfev: int = MAX_NFEV,
) -> list[Fit]:
    """One parameter vector of the last model of every part fitted to all their rows at once
    (a tyre's effect on the wheels of a car), with each part's own free parameters (its
    baseline); each part is (models, context, rows, the other models' parameters, which of
    them are free). Returns each part's fit (the shared parameters not ``free`` in it)."""
    e = parts[0][0][-1]
    if _stages([e]).any():
        raise ValueError(f"{e}: a tyre's shared effect is fitted in one stage")
    lo_e, hi_e = bounds([e])
    x0_e = np.clip(e.x0, lo_e, hi_e)
    free_e = _fitted([e])
    heads = []  # per part: the other models' start, free mask, bounds and scales
    for ms, _, _, xh, fh in parts:
        lo, hi = bounds(ms[:-1])
        fh = np.asarray(fh, bool) & _fitted(ms[:-1])
        heads.append((np.clip(np.asarray(xh, float), lo, hi), fh, lo, hi, _scales(ms[:-1])))
    x0 = np.concatenate([x0_e[free_e]] + [xh[fh] for xh, fh, *_ in heads])
    lo = np.concatenate([lo_e[free_e]] + [lo[fh] for _, fh, lo, _, _ in heads])
    hi = np.concatenate([hi_e[free_e]] + [hi[fh] for _, fh, _, hi, _ in heads])
    scale = np.concatenate([_scales([e])[free_e]] + [sc[fh] for _, fh, _, _, sc in heads])
    cuts = np.cumsum([int(free_e.sum())] + [int(fh.sum()) for _, fh, *_ in heads])

    def vectors(xt: Array) -> list[Array]:
        th = x0_e.copy()
        th[free_e] = xt[: cuts[0]]
        out = []
        for k, (xh, fh, *_) in enumerate(heads):
            x = xh.copy()
            x[fh] = xt[cuts[k] : cuts[k + 1]]
            out.append(np.concatenate([x, th]))
        return out

    def part(k: int, xt: Array) -> Array:
        ms, ctx, rows, _, _ = parts[k]
        return residuals(ms, vectors(xt)[k], ctx, rows)

    last: list[tuple[Array, list[Array]]] = []  # the latest point and its residuals per part

    def per_part(xt: Array) -> list[Array]:
        if not last or not np.array_equal(last[0][0], xt):
            last[:] = [(xt.copy(), [part(k, xt) for k in range(len(parts))])]
        return last[0][1]

    def fun(xt: Array) -> Array:
        return np.concatenate(per_part(xt))

    columns = [[*range(cuts[0]), *range(cuts[k], cuts[k + 1])] for k in range(len(parts))]

    def jac(xt: Array) -> Array:
        return block_jacobian(part, per_part(xt), xt, lo, hi, columns)

    # the starts name the shared parameters; the wheels' own are not named
    names = [p.name for p, f in zip(e.params, free_e, strict=True) if f]
    names += [""] * (len(x0) - len(names))
    every = np.ones(len(x0), bool)
    res = _least_squares(fun, x0, every, lo, hi, scale, names, e.starts, max_nfev, jac)
    fits = []
    seen = [(ctx, rows) for _, ctx, rows, _, _ in parts]
    for (ms, ctx, rows, _, _), x, (_, fh, *_) in zip(parts, vectors(res.x), heads, strict=True):
        r = residuals(ms, x, ctx, rows)
        free = np.concatenate([fh, np.zeros(e.n, bool)])
        # the wheel's own models settle on its rows, the tyre's shared one on every wheel's
        k = len(x) - e.n
        x = np.concatenate([settle(ms[:-1], x[:k], [(ctx, rows)]), e.settle(x[k:], seen)])
        fits.append(Fit(list(ms), x, 0.5 * float(r @ r), len(r), None, free))
    return fits


def block_jacobian(
    part: Callable[[int, Array], Array],
    r0: Sequence[Array],
    x: Array,
    lo: Array,
    hi: Array,
    columns: Sequence[Sequence[int]],
) -> Array:
    """Forward-difference Jacobian of stacked residual parts, part ``k`` (``part(k, x)``, at
    ``x``: ``r0[k]``) differenced only in the ``columns[k]`` it depends on (a wheel's own
    parameters move its residuals only): a car's tyre fit pays for each wheel's baseline once,
    not once per wheel. The other entries are zero."""
    h = _forward_steps(x, lo, hi)
    J = np.zeros((sum(len(r) for r in r0), len(x)))
    row = 0
    for k, r in enumerate(r0):
        for j in columns[k]:
            xj = x.copy()
            xj[j] += h[j]
            J[row : row + len(r), j] = (part(k, xj) - r) / h[j]
        row += len(r)
    return J


def _forward_steps(x: Array, lo: Array, hi: Array) -> Array:
    """Forward-difference steps as scipy's least squares takes them with ``diff_step``: DIFF_STEP
    of |x| (sqrt(eps) max(1, |x|) where that is no step), turned back where the step would
    leave the bounds, else shortened to the farther bound; exactly representable."""
    sign = np.where(x >= 0, 1.0, -1.0)
    h = DIFF_STEP * sign * np.abs(x)
    h = np.where(
        (x + h) - x == 0, np.sqrt(np.finfo(float).eps) * sign * np.maximum(1.0, np.abs(x)), h
    )
    up, down = hi - x, x - lo
    fits = np.abs(h) <= np.maximum(up, down)
    h = np.where(((x + h < lo) | (x + h > hi)) & fits, -h, h)
    h = np.where(fits, h, np.where(up >= down, up, -down))
    return (x + h) - x


def _least_squares(  # type: ignore[no-untyped-def]
    fun, x0: Array, free: Mask, lo: Array, hi: Array, scale: Array, names: list[str],
    starts: Sequence[dict[str, float]], max_nfev: int, jac=None,
):  # fmt: skip
    """Trust-region reflective least squares of the ``free`` entries of ``x0``, from the
    best of ``x0`` and the alternative ``starts`` (each briefly tried first); ``jac``: the
    Jacobian's own function (None: forward differences of every column)."""

    def solve(x_start: Array, nfev: int):  # type: ignore[no-untyped-def]
        return least_squares(
            fun,
            x_start,
            jac="2-point" if jac is None else jac,
            bounds=(lo[free], hi[free]),
            x_scale=scale,
            method="trf",
            ftol=1e-5,
            xtol=1e-5,
            gtol=1e-8,
            max_nfev=nfev,
            diff_step=DIFF_STEP,
        )

    tries = [x0[free]]
    for st in starts:
        xs = x0.copy()
        for name, v in st.items():
            if name in names and free[names.index(name)]:
                xs[names.index(name)] = v
        xs = np.clip(xs, lo, hi)[free]
        if not any(np.array_equal(xs, xo) for xo in tries):  # a start met twice is tried once
            tries.append(xs)
    xt = tries[0]
    if len(tries) > 1:
        trial = [solve(xs, max(6, max_nfev // 6)) for xs in tries]
        xt = min(trial, key=lambda r: r.cost).x
    return solve(xt, max_nfev)


def settle(models: Sequence[EffectModel], x: Array, seen: Sequence[tuple[Context, Index]]) -> Array:
    """``x`` after every model's ``settle`` on the rows it was fitted on."""
    out, i = [], 0
    for m in models:
        out.append(m.settle(np.asarray(x[i : i + m.n], dtype=np.float64), seen))
        i += m.n
    return np.concatenate(out) if out else np.asarray(x, dtype=np.float64)


def squared_z(e: dict[str, Array], ctx: Context) -> Array:
    """Per row: the squared errors ``e`` in noise units, summed over the channels."""
    return np.asarray(sum((e[ch] / ctx.sigma[ch]) ** 2 for ch in ctx.channels), dtype=np.float64)


def score(models: Sequence[EffectModel], x: Array, ctx: Context, rows: Index) -> Score:
    """Normalised score on ``rows``, with per-channel and per-block sums."""
    w = ctx.wheel
    e = errors(models, x, ctx, rows)
    z = squared_z(e, ctx) if ctx.channels else np.zeros(len(rows))
    sse = {ch: float(e[ch] @ e[ch]) for ch in ctx.channels}
    count = dict.fromkeys(ctx.channels, len(rows))
    sums = np.bincount(w.block_id[rows], weights=z, minlength=len(w.blocks))
    per_block = {(w.prefix, int(b)): float(sums[b]) for b in np.unique(w.block_id[rows])}
    return Score(float(z.sum()), len(rows) * len(ctx.channels), sse, count, per_block)


def merge(scores: Sequence[Score]) -> Score:
    """One score of several disjoint held-out sets. A block held out in parts (a rare sweep
    seen in one block only: its way out in one fold, its way back in the other) sums them."""
    out = Score(0.0, 0, {}, {}, {})
    for sc in scores:
        out.total += sc.total
        out.n += sc.n
        for ch, v in sc.sse.items():
            out.sse[ch] = out.sse.get(ch, 0.0) + v
            out.count[ch] = out.count.get(ch, 0) + sc.count[ch]
        for k, v in sc.per_block.items():
            out.per_block[k] = out.per_block.get(k, 0.0) + v
    return out


def uncertainty(f: Fit, n_eff_ratio: float) -> Array:
    """1-sigma uncertainties of the free parameters (NaN for the others) from the Jacobian,
    inflated for autocorrelation: cov = s^2 (J^T J)^-1 m / n_eff, s^2 = 2 cost / (m - n)."""
    sd = np.full(len(f.x), np.nan)
    if f.jac is None:
        return sd
    J = np.asarray(f.jac)
    k = J.shape[1]
    s2 = 2.0 * f.cost / max(f.m - k, 1)
    JTJ = J.T @ J
    with np.errstate(all="ignore"):
        cov = np.linalg.pinv(JTJ) * s2 / max(n_eff_ratio, 1e-3)
        part = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        # A parameter the data do not move (a zero column) has no finite uncertainty.
        dead = np.diag(JTJ) <= 1e-12 * max(float(np.max(np.diag(JTJ))), 1e-300)
    part[dead] = np.nan
    sd[np.ones(len(f.x), dtype=bool) if f.free is None else f.free] = part
    return sd
