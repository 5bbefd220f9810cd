"""The selection engine: forward selection of effect models on held-out whole sweeps.

Start from the baseline (the file's model, scaling factors refitted). At each step every
model of the library not yet in (one per word) is added in turn and cross-validated on the two
selection folds; those that beat the current model significantly are ranked by held-out score
(the simplest first among near-ties), and the first one the evidence tests believe joins
(:mod:`.evidence`: support, stability, controls). Then every chosen effect must still earn its
place against the others (backward step), and each is credited with what it explains: the
share of the baseline's held-out mean square error of Fx and Fy that the model loses without it.
No rule here names an effect.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from . import evidence as ev
from .effects.base import Array, EffectModel, Index, Mask
from .fitting import Fit, Score, fit, merge, score
from .predict import predict
from .prepare import Context

MAX_EFFECTS = 5
OCCAM_MARGIN = 0.02  # held-out RMS within 2 % of the best: the fewer parameters win


@dataclass
class Trial:
    """A composed model cross-validated on the two selection folds."""

    models: list[EffectModel]
    fits: list[Fit]  # one per split (trained on fold a, on fold b)
    score: Score  # held-out score, both splits merged
    split_scores: list[Score]
    vs: ev.Comparison | None = None  # against the model it was built from
    notes: list[str] = field(default_factory=list)  # what the evidence tests found

    @property
    def effect(self) -> EffectModel:
        return self.models[-1]


@dataclass
class Selection:
    """The engine's result: the chosen effects, strongest first, and how it got there."""

    baseline: Trial
    final: Trial
    chosen: list[EffectModel]  # strongest first
    explained: dict[int, float]  # id(effect) -> share of the baseline's held-out MSE
    accepted: dict[int, Trial]  # id(effect) -> the trial that admitted it
    log: list[str]


def splits(ctx: Context) -> list[tuple[Index, Index]]:
    return [(ctx.rows["a"], ctx.rows["b"]), (ctx.rows["b"], ctx.rows["a"])]


def cross_validate(
    models: Sequence[EffectModel],
    ctx: Context,
    x0s: Sequence[Array | None],
    free: Mask | None = None,
    screen: Trial | None = None,
) -> Trial:
    """Fit on each split's training fold, score on its test fold.

    With ``screen`` (the current model), a model that does not reach half the least gain on
    the first split is not fitted on the second (it cannot pass; the fits are the cost).
    """
    fits, scores = [], []
    for i, ((train, test), x0) in enumerate(zip(splits(ctx), x0s, strict=True)):
        f = fit(models, ctx, train, x0, free=free)
        fits.append(f)
        scores.append(score(models, f.x, ctx, test))
        if screen is not None and i == 0:
            gain = 1.0 - scores[0].rms / max(screen.split_scores[0].rms, 1e-12)
            if gain < 0.5 * ev.MIN_REL_RMSE_GAIN:
                fits.append(f)
                scores.append(screen.split_scores[1])  # "no better than the current model"
                break
    return Trial(list(models), fits, merge(scores), scores)


def add(cur: Trial, e: EffectModel, ctx: Context, everything: bool = False) -> Trial:
    """``cur`` plus ``e``: the new parameters and the baseline's fitted, the earlier effects'
    held (``everything``: all fitted)."""
    models = [*cur.models, e]
    free = None
    if not everything:
        n_base, n_prev = cur.models[0].n, sum(m.n for m in cur.models[1:])
        free = np.concatenate([np.ones(n_base, bool), np.zeros(n_prev, bool), np.ones(e.n, bool)])
    x0s = [np.concatenate([f.x, e.x0]) for f in cur.fits]
    t = cross_validate(models, ctx, x0s, free, screen=None if everything else cur)
    t.vs = ev.compare(cur.score, t.score)
    return t


def without(cur: Trial, e: EffectModel, ctx: Context) -> Trial:
    """``cur`` with ``e`` taken out and the rest refitted."""
    keep = [i for i, m in enumerate(cur.models) if m is not e]
    offsets = np.cumsum([0] + [m.n for m in cur.models])
    cols = np.concatenate([np.arange(offsets[i], offsets[i + 1]) for i in keep])
    return cross_validate([cur.models[i] for i in keep], ctx, [f.x[cols] for f in cur.fits])


def search(ctx: Context, baseline: EffectModel, pool: Sequence[EffectModel]) -> Selection:
    """Forward selection over ``pool``, then the backward step; see the module text."""
    log: list[str] = []
    base = cross_validate([baseline], ctx, [None, None])
    cur = base
    accepted: dict[int, Trial] = {}
    for step in range(MAX_EFFECTS):
        words = {m.word for m in cur.models}
        trials = [add(cur, e, ctx) for e in pool if e.word not in words]
        for t in trials:
            assert t.vs is not None
            log.append(f"step {step}: {t.effect!r} held-out {t.score.rms:.3f} "
                       f"(current {cur.score.rms:.3f}) {t.vs.text()}")  # fmt: skip
        best = next((t for t in _ranked(trials) if _believed(t, cur, ctx, log)), None)
        if best is None:
            break
        full = add(cur, best.effect, ctx, everything=True)  # every parameter refitted
        full.vs, full.notes = best.vs, best.notes
        cur = full if full.score.rms <= best.score.rms else best
        accepted[id(cur.effect)] = cur
        log.append(f"accepted {cur.effect!r}")
    cur, explained = _backward(cur, base, ctx, log)
    chosen = sorted(cur.models[1:], key=lambda m: -explained[id(m)])
    return Selection(base, cur, chosen, explained, accepted, log)


