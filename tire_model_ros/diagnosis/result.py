"""From the engine's selection to what a user gets: the improved model refitted on every
training sweep, its aligning moment, the figures on the final held-out sweeps, the words.

Per wheel a :class:`WheelDiagnosis`; a recording of several wheels (a car) is summarised in
:class:`Diagnosis` (``diagnose`` in :mod:`.engine`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tire_model_ros.model import TireModel
from tire_model_ros.model.states import WheelEffects
from tire_model_ros.recording.series import WheelSeries

from . import evidence as ev
from .effects.base import Array, EffectModel, Index, Mask
from .effects.static import Camber
from .fitting import fit, residuals, uncertainty
from .locate import channel_summary, where_text
from .predict import coefficients, predict, session_inputs, split_x
from .prepare import Context, prepare_wheel
from .search import Selection, held

FINAL_MAX_NFEV = 80
# The aligning moment's trail and residual-torque coefficients (MF 6.1 base and load terms, as
# the fit's Mz0 stage) with their scales; the camber terms where camber varies.
MZ_COEFS = {"QBZ1": 1.0, "QCZ1": 0.1, "QDZ1": 0.01, "QEZ1": 0.1, "QHZ1": 1e-3, "QDZ6": 1e-3,
            "QBZ10": 0.05, "QBZ2": 0.1, "QDZ2": 0.01, "QDZ7": 1e-3}  # fmt: skip
MZ_CAMBER_COEFS = {"QBZ4": 0.1, "QBZ5": 0.1, "QDZ3": 0.1, "QDZ4": 0.5, "QDZ8": 0.05,
                   "QDZ9": 0.05, "QDZ10": 0.1, "QDZ11": 0.1, "QEZ5": 0.5, "QHZ3": 0.01,
                   "QHZ4": 0.01}  # fmt: skip
MZ_MIN_CORR = 0.5  # the measured Mz must follow the model's this well to be refitted to


@dataclass
class Effect:
    """One named effect (INTERFACE.md word) with its fitted parameters."""

    name: str
    concealed: bool
    channel: str
    where: str
    evidence: str
    parameters: dict[str, float] = field(default_factory=dict)
    uncertainty: dict[str, float] = field(default_factory=dict)
    explained: float | None = None  # share of the baseline's held-out MSE of Fx and Fy
    wheels: list[str] = field(default_factory=list)  # in a summary: where it was found

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "name": self.name,
            "concealed": bool(self.concealed),
            "channel": self.channel,
            "where": self.where,
            "evidence": self.evidence,
            "parameters": {k: _num(v) for k, v in self.parameters.items()},
            "uncertainty": {k: _num(v) for k, v in self.uncertainty.items()},
        }
        if self.explained is not None:
            out["explained"] = _num(self.explained)
        if self.wheels:
            out["wheels"] = list(self.wheels)
        return out


def _num(v: float) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


class MzRefit(EffectModel):
    """The aligning moment's trail and residual-torque coefficients, refitted on a model's
    forces (they do not enter Fx or Fy)."""

    word = "baseline"
    label = "Mz trail and residual torque"

    def __init__(self, ctx: Context, coefs: dict[str, float]):
        from .effects.base import coefficient_params

        super().__init__(coefficient_params(ctx, list(coefs), list(coefs.values()), span=50.0))

    def coef(self, x: Array, ctx: Context) -> dict[str, float]:
        return {k: ctx.base[k] + float(v) for k, v in zip(self.pnames, x, strict=True)}


@dataclass
class WheelDiagnosis:
    """One wheel's diagnosis."""

    prefix: str
    effects: list[Effect]
    fit: dict[str, Any]
    improved_model: TireModel
    baseline_model: TireModel
    predictions: dict[str, Array]
    inferred: dict[str, Array]
    train_mask: Array
    heldout_mask: Array
    sweeps: list[Index]
    log: list[str]
    ctx: Context
    baseline: tuple[list[EffectModel], Array]
    improved: tuple[list[EffectModel], Array]
    sigma: dict[str, float] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"effects": [e.to_json() for e in self.effects], "fit": self.fit}

    def node_effects(self) -> tuple[WheelEffects, list[str]]:
        """What the node's effects file carries of this wheel, and the labels it cannot."""
        models, x = self.improved
        kw: dict[str, Any] = {}
        not_carried = []
        for m, xm in zip(models, split_x(models, x), strict=True):
            part = m.carry(xm, self.ctx)
            if part is None:
                not_carried.append(f"{m.word}: {m.label}")
            else:
                kw.update(part)
        return WheelEffects(**kw), not_carried


