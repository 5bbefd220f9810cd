"""Mismatch diagnosis: replay, locate, name and model the physics a fit leaves out.

1. Replay the recording's inputs through the model; r = measured - model (Fx, Fy, Mz).
2. Locate the mismatch (channels, time, slip, load, direction, energy put in) on whole sweeps.
3.-4. Try one model per candidate effect (``candidates.py``) on top of the baseline (the file's
   model with its scaling factors refitted); keep, step by step, the candidate that best predicts
   sweeps the fit did not see, if it passes the false-discovery guards (``selection.py``).
5. Refit the chosen model on all training sweeps and report on a third set of sweeps that neither
   the fits nor the selection saw.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import savgol_filter

from tire_model_ros.fit.sweeps import split_segments
from tire_model_ros.model.states import Effects, WheelEffects

from . import candidates as cd
from . import selection as sel
from .locate import channel_summary, residual_sigma, where_text
from .thermal import cumulative_work_J, frictional_power_W

FIT_ROWS_PER_FOLD = 1500  # model rows per fold used by the fits (100 Hz rows are redundant)
MIN_SEGMENTS = 6
INPUT_SMOOTH_S = 0.09  # window of the zero-phase input smoother [s]
ZERO_ALPHA = np.radians(1.0)  # |alpha| below this (and |kappa| < 0.01) counts as zero slip
# Rare sweeps each selection fold keeps before one goes to the final held-out fold: the MF
# pressure terms are quadratic (two per side), a fit needs two levels off nominal.
MIN_RARE_PER_FOLD = 2
# The two folds' readings of an offset at rest must agree within this many standard errors;
# stricter than the early/late and cold/hot tests (MIN_T_ALT): the readings come from two
# differently fitted models, whose differences add to the sweeps' scatter (a real ply-steer
# offset on lateral_sweeps read 2.1 standard errors apart).
OFFSET_FOLDS_Z = 3.0
# An offset read at rest smaller than this many noise sigmas is not told apart from the
# zero-slip force that the other effects' fits leave (the rig's grip scales its zero-slip
# force, the TTX/TTY terms do not: 25-35 N on a 6.7 kN tyre, sigma 21 N).
OFFSET_MIN_SIGMA = 2.0
# An offset's reading may differ early/late or cold/hot by this share of its size before the
# difference (if also significant) says that it is not a constant.
OFFSET_REL_TOL = 0.25
# The two selection folds' friction steps must agree in size within this factor (_step_agrees).
STEP_SIZE_RATIO = 2.0
# A hidden tread node whose fitted time constant reaches this share of its upper bound has found
# no heating of seconds (``_tread_found``).
TREAD_TAU_FOUND = 0.9
REST_KAPPA, REST_ALPHA = 0.002, np.radians(0.2)  # slip at rest: where an offset is read
# Share of a combined-slip candidate's held-out improvement that must come from the samples
# where both slips are non-zero (the only place its terms act).
MIN_COMBINED_SHARE = 0.7


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

    def to_json(self) -> dict:
        return {
            "name": self.name,
            "concealed": bool(self.concealed),
            "channel": self.channel,
            "where": self.where,
            "evidence": self.evidence,
            "parameters": {k: _num(v) for k, v in self.parameters.items()},
            "uncertainty": {k: _num(v) for k, v in self.uncertainty.items()},
        }


def _num(v: float) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


@dataclass
class Diagnosis:
    effects: list[Effect]
    fit: dict
    improved_model: object
    baseline_model: object
    predictions: dict[str, dict[str, np.ndarray]]
    inferred: dict[str, dict[str, np.ndarray]]
    train_mask: dict[str, np.ndarray]
    heldout_mask: dict[str, np.ndarray]
    sweeps: dict[str, list[np.ndarray]]
    details: dict = field(default_factory=dict)  # selection log, timings (for reports)
    # (context, components, parameters) of the baseline and of the improved model
    models: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        """The INTERFACE.md diagnosis object."""
        return {"effects": [e.to_json() for e in self.effects], "fit": self.fit}

    def node_effects(self, tir: str = "") -> Effects:
        """The improved model's effects that a forward model runs per wheel (the node's
        effects file, :mod:`tire_model_ros.model.states`), and the labels of those it cannot
        (a friction step, wear, a delay, relaxation)."""
        ctx = self.models["ctx"]
        comps, x = self.models["improved"]
        xs = cd.split_x(comps, x)
        wheels, not_carried = {}, []
        for wi, w in enumerate(ctx.wheels):
            kw: dict = {}
            for c, xc in zip(comps, xs, strict=True):
                part = c.carry(xc, ctx, wi)
                if part is None:
                    not_carried.append(f"{c.name}: {c.label}")
                else:
                    kw.update(part)
            wheels[w.prefix] = WheelEffects(**kw)
        return Effects(wheels, tir, tuple(dict.fromkeys(not_carried)))

    def score_reference(self, wheels: Sequence) -> dict:
        """Held-out RMSE of the baseline and improved models against a twin recording.

        ``wheels`` is a second recording of the same session, sample for sample (for the
        virtual rig: its noise-free twin, true inputs and true forces). Both fitted models are
        replayed on its inputs (hidden states driven by its own forces) and compared with its
        forces on the samples held out here: the model error without the sensor noise.

        Returns
        -------
        {"heldout_baseline": {ch: {"rmse": N}}, "heldout_improved": {...}} as in ``fit``, and
        "heldout_floor": the held-out RMSE that the true physics itself would score on the
        diagnosed recording (see ``_floor``).

        Raises
        ------
        ValueError
            A wheel is missing or its samples do not match the diagnosed recording's.
        """
        ctx = self.models["ctx"]
        by_prefix = {s.prefix: s for s in wheels}
        ws = []
        for w in ctx.wheels:
            s = by_prefix.get(w.prefix)
            if s is None or len(s.t) != w.n or not np.allclose(s.t - s.t[0], w.t, atol=1e-6):
                raise ValueError(f"{w.prefix}: reference recording does not match the samples")
            r = _prepare_wheel(s, ctx.model, np.random.default_rng(0))
            r.fold, r.scramble = w.fold, w.scramble
            ws.append(r)
        ref = dataclasses.replace(ctx, wheels=ws)
        preds = {}
        for wi, w in enumerate(ws):
            rows = np.arange(w.n)
            preds[w.prefix] = {}
            for kind in ("baseline", "improved"):
                comps, x = self.models[kind]
                out = cd.predict(comps, x, ref, wi, rows)
                preds[w.prefix].update({f"{kind}_{ch}": out[ch] for ch in w.meas})
        fit = _fit_json(ref, ws, preds)
        out = {k: fit[k] for k in ("heldout_baseline", "heldout_improved")}
        on_recorded, on_true = (
            [{ch: p[w.prefix][f"improved_{ch}"] for ch in w.meas} for w in ws]
            for p in (self.predictions, preds)
        )
        out["heldout_floor"] = _floor(ctx.wheels, ws, on_recorded, on_true)
        return out


# --- preparation ------------------------------------------------------------------------------


def _fill(x: np.ndarray) -> np.ndarray:
    """Missing samples of an optional channel take the channel's median (never NaN)."""
    ok = np.isfinite(x)
    if ok.all():
        return x
    return np.where(ok, x, np.median(x[ok]) if ok.any() else 0.0)