def _ranked(trials: Sequence[Trial]) -> list[Trial]:
    """The significant trials, best held-out first, the fewest parameters first among those
    within OCCAM_MARGIN of the best."""
    ok = sorted(
        (t for t in trials if t.vs is not None and t.vs.significant), key=lambda t: t.score.rms
    )
    if not ok:
        return []
    near = [t for t in ok if t.score.rms <= ok[0].score.rms * (1.0 + OCCAM_MARGIN)]
    near.sort(key=lambda t: (t.effect.n, t.score.rms))
    return near + [t for t in ok if t not in near]


def _believed(t: Trial, cur: Trial, ctx: Context, log: list[str]) -> bool:
    """The evidence tests of :mod:`.evidence` beyond significance, cheapest first."""
    e = t.effect
    for test in (_support, _stability, _controls):
        ok, note = test(t, cur, ctx)
        if note:
            t.notes.append(note)
        if not ok:
            log.append(f"rejected {e!r}: {note}")
            return False
    return True


def _support(t: Trial, cur: Trial, ctx: Context) -> tuple[bool, str]:
    mask = t.effect.support(ctx)
    if mask is None:
        return True, ""
    tests = [test for _, test in splits(ctx)]
    rel, share, n_in = ev.region_gains(ctx, cur.fits, t.fits, tests, mask)
    ok = ev.supported(rel, share, n_in)
    return ok, (f"held-out gain {rel:+.1%} where it acts ({n_in} samples), {share:.0%} of its "
                "whole gain made there")  # fmt: skip


def _doing(f: Fit, e: EffectModel, ctx: Context, rows: Index) -> Array:
    """What ``e`` (the last model of ``f``) does to the forces at ``rows``: the model with it
    minus the model without it, stacked over the channels in noise units."""
    xe = f.x[: len(f.x) - e.n]
    a, b = predict(f.models, f.x, ctx, rows), predict(f.models[:-1], xe, ctx, rows)
    return np.concatenate([(a[ch] - b[ch]) / ctx.sigma[ch] for ch in ctx.channels])


def _stability(t: Trial, cur: Trial, ctx: Context) -> tuple[bool, str]:
    """The effect does the same to the forces when fitted on the two folds, and on the early
    and on the late half of the session (its parameters may trade off; what it does may not)."""
    e = t.effect
    if not e.stable:
        return True, ""
    rows = ctx.rows["ab"]
    pairs = [("the two folds", t.fits)]
    if e.stable_in_time:
        t_mid = float(np.median(ctx.wheel.t[rows]))
        halves = [rows[ctx.wheel.t[rows] < t_mid], rows[ctx.wheel.t[rows] >= t_mid]]
        x0 = np.mean([f.x for f in t.fits], axis=0)
        free = t.fits[0].free
        pairs.append(
            ("the early and the late half", [fit(t.models, ctx, h, x0, free=free) for h in halves])
        )
    notes = []
    for what, (fa, fb) in pairs:
        da, db = _doing(fa, e, ctx, rows), _doing(fb, e, ctx, rows)
        size, diff = ev.rms(0.5 * (da + db)), ev.rms(da - db)
        notes.append(f"{diff:.2f} apart on {what} for {size:.2f} done")
        if not ev.agree_doing(size, diff):
            return (
                False,
                f"what it does differs between {what} ({diff:.2f} vs {size:.2f} done, noise units)",
            )
    return (
        True,
        "constant over the session: fitted apart it does the same to the forces ("
        + ", ".join(notes)
        + ")",
    )


def _controls(t: Trial, cur: Trial, ctx: Context) -> tuple[bool, str]:
    """It predicts held-out sweeps better than each of its controls, fitted the same way."""
    out = []
    for c in t.effect.controls(ctx):
        rms = add(cur, c, ctx).score.rms
        out.append(f"{c.label} {rms:.3f}")
        if t.score.rms > rms * (1.0 - ev.MIN_CONTROL_MARGIN):
            return False, f"not better than {c.label} ({t.score.rms:.3f} vs {rms:.3f})"
    if not out:
        return True, ""
    return (
        True,
        f"beats its controls: {', '.join(out)} vs {t.score.rms:.3f} (held-out RMS, noise units)",
    )


def _backward(
    cur: Trial, base: Trial, ctx: Context, log: list[str]
) -> tuple[Trial, dict[int, float]]:
    """Drop any effect the others make redundant; credit each what the model loses without it."""
    while True:
        explained: dict[int, float] = {}
        drop = None
        for e in cur.models[1:]:
            wo = without(cur, e, ctx)
            vs = ev.compare(wo.score, cur.score)
            explained[id(e)] = (wo.score.mse_forces() - cur.score.mse_forces()) / max(
                base.score.mse_forces(), 1e-12
            )
            if not vs.significant and drop is None:
                drop = (e, wo, vs)
        if drop is None:
            return cur, explained
        e, wo, vs = drop
        log.append(f"dropped {e!r}: the others explain it ({vs.text()})")
        cur = wo