def finish(prefix: str, sel: Selection) -> WheelDiagnosis:
    """Refit one wheel's chosen model on all its training sweeps and report on its final
    held-out fold."""
    trial = sel.final.wheels[prefix]
    log: list[str]
    ctx, log = trial.ctx, []  # this wheel's own notes (the selection's log is the recording's)
    w, rows_ab = ctx.wheel, ctx.rows["ab"]
    log.append(
        "inputs smoothed (zero-phase, window chosen per channel by cross-validation, shortened "
        "where the file model's forces ask): "
        + ", ".join(f"{k} {n} samples" for k, n in w.smoothing.items())
    )
    if w.dropped:
        log.append(f"not finite on any sample, taken as not recorded: {', '.join(w.dropped)}")
    if w.gaps:
        log.append(
            "inputs not finite, bridged linearly in time and left out of fitting and scoring: "
            + ", ".join(f"{k} {n} samples" for k, n in w.gaps.items())
        )
    models = trial.models
    # a tyre effect keeps the parameters it was fitted with to every wheel
    free = held(models, sel.final.shared)
    x0 = _final_start(models, ctx, rows_ab, [f.x for f in trial.fits], free)
    final = fit(models, ctx, rows_ab, x0, max_nfev=FINAL_MAX_NFEV, free=free)
    base = sel.baseline.wheels[prefix].models
    base_fit = fit(base, ctx, rows_ab, x0[: base[0].n])
    base_m, xb = _with_mz(ctx, base, base_fit.x, log)
    imp_m, xi = _with_mz(ctx, models, final.x, log, start=(base_m, xb))
    full = ctx.rows["all"]
    pb, pi = predict(base_m, xb, ctx, full), predict(imp_m, xi, ctx, full)
    preds = {}
    for ch in ctx.all_channels:
        preds[f"baseline_{ch}"], preds[f"improved_{ch}"] = pb[ch], pi[ch]
    resid = {ch: w.meas[ch] - pb[ch] for ch in ctx.all_channels}
    inp = session_inputs(models, final.x, ctx)
    inferred = {"E_f": w.E.copy()}
    for m, xm in zip(models, split_x(models, final.x), strict=True):
        inferred.update(m.inferred(xm, ctx, inp))
    summaries = {ch: channel_summary(ctx, resid, ch) for ch in ctx.all_channels}
    sd = uncertainty(final, ev.n_eff_ratio(residuals(models, final.x, ctx, rows_ab)))
    by_key = {(type(m).__name__, m.label): m for m in models[1:]}
    effects = [
        _effect(ctx, sel, models, final.x, sd, by_key[k], k) for k in sel.chosen if k in by_key
    ] or [_none(ctx, summaries)]
    wd = WheelDiagnosis(
        prefix=w.prefix,
        effects=effects,
        fit={},
        improved_model=ctx.model.with_params(coefficients(imp_m, xi, ctx)),
        baseline_model=ctx.model.with_params(coefficients(base_m, xb, ctx)),
        predictions=preds,
        inferred=inferred,
        train_mask=w.fold != 2,
        heldout_mask=w.fold == 2,
        sweeps=[s.index for s in w.segments],
        log=log,
        ctx=ctx,
        baseline=(base_m, xb),
        improved=(imp_m, xi),
        sigma=dict(ctx.sigma),
        summary=summaries,
    )
    wd.fit = fit_json_pooled([wd])
    return wd


