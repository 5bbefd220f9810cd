"""Fitting candidate models and choosing among them on held-out whole sweeps.

Residuals are normalised by each channel's noise level, so a score of 1 per sample is "explained
to the noise". Fitting is bounded least squares over the candidate's parameters together with the
baseline scaling factors. Selection is forward stepwise: a candidate joins the model only if, on
sweeps the fit did not see, it beats the current model by a margin relative to the noise, on most
sweeps, and beats its controls (a memoryless variant, a time-scrambled driver, a plain trend).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import binom

from .candidates import Component, Context, predict

# Acceptance guards (false-discovery control); tuned on the virtual rig, see test_diagnosis.py.
MIN_REL_RMSE_GAIN = 0.04  # >= 4 % lower held-out RMSE (noise-normalised, all channels)
MIN_GAIN_PER_SAMPLE = 0.08  # >= 8 % of the noise variance per held-out sample
MIN_SWEEP_FRACTION = 0.6  # better on >= 60 % of the held-out sweeps that change materially
MIN_T_STAT = 0.0  # mean per-segment held-out gain / its standard error (reported; > 0)
MAX_SIGN_P = 0.05  # sign test over the changed held-out segments
MIN_WEIGHTED_FRACTION = 0.8  # ... or >= 80 % of the total change is improvement
MIN_T_ALT = 2.0  # ... with t >= 2
MIN_CONTROL_MARGIN = 0.02  # >= 2 % lower held-out RMSE than each control
OCCAM_MARGIN = 0.02  # a 2-parameter file-shaped effect wins within 2 % of a freer one
# A slow trend is first taken as the tyre's slow (carcass) thermal node, when the heating it
# belongs to passes its controls; wear (never recovering) must then be clearly better.
DRIFT_VS_BULK_MARGIN = 0.15
# A pure delay (one parameter, the same lag at every speed) is preferred to relaxation (lengths
# per direction, lag ~ sigma/V) unless relaxation predicts clearly better.
DELAY_OCCAM_MARGIN = 0.05
MAX_EFFECTS = 4


@dataclass
class Fit:
    components: list[Component]
    x: np.ndarray
    cost: float
    m: int  # residuals
    jac: np.ndarray | None = None
    nfev: int = 0


@dataclass
class Score:
    """Noise-normalised squared residuals on a set of rows."""

    total: float  # sum over channels and rows
    n: int
    per_channel: dict[str, float]  # sum of squared residual [N^2] per channel
    n_channel: dict[str, int]
    per_segment: dict[tuple[int, int], float] = field(default_factory=dict)

    @property
    def rms(self) -> float:
        return float(np.sqrt(self.total / max(self.n, 1)))

    def rmse(self, ch: str) -> float:
        return float(np.sqrt(self.per_channel[ch] / max(self.n_channel[ch], 1)))


def residuals(
    components: list[Component], x: np.ndarray, ctx: Context, rows: list[np.ndarray]
) -> np.ndarray:
    """Stacked (model - measured)/sigma over wheels and channels."""
    parts = []
    for wi, r in enumerate(rows):
        if len(r) == 0:
            continue
        w = ctx.wheels[wi]
        out = predict(components, x, ctx, wi, r)
        for ch in ctx.channels:
            if ch in w.meas:
                parts.append((out[ch] - w.meas[ch][r]) / ctx.sigma[ch])
    return np.concatenate(parts) if parts else np.zeros(0)


def bounds_of(components: list[Component]):
    lo = np.concatenate([np.asarray(c.lo, float) for c in components]) if components else []
    hi = np.concatenate([np.asarray(c.hi, float) for c in components]) if components else []
    return np.asarray(lo), np.asarray(hi)


def fit(
    components: list[Component],
    ctx: Context,
    rows: list[np.ndarray],
    x0: np.ndarray | None = None,
    max_nfev: int = 40,
    held: np.ndarray | None = None,
) -> Fit:
    """Bounded least squares of the components' parameters on ``rows``.

    ``held``: values of the leading parameters, kept as they are (only the rest are fitted;
    ``x0`` and the returned ``Fit.x`` are still the whole vector, ``Fit.jac`` the fitted part's).
    """
    if x0 is None:
        x0 = np.concatenate([np.asarray(c.x0, float) for c in components])
    lo, hi = bounds_of(components)
    x0 = np.clip(np.asarray(x0, float), lo, hi)
    k = 0 if held is None else len(held)
    if held is not None:
        x0[:k] = held
    if len(x0) == k:
        r = residuals(components, x0, ctx, rows)
        return Fit(components, x0, 0.5 * float(r @ r), len(r))
    scale = np.concatenate([np.asarray(c.scale, float) for c in components])[k:]
    lo, hi, head = lo[k:], hi[k:], x0[:k]

    def fun(xt):
        r = residuals(components, np.concatenate([head, xt]), ctx, rows)
        return np.where(np.isfinite(r), r, 1e3)

    def solve(x_start, nfev):
        return least_squares(
            fun,
            x_start,
            bounds=(lo, hi),
            x_scale=scale,
            method="trf",
            ftol=1e-5,
            xtol=1e-5,
            gtol=1e-8,
            max_nfev=nfev,
            diff_step=1e-4,
        )

    starts = [x0[k:]]
    names = [n for c in components for n in c.pnames][k:]
    # Alternative starts of the newest component's non-convex parameter (the others start
    # from the current model's fit).
    for c in components[-1:]:
        for st in c.starts:
            xs = x0[k:].copy()
            for name, v in st.items():
                xs[names.index(name)] = v
            starts.append(np.clip(xs, lo, hi))
    xt = starts[0]
    if len(starts) > 1:
        trial = [solve(xs, max(6, max_nfev // 6)) for xs in starts]
        xt = min(trial, key=lambda r: r.cost).x
    res = solve(xt, max_nfev)
    x = np.concatenate([head, res.x])
    return Fit(components, x, float(res.cost), len(res.fun), res.jac, int(res.nfev))


def score(
    components: list[Component], x: np.ndarray, ctx: Context, rows: list[np.ndarray]
) -> Score:
    """Noise-normalised score on ``rows``, with per-channel and per-segment sums."""
    total, n = 0.0, 0
    per_ch = {ch: 0.0 for ch in ctx.channels}
    n_ch = {ch: 0 for ch in ctx.channels}
    per_seg: dict[tuple[int, int], float] = {}
    for wi, r in enumerate(rows):
        if len(r) == 0:
            continue
        w = ctx.wheels[wi]
        out = predict(components, x, ctx, wi, r)
        z = np.zeros(len(r))
        for ch in ctx.channels:
            if ch not in w.meas:
                continue
            e = out[ch] - w.meas[ch][r]
            e = np.where(np.isfinite(e), e, 1e6)
            per_ch[ch] += float(e @ e)
            n_ch[ch] += len(r)
            z += (e / ctx.sigma[ch]) ** 2
            n += len(r)
        total += float(z.sum())
        seg = w.seg_id[r]
        sums = np.bincount(seg, weights=z, minlength=len(w.segments))
        for s in np.unique(seg):
            per_seg[(wi, int(s))] = float(sums[s])
    return Score(total, n, per_ch, n_ch, per_seg)


def merge(scores: list[Score]) -> Score:
    """One score of several disjoint held-out sets."""
    out = Score(0.0, 0, {}, {}, {})
    for sc in scores:
        out.total += sc.total
        out.n += sc.n
        for ch, v in sc.per_channel.items():
            out.per_channel[ch] = out.per_channel.get(ch, 0.0) + v
            out.n_channel[ch] = out.n_channel.get(ch, 0) + sc.n_channel[ch]
        out.per_segment.update(sc.per_segment)
    return out


def cross_validate(
    components: list[Component],
    ctx: Context,
    splits: list[tuple[list[np.ndarray], list[np.ndarray]]],
    x0s: list[np.ndarray | None],
    current: list[Score] | None = None,
) -> tuple[list[Fit], Score, list[Score]]:
    """Fit on each split's training rows, score on its test rows; scores merged.

    With ``current`` (the current model's score per split), a candidate that does not reach
    half the acceptance margin on the first split is not fitted on the others (screening:
    it cannot pass, and the fits are the cost of the diagnosis).
    """
    fits, scores = [], []
    for i, ((train, test), x0) in enumerate(zip(splits, x0s, strict=True)):
        f = fit(components, ctx, train, x0)
        fits.append(f)
        scores.append(score(components, f.x, ctx, test))
        if (
            current is not None
            and i == 0
            and 1.0 - scores[0].rms / max(current[0].rms, 1e-12) < 0.5 * MIN_REL_RMSE_GAIN
        ):
            break
    merged = merge(scores)
    if current is not None and len(scores) < len(splits):
        # Screened out: mark the unseen split as "no better than the current model".
        for sc in current[len(scores) :]:
            merged = merge([merged, sc])
    return fits, merged, scores


def uncertainty(f: Fit, n_eff_ratio: float) -> np.ndarray:
    """1-sigma parameter uncertainties from the Jacobian, inflated for autocorrelation.

    cov = s^2 (J^T J)^-1 with s^2 = 2 cost / (m - n), times m / n_eff (100 Hz residuals are
    not independent; ``n_eff_ratio`` = n_eff / m).
    """
    n = len(f.x)
    if f.jac is None or n == 0:
        return np.full(n, np.nan)
    J = np.asarray(f.jac)
    s2 = 2.0 * f.cost / max(f.m - n, 1)
    JTJ = J.T @ J
    with np.errstate(all="ignore"):
        cov = np.linalg.pinv(JTJ) * s2 / max(n_eff_ratio, 1e-3)
        sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        # A parameter the data does not move (zero column) has no finite uncertainty.
        dead = np.diag(JTJ) <= 1e-12 * max(float(np.max(np.diag(JTJ))), 1e-300)
    sd[dead] = np.nan
    return sd


@dataclass
class Trial:
    """One candidate tried at one selection step."""

    component: Component
    fits: list[Fit]  # one per cross-validation split
    heldout: Score
    rel_gain: float = 0.0  # 1 - rms_new / rms_current
    gain_per_sample: float = 0.0
    sweep_fraction: float = 0.0
    t_stat: float = 0.0  # per-sweep gains: mean / standard error
    p_sign: float = 1.0  # sign test of the per-sweep gains
    weighted_fraction: float = 0.0  # share of the total per-segment change that improved
    controls: dict[str, float] = field(default_factory=dict)  # control label -> held-out rms
    passed: bool = False
    reason: str = ""  # a note for the evidence (e.g. how the effect's form was chosen)
    split_scores: list[Score] = field(default_factory=list)
    # The components the trial adds: ``component`` and any refinement tried with it.
    parts: list[Component] = field(default_factory=list)


def compare(cur: Score, new: Score) -> tuple[float, float, float, float, float, float]:
    """Held-out comparison of a candidate with the current model.

    Returns (relative RMS gain, gain per sample in noise variances, fraction of the changed
    sweeps that improved, t statistic of the per-sweep gains). Whole sweeps are the units:
    their count, not the row count, is the effective sample size of the test.
    """
    rel = 1.0 - new.rms / max(cur.rms, 1e-12)
    gps = (cur.total - new.total) / max(cur.n, 1)
    a_ = np.array(list(cur.per_segment.values()))
    d = np.array([a - new.per_segment.get(k, a) for k, a in cur.per_segment.items()])
    # A segment counts when its squared error changed materially: by more than one noise
    # variance and by more than 5 % of what it was (noise-level wiggles are not votes).
    changed = d[(np.abs(d) >= 1.0) & (np.abs(d) >= 0.05 * a_)]
    frac = float(np.mean(changed > 0)) if len(changed) else 0.0
    if len(d) >= 3 and np.std(d, ddof=1) > 0:
        t = float(np.mean(d) / (np.std(d, ddof=1) / np.sqrt(len(d))))
    else:
        t = 0.0
    # One-sided sign test over the changed sweeps: P(at least this many better | no effect).
    k, n = int(np.sum(changed > 0)), len(changed)
    p = float(binom.sf(k - 1, n, 0.5)) if n else 1.0
    # Weighted by size: the share of the total change that is improvement.
    wfrac = float(np.sum(np.clip(changed, 0, None)) / np.sum(np.abs(changed))) if n else 0.0
    return rel, gps, frac, t, p, wfrac


def passes(trial: Trial) -> bool:
    return (
        len(trial.fits) > 1
        and trial.rel_gain >= MIN_REL_RMSE_GAIN
        and trial.gain_per_sample >= MIN_GAIN_PER_SAMPLE
        and trial.sweep_fraction >= MIN_SWEEP_FRACTION
        and trial.t_stat >= MIN_T_STAT
        # Significant over the segments: most of them better (sign test), or the improvement
        # dominating by size and consistent (t statistic) where a crude model of a large
        # effect also moves many segments a little the wrong way.
        and (
            trial.p_sign <= MAX_SIGN_P
            or (trial.weighted_fraction >= MIN_WEIGHTED_FRACTION and trial.t_stat >= MIN_T_ALT)
        )
    )