def _smooth(x: np.ndarray, t: np.ndarray, window_s: float = INPUT_SMOOTH_S) -> np.ndarray:
    """Zero-phase Savitzky-Golay smoothing of a recorded input (no lag, ramps kept exact).

    Recorded slip carries sensor noise; through the slip stiffness it is as large as the force
    noise. Left in, any candidate that low-passes the inputs (relaxation, a fractional delay)
    would gain by denoising rather than by physics. A zero-phase filter takes that away from all
    candidates alike without shifting anything in time.
    """
    dts = np.diff(t)
    dt = float(np.median(dts[dts > 0])) if np.any(dts > 0) else 1.0
    w = round(window_s / dt) | 1
    if w < 5 or len(x) <= w:
        return x
    return savgol_filter(x, w, 2, mode="interp")


def _prepare_wheel(s, model, rng: np.random.Generator) -> cd.Wheel:
    n = len(s.t)
    if n < 50:
        raise ValueError(f"{s.prefix}: only {n} samples, too few to diagnose")
    P = model.params
    V = _fill(np.asarray(s.Vx, float)) if s.Vx is not None else np.full(n, float(P["LONGVL"]))
    meas = {}
    for ch in cd.CHANNELS:
        v = getattr(s, ch)
        if v is not None and np.isfinite(v).mean() > 0.5:
            meas[ch] = np.where(np.isfinite(v), v, np.nan)
    if not meas:
        raise ValueError(f"{s.prefix}: no measured Fx, Fy or Mz")
    t = np.asarray(s.t, float) - float(s.t[0])
    inputs = {
        "kappa": _smooth(np.nan_to_num(s.kappa), t),
        "alpha": _smooth(np.nan_to_num(s.alpha), t),
        "gamma": _smooth(np.nan_to_num(s.gamma), t),
        "Fz": _smooth(np.nan_to_num(s.Fz), t),
        "V": _smooth(V, t),
        "p": None if s.p is None else _fill(np.asarray(s.p, float)),
        "T": None if s.T is None else _fill(np.asarray(s.T, float)),
    }
    Pw = frictional_power_W(
        np.nan_to_num(meas.get("Fx", np.zeros(n))),
        np.nan_to_num(meas.get("Fy", np.zeros(n))),
        V,
        inputs["kappa"],
        inputs["alpha"],
    )
    Vs = np.abs(V) * np.hypot(inputs["kappa"], np.tan(inputs["alpha"]))
    segments = split_segments(s)
    if len(_blocks(segments, np.asarray(s.t, float) - float(s.t[0]))) < MIN_SEGMENTS:
        # Too few sweeps for sweep-wise validation: fall back to equal time blocks.
        from tire_model_ros.fit.sweeps import Segment

        segments = [Segment(idx, "steady", {}) for idx in np.array_split(np.arange(n), 9)]
    # Scores are kept per segment (ramp, steady part, pause): the segments, not the rows, are
    # the units of the significance test (folds are whole sweeps, see _assign_folds).
    seg_id = np.empty(n, dtype=np.int64)
    for i, seg in enumerate(segments):
        seg_id[seg.index] = i
    fold = _assign_folds(segments, t, rng, inputs)
    order = rng.permutation(len(segments))
    scramble = np.concatenate([segments[i].index for i in order])
    return cd.Wheel(
        s.prefix,
        t,
        inputs,
        meas,
        Pw,
        cumulative_work_J(Pw, t),
        Vs,
        segments,
        seg_id,
        fold,
        scramble,
    )


def _blocks(segments, t: np.ndarray) -> list[list[int]]:
    """Whole sweeps: runs of segments between pauses (a long run is cut near 15 s pieces).

    The unit of validation is the sweep, not the ramp: the way out and the way back of one
    sweep stay together, so a held-out sweep tests the model's within-sweep dynamics too.
    """
    blocks: list[list[int]] = []
    cur: list[int] = []
    for i, seg in enumerate(segments):
        cur.append(i)
        if seg.kind == "pause":
            blocks.append(cur)
            cur = []
    if cur:
        blocks.append(cur)
    out: list[list[int]] = []
    for b in blocks:
        piece: list[int] = []
        for i in b:
            piece.append(i)
            idx = segments[i].index
            if t[idx[-1]] - t[segments[piece[0]].index[0]] > 15.0 and i != b[-1]:
                out.append(piece)
                piece = []
        if piece:
            out.append(piece)
    return out


def _assign_folds(
    segments, t: np.ndarray, rng: np.random.Generator, inputs: dict | None = None
) -> np.ndarray:
    """Folds 0/1 (fit/select) and 2 (final held-out) of whole sweeps, balanced in time.

    Sweeps run at a rare condition (pressure or camber away from the session's usual value)
    are few and are stratified per kind of sweep (lateral / longitudinal, see ``_rare_folds``).
    The other sweeps are taken three at a time in time order, each triple getting a random
    permutation of the folds, so every fold spans the whole session.
    """
    fold = np.zeros(len(t), dtype=np.int8)
    blocks = _blocks(segments, t)
    rare = [_rare_kind(segments, b, inputs) for b in blocks] if inputs else [None] * len(blocks)
    rare_fold = _rare_folds(rare, rng)
    common = []
    for j, b in enumerate(blocks):
        if rare[j] is None:
            common.append(b)
            continue
        for i in b:
            fold[segments[i].index] = rare_fold[j]
    for j in range(0, len(common), 3):
        perm = rng.permutation(3)
        for k, b in enumerate(common[j : j + 3]):
            for i in b:
                fold[segments[i].index] = int(perm[k])
    return fold


def _rare_folds(rare: list[tuple[str, tuple] | None], rng: np.random.Generator) -> dict[int, int]:
    """Fold of each rare block (index into ``rare``: its (kind, condition) or None).

    A rare sweep is a run of blocks of one kind at one condition (the pieces of one long sweep
    stay together). Rare sweeps alternate, per kind, between the two selection folds, so
    that every selection fit sees one and predicts another. A stratum (a kind and the
    conditions it varies: pressure, camber) with enough rare sweeps that each selection fold
    keeps MIN_RARE_PER_FOLD of them also gives one to the final held-out fold: the interior
    condition farthest from the usual one (the held-out test interpolates, as the fit does, and
    sees the effect where it is strongest; the kinds at different conditions).
    """
    runs: list[tuple[str, tuple, list[int]]] = []
    last: dict[str, int] = {}  # kind -> its latest run
    for j, r in enumerate(rare):
        if r is None:
            continue
        kind, cond = r
        if kind in last and runs[last[kind]][1] == cond:
            runs[last[kind]][2].append(j)
            continue
        last[kind] = len(runs)
        runs.append((kind, cond, [j]))
    strata: dict[tuple, list[int]] = {}
    for k, (kind, cond, _) in enumerate(runs):
        strata.setdefault((kind, tuple(i for i, v in enumerate(cond) if v)), []).append(k)
    held: set[int] = set()
    taken: set[tuple] = set()
    for key in sorted(strata):
        ks = strata[key]
        levels = sorted({runs[k][1] for k in ks})[1:-1]
        free = [c for c in levels if c not in taken] or levels
        if len(ks) >= 2 * MIN_RARE_PER_FOLD + 1 and free:
            far = max(free, key=lambda cond: sum(map(abs, cond)))  # farthest from usual
            held.add(next(k for k in ks if runs[k][1] == far))
            taken.add(far)
    out: dict[int, int] = {}
    turn: dict[str, int] = {}
    for k, (kind, _, js) in enumerate(runs):
        f = turn.setdefault(kind, int(rng.integers(2)))
        if k in held:
            out.update(dict.fromkeys(js, 2))
            continue
        out.update(dict.fromkeys(js, f))
        turn[kind] = 1 - f
    return out