def _final_start(
    models: Sequence[EffectModel], ctx: Context, rows: Index, xs: Sequence[Array], free: Mask
) -> Array:
    """Where the final refit starts: the mean of the selection folds' fits, or either fit's
    own parameters (a tyre effect's held ones always the mean, one set for every wheel),
    whichever fits the training sweeps best. The mean of two fits of a non-convex model (a
    thermal node's time constant and its grip law) can be far from both: a car wheel's
    final model started there ended worse than its baseline (unseen car multi2_a, seed 25:
    held-out 55 -> 164 N)."""
    mean = np.asarray(np.mean(xs, axis=0), dtype=np.float64)
    starts = [mean] + [np.where(free, x, mean) for x in xs]
    costs = [float(np.sum(residuals(models, x, ctx, rows) ** 2)) for x in starts]
    return starts[int(np.argmin(costs))]


def _effect(
    ctx: Context,
    sel: Selection,
    models: list[EffectModel],
    x: Array,
    sd: Array,
    m: EffectModel,
    key: tuple[str, str],
) -> Effect:
    k = next(i for i, mm in enumerate(models) if mm is m)
    xs, sds = split_x(models, x), split_x(models, sd)
    params, unc = m.reported(xs[k], ctx), dict(zip(m.pnames, map(float, sds[k]), strict=True))
    delta = _contribution(ctx, models, x, m)
    ch = max(ctx.channels, key=lambda c: float(np.nanmean(delta[c] ** 2)))
    info = channel_summary(ctx, delta, ch)
    where = where_text(info, ch, f"change made by the {m.word} model") if info else ch
    explained = sel.explained_per_wheel.get(key, {}).get(ctx.wheel.prefix, math.nan)
    parts = [
        f"{m.label}: explains {explained:.0%} of the baseline's held-out mean square error "
        "of Fx and Fy"
    ]
    tr = sel.accepted.get(key)
    if tr is not None and tr.vs is not None:
        parts.append(
            f"noise-normalised held-out RMS gain {tr.vs.rel_gain:.1%} when added, better on "
            f"{tr.vs.block_fraction:.0%} of the changed held-out sweeps (sign test p = "
            f"{tr.vs.p_sign:.2g}, t = {tr.vs.t_stat:.1f}; {tr.vs.weighted_fraction:.0%} of "
            "their change is improvement), two-way cross-validation on whole sweeps"
        )
        parts += tr.notes
    names = [n for n in m.pnames if n in params][:6]  # a guide's, handed over, is not
    shown = [f"{n} = {params[n]:.4g} +- {unc.get(n, math.nan):.2g}" for n in names]
    parts.append("; ".join(shown))
    return Effect(m.word, m.concealed, ch, where, "; ".join(parts), params, unc, explained)


def _none(ctx: Context, summaries: dict[str, dict[str, Any]]) -> Effect:
    worst = max(ctx.channels, key=lambda c: summaries[c].get("rmse", 0) / ctx.sigma[c])
    return Effect(
        "none",
        False,
        worst,
        where_text(summaries[worst], worst),
        "no model of missing physics beat the baseline on held-out sweeps by the margins "
        f"(>= {ev.MIN_EXCESS_SHARE:.0%} of its mean square error beyond the noise, "
        f">= {ev.MIN_GAIN_PER_SAMPLE:.0%} of the noise variance per sample, on most sweeps or "
        "by a consistent gain that dominates the change) and "
        "passed its evidence tests",
    )