def _rare_kind(segments, block: list[int], inputs: dict) -> tuple[str, tuple] | None:
    """('x'/'y', condition) if the sweep runs at a rare condition, else None.

    'x'/'y' is the slip the sweep excites; the condition is its pressure and camber, rounded
    to the tolerances that make them rare.
    """
    idx = np.concatenate([segments[i].index for i in block])
    rare = False
    cond = []
    for key, tol in (("p", 0.05),):
        x = inputs.get(key)
        if x is not None:
            ref, here = float(np.median(x)), float(np.median(x[idx]))
            step = tol * max(abs(ref), 1e-9)
            rare |= abs(here - ref) > step
            cond.append(round((here - ref) / step))
    g = inputs["gamma"]
    dg = float(np.median(g[idx])) - float(np.median(g))
    rare |= abs(dg) > np.radians(0.5)
    cond.append(round(dg / np.radians(0.5)))
    if not rare:
        return None
    k = float(np.max(np.abs(inputs["kappa"][idx])))
    a = float(np.max(np.abs(inputs["alpha"][idx])))
    if k < 0.01 and a < np.radians(1.0):
        return None  # a pause or hold at the condition: nothing to fit
    return ("x" if k / 0.1 > a / np.radians(5.0) else "y"), tuple(cond)


def _rows(ctx: cd.Context, folds: tuple[int, ...], stride: int) -> list[np.ndarray]:
    out = []
    for w in ctx.wheels:
        ok = np.ones(w.n, dtype=bool)
        for v in w.meas.values():
            ok &= np.isfinite(v)
        idx = np.flatnonzero(np.isin(w.fold, folds) & ok)
        out.append(idx[::stride])
    return out


def _excited(w: cd.Wheel, key: str, level: float) -> bool:
    """A slip channel is swept in enough whole sweeps of every fold to be cross-validated."""
    x = np.abs(w.inputs[key])
    per_fold = [0, 0, 0]
    for b in _blocks(w.segments, w.t):
        idx = np.concatenate([w.segments[i].index for i in b])
        if np.max(x[idx]) > level:
            per_fold[int(w.fold[idx[0]])] += 1
    return min(per_fold) >= 1 and sum(per_fold) >= 4


def _context(ws: list[cd.Wheel], model) -> cd.Context:
    P = dict(model.params)
    chans = tuple(ch for ch in cd.CHANNELS if any(ch in w.meas for w in ws))
    # Selection and fitting use the forces; Mz (pneumatic trail, effect-specific) is reported
    # but only fitted when no force was recorded.
    fit_chans = tuple(ch for ch in chans if ch != "Mz") or chans
    inf_x = any("Fx" in w.meas and _excited(w, "kappa", 0.02) for w in ws)
    inf_y = any("Fy" in w.meas and _excited(w, "alpha", np.radians(2.0)) for w in ws)
    Pall = np.concatenate([w.P for w in ws])
    p95 = float(np.percentile(Pall[Pall > 0], 95)) if np.any(Pall > 0) else 1.0
    p_nom = float(P.get("INFLPRES") or P.get("NOMPRES") or 2e5)
    return cd.Context(
        model=model,
        base=P,
        wheels=ws,
        channels=fit_chans,
        sigma={ch: 1.0 for ch in chans},
        all_channels=chans,
        T_amb=float(P.get("NOMTEMP", 25.0)),
        k_thermal=cd.THERMAL_RISE_REF_K / max(p95, 1e-6),
        p_nom=p_nom,
        E_ref=max(float(np.median([w.E[-1] for w in ws])), 1e-6),
        t_end=max(float(max(w.t[-1] for w in ws)), 1e-3),
        V0=float(P.get("LONGVL", 16.7)),
        informative={"x": inf_x, "y": inf_y},
        moving={
            "x": inf_x
            or any(
                "Fx" in w.meas and np.percentile(np.abs(w.inputs["kappa"]), 95) > 0.01 for w in ws
            ),
            "y": inf_y
            or any(
                "Fy" in w.meas and np.percentile(np.abs(w.inputs["alpha"]), 95) > np.radians(1)
                for w in ws
            ),
        },
    )


def _candidates(ctx: cd.Context) -> list[cd.Component]:
    """The candidate models that the recording can tell anything about."""
    ws = ctx.wheels
    out: list[cd.Component] = []
    has_T = any(w.inputs["T"] is not None for w in ws)
    has_p = any(w.inputs["p"] is not None for w in ws)
    if has_T:
        if any(np.nanstd(w.inputs["T"]) > 0.5 for w in ws if w.inputs["T"] is not None):
            out.append(cd.ThermalRecorded(ctx))
    else:
        out += [cd.ThermalHidden(ctx, "physical"), cd.ThermalBulk(ctx)]
    pressure_terms = any(
        abs(ctx.base.get(k, 0.0)) > 0
        for k in ("PPX1", "PPX2", "PPX3", "PPX4", "PPY1", "PPY2", "PPY3", "PPY4")
    )
    if has_p:
        if any(
            np.nanstd(w.inputs["p"]) > 0.01 * ctx.p_nom for w in ws if w.inputs["p"] is not None
        ):
            out.append(cd.PressureRecorded(ctx))
    elif pressure_terms:
        out.append(cd.GasHidden(ctx))
    out += [cd.Relaxation(ctx), cd.Delay(ctx), cd.Offset(ctx)]
    if any(np.ptp(w.inputs["gamma"]) > np.radians(0.5) for w in ws):
        out.append(cd.camber_component(ctx))
    both = np.concatenate(
        [
            (np.abs(w.inputs["kappa"]) > 0.01) & (np.abs(w.inputs["alpha"]) > np.radians(1))
            for w in ws
        ]
    )
    if both.mean() > 0.05 and ctx.informative["x"] and ctx.informative["y"]:
        out.append(cd.combined_component(ctx))
    # Sliding speed varies with slip even at a constant wheel speed: speed always applies.
    out += [cd.Speed(ctx), cd.SpeedTable(ctx)]
    out += [cd.Wear(ctx, "work"), cd.Wear(ctx, "time"), cd.FrictionStep(ctx)]
    return [c for c in out if c.n > 0]


# --- diagnosis ----------------------------------------------------------------------------------


def diagnose(wheels: Sequence, model, *, seed: int = 0) -> Diagnosis:
    """Compare ``model`` with recorded ``wheels`` and name the physics it leaves out."""
    if not wheels:
        raise ValueError("no wheels to diagnose")
    rng = np.random.default_rng(seed)
    ws = [_prepare_wheel(s, model, rng) for s in wheels]
    ctx = _context(ws, model)
    n_total = sum(w.n for w in ws)
    stride = max(1, int(n_total / 3 / FIT_ROWS_PER_FOLD))
    rows_a, rows_b = _rows(ctx, (0,), stride), _rows(ctx, (1,), stride)
    rows_ab, rows_c = _rows(ctx, (0, 1), stride), _rows(ctx, (2,), 1)

    # Noise level per channel from the file model's residual (high-pass, robust).
    full = [np.arange(w.n) for w in ws]
    for ch in ctx.all_channels:
        rr, rng_ch = [], []
        for wi, w in enumerate(ws):
            if ch in w.meas:
                out = cd.predict([], np.zeros(0), ctx, wi, full[wi])
                rr.append(w.meas[ch] - out[ch])
                rng_ch.append(np.nanmax(w.meas[ch]) - np.nanmin(w.meas[ch]))
        sig = float(np.median([residual_sigma(r) for r in rr]))
        ctx.sigma[ch] = max(sig, 1e-3 * max(rng_ch), 1e-6)

    log: list[str] = []
    base = [cd.Scaling(ctx)]
    splits = [(rows_a, rows_b), (rows_b, rows_a)]  # two-way sweep-wise cross-validation
    cur_fits, cur_score, cur_split = sel.cross_validate(base, ctx, splits, [None, None])
    chosen: list[tuple[sel.Trial, dict]] = []
    pool = _candidates(ctx)
    drifts = [c for c in pool if c.name == "drift"]
    for _step in range(sel.MAX_EFFECTS):
        names_in = {t.component.name for t, _ in chosen}
        trials = []
        in_model = cur_fits[0].components
        cur = (cur_fits, cur_score, cur_split)
        for c in pool:
            if any(c is k for k in in_model) or (c.name in names_in and not c.extends):
                continue
            if c.extends and not any(isinstance(k, cd.ThermalHidden) for k in in_model):
                continue
            trials.append(_trial(c, _parts(c, pool, in_model), ctx, splits, cur, log, _step))
        best = _choose(trials, ctx, cur, splits, log)
        if best is None:
            break
        chosen.append(
            (best, {ch: (cur_score.rmse(ch), best.heldout.rmse(ch)) for ch in ctx.channels})
        )
        cur_fits, cur_score, cur_split = best.fits, best.heldout, best.split_scores
        if best.component.name == "drift":  # one drift variant is enough
            pool = [c for c in pool if c.name != "drift"]

    cur_fits = _drift_form(ctx, cur_fits, chosen, drifts, rows_ab, log)
    return _finish(ctx, ws, wheels, base, cur_fits, chosen, rows_ab, rows_c, log, stride)


def _trial(c, parts, ctx, splits, cur, log, step) -> sel.Trial:
    """Cross-validate the current model plus ``parts`` (for candidate ``c``) against it."""
    cur_fits, cur_score, cur_split = cur
    comps = [*cur_fits[0].components, *parts]
    x0s = [np.concatenate([f.x, *(p.x0 for p in parts)]) for f in cur_fits]
    fits, sc, split_sc = sel.cross_validate(comps, ctx, splits, x0s, cur_split)
    tr = sel.Trial(c, fits, sc)
    tr.split_scores = split_sc
    tr.parts = parts
    (
        tr.rel_gain,
        tr.gain_per_sample,
        tr.sweep_fraction,
        tr.t_stat,
        tr.p_sign,
        tr.weighted_fraction,
    ) = sel.compare(cur_score, sc)
    log.append(
        f"step {step}: {c.name} [{' + '.join(p.label for p in parts)}] "
        f"held-out rms {sc.rms:.3f} (current {cur_score.rms:.3f}) gain {tr.rel_gain:+.3f} "
        f"gps {tr.gain_per_sample:+.3f} sweeps {tr.sweep_fraction:.2f} "
        f"t {tr.t_stat:.1f} p {tr.p_sign:.3f} w {tr.weighted_fraction:.2f} | "
        + " ".join(f"{ch} {cur_score.rmse(ch):.1f}->{sc.rmse(ch):.1f}" for ch in ctx.channels)
    )
    return tr


def _drift_form(ctx, cur_fits, chosen, variants, rows, log) -> list[sel.Fit]:
    """The form of an accepted drift, chosen among its variants on all training sweeps (BIC).

    Drift has passed the held-out tests as an effect; its form (a trend in work or time, a
    step) is decided here. A change point is only located between the sweeps a fit sees:
    fitted on one selection fold, a step can land anywhere in a gap of that fold and lose on
    the other fold to a straight trend, though it is the better form. On both folds together
    the gaps are short.
    """
    tr = next((t for t, _ in chosen if t.component.name == "drift"), None)
    if tr is None:
        return cur_fits
    comps = cur_fits[0].components
    j = next(i for i, c in enumerate(comps) if c is tr.component)
    xs = cd.split_x(comps, np.mean([f.x for f in cur_fits], axis=0))
    others = [c for i, c in enumerate(comps) if i != j]
    x_others = [x for i, x in enumerate(xs) if i != j]
    m = sum(len(r) for r in rows) * len(ctx.channels)
    fits = []
    for v in variants:  # the variant goes last: the fit's alternative starts are its own
        x0 = np.concatenate([*x_others, xs[j] if v is tr.component else np.asarray(v.x0)])
        f = sel.fit([*others, v], ctx, rows, x0)
        fits.append((2.0 * f.cost + v.n * math.log(m), v, f))
        log.append(f"drift form {v.label}: BIC {fits[-1][0]:.1f}")
    _, v, f = min(fits, key=lambda b: b[0])
    if v is not tr.component:
        log.append(f"drift form: {v.label} instead of {tr.component.label} (BIC, training sweeps)")
        tr.reason = (
            f"form chosen on the training sweeps by BIC; the held-out figures are "
            f"those of the {tr.component.label} form that passed selection"
        )
        tr.component, tr.parts = v, [v]
    return [f]


def _parts(c: cd.Component, pool, in_model) -> list[cd.Component]:
    """What trying ``c`` adds to the model: a first hidden thermal node comes with its slow node.

    The tyre heats on two time scales (PHYSICS.md: tread surface in seconds, carcass in
    minutes). One node alone fits either, and on the slow part loses to a plain drift, so drift
    would be named before the heating it stands in for. The thermal hypothesis therefore
    competes in its two-node form (one effect, "temperature"). The slow node goes first so that
    the fit's alternative starts apply to the fast node's time constant (see ``sel.fit``).
    """
    first = not any(isinstance(k, cd.ThermalHidden) for k in in_model)
    if isinstance(c, cd.ThermalHidden) and first:
        return [*(k for k in pool if isinstance(k, cd.ThermalBulk)), c]
    return [c]


def _slow_node(tr: sel.Trial) -> bool:
    """The trial adds a slow thermal node (alone, or with its hidden thermal node)."""
    return any(p.extends for p in tr.parts)


def _tread_found(tr: sel.Trial) -> bool:
    """Every fit of the trial has its hidden tread node's time constant inside its range.

    The tread heats and cools within seconds (PHYSICS.md: the loop inside a sweep, recovery
    after a pause); a node pushed to TAU_FAST_MAX_S has found none of that and only follows a
    slow trend, which is not evidence of heating over drift.
    """
    for f in tr.fits:
        for c, xc in zip(f.components, cd.split_x(f.components, f.x), strict=True):
            if not isinstance(c, cd.ThermalHidden):
                continue
            if c.tau_s(xc) >= TREAD_TAU_FOUND * cd.TAU_FAST_MAX_S:
                return False
    return True


def _step_agrees(tr: sel.Trial, log: list[str]) -> bool:
    """Both selection fits of a friction step find a change of one sign and size (within a
    factor STEP_SIZE_RATIO): a belt or road change is one event of the session, which each
    fold's sweeps see alike; a step that one fold puts elsewhere or finds far smaller is
    fitting noise."""
    losses = []
    for f in tr.fits:
        for c, xc in zip(f.components, cd.split_x(f.components, f.x), strict=True):
            if isinstance(c, cd.FrictionStep):
                losses.append(float(xc[1]))
    a, b = sorted(losses, key=abs)[:2] if len(losses) >= 2 else (1.0, 1.0)
    if a * b > 0 and abs(b) <= STEP_SIZE_RATIO * abs(a):
        return True
    log.append(f"drift step rejected: the two folds' steps disagree ({losses})")
    return False