def _contribution(
    ctx: Context, models: list[EffectModel], x: Array, m: EffectModel
) -> dict[str, Array]:
    """What ``m`` changes in the model's output: with it minus without it, every sample."""
    keep = [i for i, mm in enumerate(models) if mm is not m]
    xs = split_x(models, x)
    rows = ctx.rows["all"]
    a = predict(models, x, ctx, rows, ctx.channels)
    b = predict(
        [models[i] for i in keep], np.concatenate([xs[i] for i in keep]), ctx, rows, ctx.channels
    )
    return {ch: a[ch] - b[ch] for ch in ctx.channels}


def _with_mz(
    ctx: Context,
    models: list[EffectModel],
    x: Array,
    log: list[str],
    start: tuple[list[EffectModel], Array] | None = None,
) -> tuple[list[EffectModel], Array]:
    """``models`` plus the Mz coefficients refitted to the measured Mz, the forces held.

    Mz is left out of the selection (its trail and residual torque follow the forces, so it
    would count a force effect twice), but a model whose forces changed needs its Mz refitted
    on them. ``start``: another model with its Mz refit, whose Q*Z values are a second start
    (the trail's shape is not convex). A measured Mz that does not follow the model's (a wrench
    whose torques are not measured) is left alone, and so are the Q*Z.
    """
    if "Mz" in ctx.channels or "Mz" not in ctx.all_channels:
        return models, x
    rows = ctx.rows["ab"]
    r = _mz_correlation(ctx, models, x, rows)
    if not r >= MZ_MIN_CORR:
        log.append(f"Mz not refitted: the measured Mz does not follow the model's (r = {r:.2f})")
        return models, x
    coefs = dict(MZ_COEFS)
    if Camber.propose(ctx):
        coefs.update(MZ_CAMBER_COEFS)
    mz = MzRefit(ctx, coefs)
    if not mz.n:
        return models, x
    if start is not None and isinstance(start[0][-1], MzRefit):
        mz.starts.append(dict(zip(mz.pnames, start[1][-start[0][-1].n :], strict=True)))
    on_mz = dataclasses.replace(ctx, channels=("Mz",))
    free = np.concatenate([np.zeros(len(x), bool), np.ones(mz.n, bool)])
    f = fit([*models, mz], on_mz, rows, np.concatenate([x, mz.x0]), max_nfev=30, free=free)
    return [*models, mz], f.x


def _mz_correlation(ctx: Context, models: list[EffectModel], x: Array, rows: Index) -> float:
    a = ctx.wheel.meas["Mz"][rows]
    b = predict(models, x, ctx, rows)["Mz"]
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3 or np.std(a[ok]) == 0 or np.std(b[ok]) == 0:
        return 0.0
    return float(np.corrcoef(a[ok], b[ok])[0, 1])


def fit_json_pooled(items: Sequence[Any]) -> dict[str, Any]:
    """INTERFACE.md's ``fit`` block: RMSE (and NRMSE) on the training and held-out samples,
    pooled over ``items`` (each with ``.ctx`` and ``.predictions``: the wheels)."""
    kinds = ("baseline", "improved", "heldout_baseline", "heldout_improved")
    out: dict[str, Any] = {k: {} for k in kinds}
    for ch in ("Fx", "Fy", "Mz"):
        acc = {k: [0.0, 0] for k in kinds}
        spans = []
        for it in items:
            w = it.ctx.wheel
            if ch not in w.meas or f"baseline_{ch}" not in it.predictions:
                continue
            m = w.meas[ch]
            spans.append(float(np.nanmax(m) - np.nanmin(m)))
            for which, mask in (("", w.fold != 2), ("heldout_", w.fold == 2)):
                for kind in ("baseline", "improved"):
                    e = (it.predictions[f"{kind}_{ch}"] - m)[mask]
                    e = e[np.isfinite(e)]
                    acc[which + kind][0] += float(e @ e)
                    acc[which + kind][1] += len(e)
        if not spans:
            continue
        span = max(spans)
        for k, (ss, n) in acc.items():
            rmse = math.sqrt(ss / n) if n else math.nan
            out[k][ch] = {"rmse": _num(rmse)}
            if not k.startswith("heldout"):
                out[k][ch]["nrmse"] = _num(rmse / span) if span > 0 else None
    return out