def _choose(trials, ctx, cur, splits, log) -> sel.Trial | None:
    """The best passing trial after Occam's rule, the delay sign check and the controls."""
    cur_fits = cur[0]
    ranked = sorted(trials, key=lambda t: t.heldout.rms)
    for tr in ranked:
        c = tr.component
        if not sel.passes(tr):
            continue
        if c.name == "time_delay" and min(f.x[-1] for f in tr.fits) <= 0.0:
            log.append("time_delay rejected: negative fitted delay is not a delay")
            continue
        if c.name == "offset":
            tr = _constant_offset(tr, ctx, cur, splits, log)
            if tr is None:
                continue
            c = tr.component
        if c.name == "combined_slip" and not _combined_where_both(tr, ctx, cur_fits, splits, log):
            continue
        if c.name == "drift":
            # Only a slow node that itself passes (and beats its controls), with a tread node
            # of seconds, may stand in for drift.
            bulk = [t for t in trials if _slow_node(t) and sel.passes(t) and _tread_found(t)]
            if (
                bulk
                and bulk[0].heldout.rms <= tr.heldout.rms * (1.0 + sel.DRIFT_VS_BULK_MARGIN)
                and _beats_controls(bulk[0], trials, ctx, cur_fits, splits, log)
            ):
                log.append(
                    "slow thermal node preferred to drift: the tyre's own heating "
                    "explains the trend"
                )
                tr = bulk[0]
                c = tr.component
        if isinstance(c, cd.FrictionStep) and not _step_agrees(tr, log):
            continue
        if c.name == "relaxation":
            delay = [t for t in trials if t.component.name == "time_delay" and sel.passes(t)]
            if delay and delay[0].heldout.rms <= tr.heldout.rms * (1.0 + sel.DELAY_OCCAM_MARGIN):
                log.append("time_delay preferred to relaxation: one lag for all speeds explains it")
                tr = delay[0]
                c = tr.component
        if c.name == "temperature" and c.concealed and not c.extends:
            gas = [t for t in trials if t.component.name == "pressure" and sel.passes(t)]
            if gas and gas[0].heldout.rms <= tr.heldout.rms * (1.0 + sel.OCCAM_MARGIN):
                log.append("pressure preferred to temperature: file's pressure terms explain it")
                tr = gas[0]
                c = tr.component
        if not _beats_controls(tr, trials, ctx, cur_fits, splits, log):
            continue
        tr.passed = True
        log.append(f"accepted {c.name} [{c.label}]")
        return tr
    return None


def _near_zero_slip(w: cd.Wheel, r: np.ndarray) -> np.ndarray:
    """Rows of ``r`` at zero slip (|kappa| < 0.01, |alpha| < ZERO_ALPHA)."""
    return r[(np.abs(w.inputs["kappa"][r]) < 0.01) & (np.abs(w.inputs["alpha"][r]) < ZERO_ALPHA)]


def _at_rest(w: cd.Wheel, r: np.ndarray) -> np.ndarray:
    """Rows of ``r`` at rest in slip (|kappa| < 0.002, |alpha| < 0.2 deg: pauses and holds),
    where the slip stiffness (~1e5 N per unit slip) cannot stand in for an offset."""
    return r[
        (np.abs(w.inputs["kappa"][r]) < REST_KAPPA) & (np.abs(w.inputs["alpha"][r]) < REST_ALPHA)
    ]


def _combined_rows(w: cd.Wheel, r: np.ndarray) -> np.ndarray:
    """Rows of ``r`` where both slips are non-zero (where combined-slip terms act)."""
    return r[(np.abs(w.inputs["kappa"][r]) >= 0.01) & (np.abs(w.inputs["alpha"][r]) >= ZERO_ALPHA)]


def _gain_on(tr, ctx, cur_fits, splits, pick) -> tuple[float, float, int]:
    """Held-out gain of ``tr`` over the current model on the rows ``pick(wheel, rows)`` keeps.

    Returns (relative RMS gain there, share of the whole held-out improvement [noise variances]
    made there, rows).
    """
    sub = [[pick(w, r) for w, r in zip(ctx.wheels, test, strict=True)] for _, test in splits]
    cur = sel.merge(
        [sel.score(f.components, f.x, ctx, n) for f, n in zip(cur_fits, sub, strict=True)]
    )
    new = sel.merge(
        [sel.score(f.components, f.x, ctx, n) for f, n in zip(tr.fits, sub, strict=True)]
    )
    whole = sum(a.total for a in tr.split_scores)
    cur_whole = sum(
        sel.score(f.components, f.x, ctx, test).total
        for f, (_, test) in zip(cur_fits, splits, strict=True)
    )
    share = (cur.total - new.total) / max(cur_whole - whole, 1e-12)
    return 1.0 - new.rms / max(cur.rms, 1e-12), float(share), cur.n


def _offset_at_zero_slip(tr, ctx, cur_fits, splits, log) -> bool:
    """An offset must show where it is defined: on held-out samples near zero slip.

    A constant at zero slip (PHYSICS.md) lowers the held-out error there by at least the
    least gain selection accepts (MIN_REL_RMSE_GAIN); an offset that only helps on the slopes
    is standing in for something else.
    """
    gain, _, n = _gain_on(tr, ctx, cur_fits, splits, _near_zero_slip)
    if n == 0 or gain < sel.MIN_REL_RMSE_GAIN:
        log.append(f"offset rejected: held-out gain near zero slip {gain:+.3f} (n {n})")
        return False
    return True


def _constant_offset(tr, ctx, cur, splits, log) -> sel.Trial | None:
    """The offset trial restricted to the channels whose offset is constant, or None.

    An offset is a constant at zero slip (PHYSICS.md): a channel where it is not
    (``_inconstant_channels``) has no offset; the others are tried again alone. The offset
    must then show where it is defined (near zero slip), and an offset that may change at
    mid-session (the drift control) must not predict held-out sweeps clearly better.
    """
    bad = _inconstant_channels(tr, ctx, cur[0], splits, log)
    if bad:
        keep = [ch for ch in ctx.channels if ch not in bad]
        if not keep:
            return None
        c = cd.Offset(ctx, channels=keep)
        tr = _trial(c, [c], ctx, splits, cur, log, "offset")
        if not sel.passes(tr) or _inconstant_channels(tr, ctx, cur[0], splits, log):
            log.append(f"offset rejected: {c.label} does not pass on its own")
            return None
    if not _offset_at_zero_slip(tr, ctx, cur[0], splits, log):
        return None
    t_mid = 0.5 * ctx.t_end
    drifting = cd.Offset(ctx, drift_at=t_mid, channels=tr.component.channels)
    comps = [*cur[0][0].components, drifting]
    x0s = [np.concatenate([f.x, drifting.x0]) for f in cur[0]]
    _, sc, _ = sel.cross_validate(comps, ctx, splits, x0s)
    if sc.rms < tr.heldout.rms * (1.0 - sel.MIN_CONTROL_MARGIN):
        log.append(
            f"offset rejected: control '{drifting.label}' predicts better "
            f"({sc.rms:.3f} vs {tr.heldout.rms:.3f})"
        )
        return None
    tr.reason = (
        "constant: read at rest, both folds' sweeps, early and late, cold and hot ones agree, "
        f"and '{drifting.label}' predicts no better ({sc.rms:.3f} vs {tr.heldout.rms:.3f} "
        "held-out RMS, noise units)"
    )
    return tr


def _inconstant_channels(tr, ctx, cur_fits, splits, log) -> set[str]:
    """Channels whose offset is not a constant at zero slip (PHYSICS.md), or is too small to
    be read there.

    Sweeps are the units (rows are autocorrelated); "agree" is within two standard errors.

    - Read at rest in slip on the held-out sweeps of each selection fold, with the current
      model (without the offset) fitted on the other fold, the offset is the same: it is a
      property of the session, not of how the other effects were fitted. It is at least
      OFFSET_MIN_SIGMA noise sigmas.
    - Per held-out sweep, the mean residual at rest of the model with the offset is the
      offset that sweep alone would want on top. Its means over the early and the late sweeps
      (and, when the model has a temperature, over the cold and the hot ones) agree, or differ
      by less than OFFSET_REL_TOL of the offset: an offset does not follow the session or the
      heating.
    """
    read: dict[tuple[int, str], list[tuple[float, float]]] = {
        (wi, ch): [] for wi in range(len(ctx.wheels)) for ch in tr.component.channels
    }
    moves: dict[tuple[int, str], list[tuple[str, float, float]]] = {k: [] for k in read}
    for (_, test), f, f0 in zip(splits, tr.fits, cur_fits, strict=True):
        for wi, (w, r) in enumerate(zip(ctx.wheels, test, strict=True)):
            out = cd.predict(f.components, f.x, ctx, wi, np.arange(w.n))
            out0 = cd.predict(f0.components, f0.x, ctx, wi, np.arange(w.n))
            states = _offset_states(f, ctx, w)
            sweeps = [
                _at_rest(w, np.intersect1d(np.concatenate([w.segments[i].index for i in b]), r))
                for b in _blocks(w.segments, w.t)
            ]
            for ch in tr.component.channels:
                if ch not in w.meas:
                    continue
                e = w.meas[ch] - out[ch]
                keep = [idx[np.isfinite(e[idx])] for idx in sweeps]
                keep = [idx for idx in keep if len(idx) >= 5]
                off = np.array([np.mean(e[idx]) for idx in keep])
                e0 = w.meas[ch] - out0[ch]
                read[(wi, ch)].append(_mean_se(np.array([np.mean(e0[idx]) for idx in keep])))
                for label, x in states.items():
                    d, z = _split_difference(off, np.array([np.mean(x[idx]) for idx in keep]))
                    moves[(wi, ch)].append((label, d, z))
    return {key[1] for key, ms in read.items() if _offset_refused(key, ms, moves[key], ctx, log)}


def _offset_states(f: sel.Fit, ctx: cd.Context, w: cd.Wheel) -> dict[str, np.ndarray]:
    """The states an offset must not follow: time, and the fit's temperature if it has one."""
    inp = dict(w.inputs)
    for c, xc in zip(f.components, cd.split_x(f.components, f.x), strict=True):
        c.inputs(xc, ctx, w, inp)
    states = {"time": w.t}
    if inp["T"] is not None and np.ptp(inp["T"]) > 1.0:
        states["temperature"] = inp["T"]
    return states


def _offset_refused(key, ms, moves, ctx, log) -> bool:
    """Whether the offset of wheel ``key[0]``, channel ``key[1]`` fails a test of
    ``_inconstant_channels`` (``ms``: the two folds' readings; ``moves``: its differences by
    state), logging the reason."""
    ch, prefix = key[1], ctx.wheels[key[0]].prefix
    size = 0.0  # unknown without both readings: any significant difference then counts
    if len(ms) == 2 and all(math.isfinite(se) for _, se in ms):
        (m0, s0), (m1, s1) = ms
        size = 0.5 * abs(m0 + m1)
        z = abs(m1 - m0) / max(math.hypot(s0, s1), 1e-9)
        if z > OFFSET_FOLDS_Z:
            log.append(
                f"offset on {ch} rejected: {prefix} read at rest without it, the two folds' "
                f"sweeps disagree ({m0:+.1f} vs {m1:+.1f} N, {z:.1f} standard errors): it "
                "depends on how the other effects were fitted"
            )
            return True
        if size < OFFSET_MIN_SIGMA * ctx.sigma[ch]:
            log.append(
                f"offset on {ch} rejected: {prefix} reads {size:.1f} N at rest, below "
                f"{OFFSET_MIN_SIGMA:g} noise sigmas ({ctx.sigma[ch]:.1f} N)"
            )
            return True
    for label, d, zd in moves:
        if zd > sel.MIN_T_ALT and abs(d) > OFFSET_REL_TOL * size:
            log.append(
                f"offset on {ch} rejected: {prefix} residual at rest differs by "
                f"{label} ({d:+.1f} N of {size:.1f} N, {zd:.1f} standard errors)"
            )
            return True
    return False


def _mean_se(y: np.ndarray) -> tuple[float, float]:
    """Mean and its standard error (NaN with fewer than two values)."""
    if len(y) < 2:
        return float("nan"), float("nan")
    return float(np.mean(y)), float(np.std(y, ddof=1) / math.sqrt(len(y)))


def _split_difference(y: np.ndarray, level: np.ndarray) -> tuple[float, float]:
    """Mean of ``y`` above the median ``level`` minus below, and its size in standard errors
    (0 with fewer than two on a side)."""
    hi = level > np.median(level) if len(level) else level.astype(bool)
    a, b = y[~hi], y[hi]
    if min(len(a), len(b)) < 2:
        return 0.0, 0.0
    (ma, sa), (mb, sb) = _mean_se(a), _mean_se(b)
    d = mb - ma
    return d, abs(d) / max(math.hypot(sa, sb), 1e-9)


def _combined_where_both(tr, ctx, cur_fits, splits, log) -> bool:
    """Combined slip acts only where both slips are non-zero: its gain must come from there.

    In pure sweeps the weighting functions are 1 (Gxa(alpha = 0) = Gyk(kappa = 0) = 1, eqs.
    4.E51, 4.E59); an improvement made elsewhere is another effect leaking into its terms.
    """
    gain, share, n = _gain_on(tr, ctx, cur_fits, splits, _combined_rows)
    if n == 0 or gain < sel.MIN_REL_RMSE_GAIN or share < MIN_COMBINED_SHARE:
        log.append(
            f"combined_slip rejected: held-out gain where both slips act {gain:+.3f}, "
            f"{share:.0%} of the improvement (n {n})"
        )
        return False
    return True


def _beats_controls(tr, trials, ctx, cur_fits, splits, log) -> bool:
    """A memory effect must beat a memoryless variant, a scrambled driver and a plain trend
    (the trend: not for a thermal node tried with its slow node, see _control_scores)."""
    c = tr.component
    if c.name not in ("temperature", "pressure") or not c.concealed or c.extends:
        return True
    if not tr.controls:  # computed once (the drift rule in _choose may ask first)
        _control_scores(tr, trials, ctx, cur_fits, splits)
    for label, rms in tr.controls.items():
        if tr.heldout.rms > rms * (1.0 - sel.MIN_CONTROL_MARGIN):
            log.append(
                f"{c.name} rejected: not better than control '{label}' "
                f"({tr.heldout.rms:.3f} vs {rms:.3f})"
            )
            return False
    return True


def _control_scores(tr, trials, ctx, cur_fits, splits) -> None:
    """Held-out RMS of the controls of ``tr``, fitted in the same form (with its slow node).

    With a slow node the thermal model is itself a trend: the controls then test its fast node
    (memoryless, scrambled, each with the same slow node), and its contest with drift is the
    drift-vs-bulk rule in _choose, not a control.
    """
    c = tr.component
    slow = [p for p in tr.parts if p is not c]
    controls: list[cd.Component] = []
    if c.name == "temperature":
        controls += [cd.ThermalHidden(ctx, "memoryless"), cd.ThermalHidden(ctx, "scrambled")]
    for k in controls:
        comps = [*cur_fits[0].components, *slow, k]
        x0s = [np.concatenate([f.x, *(p.x0 for p in slow), k.x0]) for f in cur_fits]
        _, sc, _ = sel.cross_validate(comps, ctx, splits, x0s)
        tr.controls[k.label] = sc.rms
    for t in trials if not slow else []:
        if t.component.name == "drift":
            tr.controls[t.component.label] = t.heldout.rms