def set_noise(ctx: Context) -> None:
    """Noise level per channel from the file model's residual (high-pass, robust)."""
    from .locate import residual_sigma

    w = ctx.wheel
    out = predict([], np.zeros(0), ctx, ctx.rows["all"])
    for ch in ctx.all_channels:
        r = w.meas[ch] - out[ch]
        span = float(np.nanmax(w.meas[ch]) - np.nanmin(w.meas[ch]))
        ctx.sigma[ch] = max(residual_sigma(r), 1e-3 * span, 1e-6)


def reference_context(wd: WheelDiagnosis, twin: WheelSeries) -> Context:
    """A context of the twin recording with the diagnosed wheel's sweeps and folds, and only
    the channels the diagnosed recording has: a twin's true pressure or temperature, which
    the recording conceals, would reach the models as an input the diagnosis never had (the
    file's pressure terms run on a concealed leak's true pressure), and what a model does
    with it would count as its error."""
    ctx = wd.ctx
    w = ctx.wheel
    if len(twin.t) != w.n or not np.allclose(twin.t - twin.t[0], w.t, atol=1e-6):
        raise ValueError(f"{w.prefix}: reference recording does not match the samples")
    seen = dataclasses.replace(
        twin,
        p=None if w.inputs["p"] is None else twin.p,
        T=None if w.inputs["T"] is None else twin.T,
    )
    # prepared alike: the recording's own smoother windows
    r = prepare_wheel(seen, ctx.model, np.random.default_rng(0), w.smoothing)
    r = dataclasses.replace(
        r,
        segments=w.segments,
        blocks=w.blocks,
        block_id=w.block_id,
        fold=w.fold,
        scramble=w.scramble,
        bridged=w.bridged,
    )
    ref = dataclasses.replace(ctx, wheel=r, cache={})
    return ref


def floor(
    measured: Sequence[Context],
    twins: Sequence[Context],
    on_recorded: Sequence[dict[str, Array]],
    on_true: Sequence[dict[str, Array]],
) -> dict[str, Any]:
    """Held-out RMSE of the true physics on the recording, per channel [N, N m].

    The sensor noise on the forces (the twin's true forces against the measured ones) and on
    the inputs (a model replayed on the recorded inputs against the same model on the true
    ones: the improved model stands in for the true physics' slip stiffness), added as
    independent variances. Both input sets are prepared alike (smoothed), so the second term
    is the noise the smoother leaves, not what it takes from the true inputs: where they move
    fast (a car's load transfer, its wheel slip) a perfect model scores a little above the
    floor (realities/car seed 41 null_2: the file model is the car's tyre exactly, on its
    smoothed true inputs 7 N off its true forces, held-out 23.3 N against a 22.0 N floor).
    """
    out = {}
    for ch in ("Fx", "Fy", "Mz"):
        acc = np.zeros((2, 2))
        for m, t, a, b in zip(measured, twins, on_recorded, on_true, strict=True):
            if ch not in m.wheel.meas or ch not in t.wheel.meas or f"improved_{ch}" not in a:
                continue
            held = (m.wheel.fold == 2) & ~m.wheel.bridged
            pairs = (
                (t.wheel.meas[ch] - m.wheel.meas[ch]),
                a[f"improved_{ch}"] - b[f"improved_{ch}"],
            )
            for k, e in enumerate(pairs):
                e = e[held]
                e = e[np.isfinite(e)]
                acc[k] += (float(e @ e), len(e))
        if acc[0, 1] and acc[1, 1]:
            out[ch] = {"rmse": _num(math.sqrt(acc[0, 0] / acc[0, 1] + acc[1, 0] / acc[1, 1]))}
    return out