def _finish(ctx, ws, wheels, base, cur_fits, chosen, rows_ab, rows_c, log, stride) -> Diagnosis:
    comps = cur_fits[0].components
    x0 = np.mean([f.x for f in cur_fits], axis=0)
    final = sel.fit(comps, ctx, rows_ab, x0, max_nfev=80)
    final.x = np.concatenate(
        [
            c.settle(xc, ctx, rows_ab)
            for c, xc in zip(comps, cd.split_x(comps, final.x), strict=True)
        ]
    )
    base_fit = sel.fit(base, ctx, rows_ab, x0[: base[0].n])
    xs = cd.split_x(comps, final.x)
    full = [np.arange(w.n) for w in ws]
    # each model's aligning moment refitted on its own forces (the model a user gets)
    base_m, xb_m = _with_mz(ctx, base, base_fit.x, rows_ab, log)
    comps_m, x_m = _with_mz(ctx, comps, final.x, rows_ab, log, start=base_m[-1:], x_start=xb_m)

    preds, inferred, resid = {}, {}, {}
    for wi, w in enumerate(ws):
        pb = cd.predict(base_m, xb_m, ctx, wi, full[wi])
        pi = cd.predict(comps_m, x_m, ctx, wi, full[wi])
        preds[w.prefix] = {}
        for ch in ctx.all_channels:
            if ch in w.meas:
                preds[w.prefix][f"baseline_{ch}"] = pb[ch]
                preds[w.prefix][f"improved_{ch}"] = pi[ch]
        resid[wi] = {ch: w.meas[ch] - pb[ch] for ch in w.meas}
        inp = dict(w.inputs)
        for c, xc in zip(comps, xs, strict=True):
            c.inputs(xc, ctx, w, inp)
        inferred[w.prefix] = {"E_f": w.E.copy()}
        if any(isinstance(c, cd.ThermalHidden) for c in comps):
            inferred[w.prefix]["T"] = inp["T"]
        if any(isinstance(c, cd.GasHidden) for c in comps):
            inferred[w.prefix]["p"] = inp["p"]

    fitjson = _fit_json(ctx, ws, preds)
    summaries = {ch: channel_summary(ctx, resid, ch) for ch in ctx.all_channels}
    n_ratio = (
        np.mean(
            [
                summaries[ch]["n_eff"] / max(summaries[ch]["n"], 1)
                for ch in ctx.channels
                if summaries[ch]
            ]
        )
        if summaries
        else 1.0
    )
    sd = sel.uncertainty(final, min(1.0, float(n_ratio) * stride))
    sds = cd.split_x(comps, sd)

    effects = []
    for tr, per_ch, c in _named_parts(chosen):
        k = next(i for i, comp in enumerate(comps) if comp is c)
        if c.extends:  # a refinement of an effect already named: add its parameters there
            host = next((e for e in effects if e.name == c.extends), None)
            if host is not None:
                host.parameters.update(zip(c.pnames, map(float, xs[k]), strict=True))
                host.uncertainty.update(zip(c.pnames, map(float, sds[k]), strict=True))
                pv = dict(zip(c.pnames, xs[k], strict=True))
                ps = dict(zip(c.pnames, sds[k], strict=True))
                if c is tr.component:  # tried on its own: its own held-out evidence
                    host.evidence += "; " + _evidence(tr, per_ch, host.channel, c, pv, ps)
                else:  # tried with its host: the host's evidence covers both
                    host.evidence += f"; with {c.label}: " + "; ".join(
                        f"{n} = {pv[n]:.4g} +- {ps[n]:.2g}" for n in c.pnames
                    )
                continue
        gains = {ch: 1 - b / a for ch, (a, b) in per_ch.items() if a > 0}
        ch = max(gains, key=gains.get) if gains else ctx.channels[0]
        params = {n: float(v) for n, v in zip(c.pnames, xs[k], strict=True)}
        unc = {n: float(v) for n, v in zip(c.pnames, sds[k], strict=True)}
        if isinstance(c, cd.ThermalHidden):
            params["gain_K_per_W"] = ctx.k_thermal
            params["T_amb_C"] = ctx.T_amb
            params.update({f"{n}_total": ctx.base[n] + params[n] for n in c.pnames[1:]})
        effects.append(
            Effect(
                c.name,
                c.concealed,
                ch,
                _where(ctx, comps, final.x, c, ch),
                _evidence(tr, per_ch, ch, c, params, unc),
                params,
                unc,
            )
        )
    if not effects:
        worst = max(ctx.channels, key=lambda ch: summaries[ch].get("rmse", 0) / ctx.sigma[ch])
        effects.append(
            Effect(
                "none",
                False,
                worst,
                where_text(summaries[worst], worst),
                "no candidate beat the baseline on held-out sweeps by the margins "
                f"(>= {sel.MIN_REL_RMSE_GAIN:.0%} RMSE, >= "
                f"{sel.MIN_GAIN_PER_SAMPLE:.0%} of noise variance, most sweeps)",
            )
        )

    improved = _improved_model(ctx, comps_m, x_m)
    baseline_model = ctx.model.with_params(_coefs(ctx, base_m, xb_m))
    return Diagnosis(
        effects=effects,
        fit=fitjson,
        improved_model=improved,
        baseline_model=baseline_model,
        predictions=preds,
        inferred=inferred,
        train_mask={w.prefix: w.fold != 2 for w in ws},
        heldout_mask={w.prefix: w.fold == 2 for w in ws},
        sweeps={w.prefix: [s.index for s in w.segments] for w in ws},
        details={
            "log": log,
            "sigma": dict(ctx.sigma),
            "summaries": summaries,
            "components": [c.label for c in comps],
        },
        models={"ctx": ctx, "baseline": (base_m, xb_m), "improved": (comps_m, x_m)},
    )


# The aligning moment's trail and residual-torque coefficients (MF 6.1 base and load terms,
# as the fit's Mz0 stage) with their parameter scales; the camber terms where camber varies.
MZ_COEFS = {"QBZ1": 1.0, "QCZ1": 0.1, "QDZ1": 0.01, "QEZ1": 0.1, "QHZ1": 1e-3, "QDZ6": 1e-3,
            "QBZ10": 0.05, "QBZ2": 0.1, "QDZ2": 0.01, "QDZ7": 1e-3}  # fmt: skip
MZ_CAMBER_COEFS = {"QBZ4": 0.1, "QBZ5": 0.1, "QDZ3": 0.1, "QDZ4": 0.5, "QDZ8": 0.05,
                   "QDZ9": 0.05, "QDZ10": 0.1, "QDZ11": 0.1, "QEZ5": 0.5, "QHZ3": 0.01,
                   "QHZ4": 0.01}  # fmt: skip


MZ_MIN_CORR = 0.5  # measured Mz must follow the model's this well to be refitted to


def _with_mz(ctx, comps, x, rows, log, start=(), x_start=None):
    """``comps`` and ``x`` plus the Mz coefficients refitted to the measured Mz on ``rows``,
    the force parameters held.

    Mz is left out of the selection (its trail and residual torque follow the forces, so it
    would count a force effect twice), but a model whose forces changed needs its Mz
    refitted on them: the Q*Z coefficients do not enter Fx or Fy, so the forces stay as fitted.
    ``start``: another model's Mz component (the last of its components, ``x_start`` their
    parameters), whose fitted Q*Z values are tried as a second starting point: the trail's
    shape (QBZ, QCZ, QEZ) is not convex. A measured Mz that does not follow the model's (a
    wrench whose torques are not measured: zeros or noise) is left alone, and so are the Q*Z.
    """
    if "Mz" in ctx.channels or "Mz" not in ctx.all_channels:
        return comps, x
    r = _mz_correlation(ctx, comps, x, rows)
    if not r >= MZ_MIN_CORR:
        log.append(f"Mz not refitted: the measured Mz does not follow the model's (r = {r:.2f})")
        return comps, x
    coefs = dict(MZ_COEFS)
    if any(np.ptp(w.inputs["gamma"]) > np.radians(0.5) for w in ctx.wheels):
        coefs.update(MZ_CAMBER_COEFS)
    mz = cd.CoefRefit(ctx, "aligning_moment", "Mz trail and residual torque",
                      list(coefs), list(coefs.values()))  # fmt: skip
    if not mz.n:
        return comps, x
    for other in start:
        if isinstance(other, cd.CoefRefit) and other.pnames == mz.pnames:
            mz.starts.append(dict(zip(mz.pnames, x_start[-other.n :], strict=True)))
    allc = [*comps, mz]
    on_mz = dataclasses.replace(ctx, channels=("Mz",))
    f = sel.fit(allc, on_mz, rows, np.concatenate([x, mz.x0]), max_nfev=30, held=x)
    return allc, f.x


def _mz_correlation(ctx, comps, x, rows) -> float:
    """Correlation of the measured Mz with the model's on ``rows`` (wheels pooled)."""
    meas, model = [], []
    for wi, r in enumerate(rows):
        w = ctx.wheels[wi]
        if "Mz" in w.meas and len(r):
            meas.append(w.meas["Mz"][r])
            model.append(cd.predict(comps, x, ctx, wi, r)["Mz"])
    if not meas:
        return math.nan
    a, b = np.concatenate(meas), np.concatenate(model)
    if np.std(a) == 0 or np.std(b) == 0:
        return 0.0
    return float(np.corrcoef(a, b)[0, 1])


def _named_parts(chosen):
    """(trial, per-channel RMSE, component) in the order effects are named: a trial's
    refinements after the component they refine."""
    for tr, per_ch in chosen:
        for c in sorted(tr.parts or [tr.component], key=lambda p: bool(p.extends)):
            yield tr, per_ch, c


def _coefs(ctx, comps, x) -> dict[str, float]:
    upd: dict[str, float] = {}
    for c, xc in zip(comps, cd.split_x(comps, x), strict=True):
        upd.update(c.coef(xc, ctx))
    return upd


def _improved_model(ctx, comps, x):
    """The file's model with every coefficient the chosen effects fitted (TTX/TTY, LMUV ...)."""
    upd = _coefs(ctx, comps, x)
    for c, xc in zip(comps, cd.split_x(comps, x), strict=True):
        if isinstance(c, cd.Speed) and "LMUV" in ctx.base:
            upd["LMUV"] = float(xc[0])
    try:
        return ctx.model.with_params(upd)
    except ValueError:
        upd.pop("LMUV", None)
        return ctx.model.with_params(upd)


def _floor(measured: list, twins: list, on_recorded: list, on_true: list) -> dict:
    """Held-out RMSE of the true physics on the recording, per channel [N, N m].

    The sensor noise on the forces (the twin's true forces against the measured ones) and on
    the inputs (a model replayed on the recorded inputs against the same model on the true
    ones: the improved model stands in for the true physics' slip stiffness), added as
    independent variances. A model can only approach it.
    """
    out = {}
    for ch in ("Fx", "Fy", "Mz"):
        acc = np.zeros((2, 2))  # (force noise, input noise) x (sum of squares, count)
        for m, t, a, b in zip(measured, twins, on_recorded, on_true, strict=True):
            if ch not in m.meas or ch not in t.meas:
                continue
            held = m.fold == 2
            for k, e in enumerate(((t.meas[ch] - m.meas[ch])[held], (a[ch] - b[ch])[held])):
                e = e[np.isfinite(e)]
                acc[k] += (float(e @ e), len(e))
        if acc[0, 1] and acc[1, 1]:
            out[ch] = {"rmse": _num(math.sqrt(acc[0, 0] / acc[0, 1] + acc[1, 0] / acc[1, 1]))}
    return out


def _fit_json(ctx, ws, preds) -> dict:
    out = {k: {} for k in ("baseline", "improved", "heldout_baseline", "heldout_improved")}
    for ch in ("Fx", "Fy", "Mz"):
        if ch not in ctx.all_channels:
            continue
        acc = {k: [0.0, 0] for k in out}
        rng = []
        for w in ws:
            if ch not in w.meas:
                continue
            m = w.meas[ch]
            rng.append(np.nanmax(m) - np.nanmin(m))
            for which, mask in (("", w.fold != 2), ("heldout_", w.fold == 2)):
                for kind in ("baseline", "improved"):
                    e = (preds[w.prefix][f"{kind}_{ch}"] - m)[mask]
                    e = e[np.isfinite(e)]
                    acc[which + kind][0] += float(e @ e)
                    acc[which + kind][1] += len(e)
        span = max(rng) if rng else 0.0
        for k, (ss, n) in acc.items():
            rmse = math.sqrt(ss / n) if n else float("nan")
            out[k][ch] = {"rmse": _num(rmse)}
            if not k.startswith("heldout"):
                out[k][ch]["nrmse"] = _num(rmse / span) if span > 0 else None
    return out


def _where(ctx, comps, x, c, ch) -> str:
    """Where this effect's part of the model acts: model with it minus model without it."""
    keep = [
        i for i, k in enumerate(comps) if k is not c and not (k.extends and k.extends == c.name)
    ]
    xs = cd.split_x(comps, x)
    without = [comps[i] for i in keep]
    x_without = np.concatenate([xs[i] for i in keep]) if keep else np.zeros(0)
    delta = {}
    for wi, w in enumerate(ctx.wheels):
        rows = np.arange(w.n)
        full = cd.predict(comps, x, ctx, wi, rows)
        part = cd.predict(without, x_without, ctx, wi, rows)
        delta[wi] = {k: full[k] - part[k] for k in w.meas}
    info = channel_summary(ctx, delta, ch)
    return where_text(info, ch, f"change made by the {c.name} model") if info else ch


def _evidence(tr, per_ch, ch, c, params, unc) -> str:
    a, b = per_ch[ch]
    parts = [
        f"held-out {ch} RMSE {a:.1f} -> {b:.1f} N ({(1 - b / a) if a else 0:+.0%})",
        f"noise-normalised RMS gain {tr.rel_gain:.1%}, better on "
        f"{tr.sweep_fraction:.0%} of changed held-out segments (sign test p = {tr.p_sign:.2g}, "
        f"t = {tr.t_stat:.1f}), two-way cross-validation on whole sweeps",
    ]
    if tr.controls:
        parts.append(
            "beats controls: "
            + ", ".join(f"{k} {v:.3f}" for k, v in tr.controls.items())
            + f" vs {tr.heldout.rms:.3f} (held-out RMS in noise units)"
        )
    shown = [f"{n} = {params[n]:.4g} +- {unc.get(n, float('nan')):.2g}" for n in c.pnames[:4]]
    parts.append("; ".join(shown))
    if tr.reason:
        parts.append(tr.reason)
    return f"{c.label}: " + "; ".join(parts)
