"""Whole sweeps as the units of validation, and their folds.

100 Hz samples are strongly autocorrelated (PHYSICS.md): a random choice of validation rows
measures interpolation. The diagnosis therefore validates on whole sweeps (*blocks*): runs of
segments between pauses, a long run cut into pieces of about ``BLOCK_S``. Folds 0 and 1 are the
two halves of the selection's cross-validation; fold 2 is held out from everything until the
final report.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from tire_model_ros.fit.sweeps import Segment

Index = npt.NDArray[np.int64]
Array = npt.NDArray[np.float64]

BLOCK_S = 10.0  # a continuous run (no pause) is cut into blocks of about this length [s]
# Rare sweeps each selection fold keeps before one goes to the final held-out fold: the MF
# pressure terms are quadratic (two per side), a fit needs two levels off nominal.
MIN_RARE_PER_FOLD = 2
RARE_PRESSURE = 0.05  # a sweep 5 % off the session's usual pressure is at a rare condition
RARE_CAMBER_RAD = np.radians(0.5)
# A block that sweeps a slip to this many times the usual sweep's reach is at a rare
# condition too (a car's one hard corner): the peak and beyond, seen in few sweeps.
RARE_REACH = 2.0
# A block sweeps a slip when it reaches this share of the session's largest value of it (the
# slip held while the other is swept, or the end of a sweep in the next block, does not).
MIN_SWEEP_SHARE = 0.2
LOAD_STEP = 0.1  # of the session's usual load: a rare sweep's load level (its identity only)

#: A block at a rare condition: the slip it sweeps ('x'/'y'), its pressure and camber levels
#: (what makes it rare), and its load level (what tells one corner of the range from another).
Rare = tuple[str, tuple[int, ...], int]
SPLIT = -1  # the fold of a rare sweep seen in one block only: its segments alternate


def blocks(segments: Sequence[Segment], t: Array, block_s: float = BLOCK_S) -> list[list[int]]:
    """Whole sweeps as lists of segment numbers: runs between pauses, cut near ``block_s``.

    The way out and the way back of one sweep stay together, so a held-out block tests the
    model's within-sweep dynamics too.
    """
    runs: list[list[int]] = []
    cur: list[int] = []
    for i, seg in enumerate(segments):
        cur.append(i)
        if seg.kind == "pause":
            runs.append(cur)
            cur = []
    if cur:
        runs.append(cur)
    out: list[list[int]] = []
    for run in runs:
        piece: list[int] = []
        for i in run:
            piece.append(i)
            start = t[segments[piece[0]].index[0]]
            if t[segments[i].index[-1]] - start > block_s and i != run[-1]:
                out.append(piece)
                piece = []
        if piece:
            out.append(piece)
    return out


def block_index(segments: Sequence[Segment], t: Array, block_s: float = BLOCK_S) -> list[Index]:
    """The sample indices of each block (see :func:`blocks`), in time order."""
    return [np.concatenate([segments[i].index for i in b]) for b in blocks(segments, t, block_s)]


def assign_folds(
    segments: Sequence[Segment],
    t: Array,
    rng: np.random.Generator,
    inputs: Mapping[str, Array | None],
    block_s: float = BLOCK_S,
) -> npt.NDArray[np.int8]:
    """Fold 0/1 (selection) or 2 (final held-out) per sample, whole blocks, balanced in time.

    Blocks at a rare condition (pressure or camber away from the session's usual value, or a
    slip swept far beyond the usual reach) are few and are stratified per kind of sweep (see
    :func:`rare_folds`). The other blocks are taken three at a time in time order, each
    triple getting a random permutation of the folds, so that every fold spans the whole
    session; a draw that would leave one mix of sweeps (:func:`sweep_mix`) in fewer folds
    than another permutation would is replaced by the most balanced one (see
    :func:`balanced_permutation`).
    """
    fold = np.zeros(len(t), dtype=np.int8)
    bl = blocks(segments, t, block_s)
    reach = usual_reach(segments, bl, inputs)
    rare = [rare_kind(segments, b, inputs, reach) for b in bl]
    rare_fold = rare_folds(rare, rng)
    common = []
    for j, b in enumerate(bl):
        if rare[j] is None:
            common.append(b)
            continue
        f = rare_fold[j]
        first = int(rng.integers(2))
        for n, i in enumerate(b):  # a split block: way out in one fold, way back in the other
            fold[segments[i].index] = f if f != SPLIT else (first + n) % 2
    mixes = [sweep_mix(segments, b, inputs) for b in common]
    counts: dict[tuple[int, ...], npt.NDArray[np.int64]] = {}
    for j in range(0, len(common), 3):
        triple = mixes[j : j + 3]
        perm = balanced_permutation(triple, counts, rng)
        for k, b in enumerate(common[j : j + 3]):
            counts.setdefault(triple[k], np.zeros(3, dtype=np.int64))[perm[k]] += 1
            for i in b:
                fold[segments[i].index] = perm[k]
    return fold


def balanced_permutation(
    triple: Sequence[tuple[int, ...]],
    counts: Mapping[tuple[int, ...], npt.NDArray[np.int64]],
    rng: np.random.Generator,
) -> tuple[int, ...]:
    """Folds for a triple of blocks of the given mixes: a random permutation, kept unless
    another leaves the blocks of each mix spread more evenly over the folds (least sum of
    squared counts per mix and fold, given ``counts`` so far).

    A programme that cycles three sweeps (pure drive slip, combined at two slip angles) puts
    one of each in every time-ordered triple; a free draw per triple sent all three pure
    sweeps of a session to the final held-out fold one time in 27 (unseen brush speed, seed
    15: held-out 27 -> 68 N). A session of one mix keeps every draw.
    """

    def spread(perm: Sequence[int]) -> int:
        c = {m: counts.get(m, np.zeros(3, dtype=np.int64)).copy() for m in triple}
        for m, f in zip(triple, perm[: len(triple)], strict=True):
            c[m][f] += 1
        return int(sum(int(np.sum(v * v)) for v in c.values()))

    drawn = tuple(int(f) for f in rng.permutation(3))
    best = min(itertools.permutations(range(3)), key=spread)
    return drawn if spread(drawn) <= spread(best) else best


def sweep_mix(
    segments: Sequence[Segment], block: Sequence[int], inputs: Mapping[str, Array | None]
) -> tuple[int, ...]:
    """The block's shares (in quarters) of samples that sweep the slip ratio alone, the slip
    angle alone and both (each beyond MIN_SWEEP_SHARE of the session's largest)."""
    idx = np.concatenate([segments[i].index for i in block])
    on = []
    for key in ("kappa", "alpha"):
        slip = inputs[key]
        assert slip is not None
        top = float(np.max(np.abs(slip)))
        on.append(np.abs(slip[idx]) >= max(MIN_SWEEP_SHARE * top, 1e-12))
    x, y = on
    return tuple(round(4.0 * float(np.mean(m))) for m in (x & ~y, y & ~x, x & y))


def rare_folds(rare: Sequence[Rare | None], rng: np.random.Generator) -> dict[int, int]:
    """Fold of each rare block (index into ``rare``: its :data:`Rare` or None).

    A rare sweep is a run of blocks of one kind at one condition and load. A condition is a
    pressure and camber at a load: a low pressure at a high load (the deflection of a sidewall
    touching the road) is a visit of its own, not a second visit of that pressure. Rare
    sweeps alternate, per kind, between the two selection folds, so that every selection fit
    sees one and predicts another; a condition visited again goes to the other fold than its
    last visit (a corner of the operating range visited twice: one visit in each), and the
    pieces of a condition visited once alternate (nothing about it could be validated
    otherwise); visited in one block only, that block is :data:`SPLIT`: its segments
    alternate. A stratum (a kind
    and the conditions it varies) with enough rare sweeps that each selection fold keeps
    MIN_RARE_PER_FOLD of them also gives one to the final held-out fold: the interior
    condition farthest from the usual one (the held-out test interpolates, as the fit does,
    and sees the effect where it is strongest; the kinds at different conditions).
    """
    runs: list[tuple[str, tuple[int, ...], int, list[int]]] = []
    last: dict[str, int] = {}  # kind -> its latest run
    for j, r in enumerate(rare):
        if r is None:
            continue
        kind, cond, load = r
        if kind in last and runs[last[kind]][1:3] == (cond, load):
            runs[last[kind]][3].append(j)
            continue
        last[kind] = len(runs)
        runs.append((kind, cond, load, [j]))
    strata: dict[tuple[str, tuple[int, ...]], list[int]] = {}
    for k, (kind, cond, _, _) in enumerate(runs):
        strata.setdefault((kind, tuple(i for i, v in enumerate(cond) if v)), []).append(k)
    held: set[int] = set()
    taken: set[tuple[int, ...]] = set()
    for key in sorted(strata):
        ks = strata[key]
        levels = sorted({runs[k][1] for k in ks})[1:-1]
        free = [c for c in levels if c not in taken] or levels
        if len(ks) >= 2 * MIN_RARE_PER_FOLD + 1 and free:
            far = max(free, key=lambda cond: sum(map(abs, cond)))  # farthest from usual
            held.add(next(k for k in ks if runs[k][1] == far))
            taken.add(far)
    out: dict[int, int] = {}
    turn: dict[str, int] = {}  # per kind: the fold of its next new condition
    again: dict[Rare, int] = {}  # a condition seen: its next run's fold
    visits = {v: sum(1 for r in runs if r[:3] == v) for v in {r[:3] for r in runs}}
    for k, (kind, cond, load, js) in enumerate(runs):
        visit = (kind, cond, load)
        if k in held:
            out.update(dict.fromkeys(js, 2))
            continue
        if visits[visit] == 1:  # one visit: its pieces alternate (one piece: its segments)
            f = turn.setdefault(kind, int(rng.integers(2)))
            out.update({j: (f + i) % 2 if len(js) > 1 else SPLIT for i, j in enumerate(js)})
            continue
        if visit in again:
            f = again[visit]
        else:
            f = turn.setdefault(kind, int(rng.integers(2)))
            turn[kind] = 1 - f
        out.update(dict.fromkeys(js, f))
        again[visit] = 1 - f
    return out


def _reach(segments: Sequence[Segment], block: Sequence[int], slip: Array) -> float:
    return float(np.max(np.abs(slip[np.concatenate([segments[i].index for i in block])])))


def usual_reach(
    segments: Sequence[Segment], bl: Sequence[Sequence[int]], inputs: Mapping[str, Array | None]
) -> dict[str, float]:
    """Per slip ('kappa', 'alpha') that some block sweeps: the median reach of those blocks."""
    out = {}
    for key in ("kappa", "alpha"):
        slip = inputs[key]
        assert slip is not None
        reach = np.array([_reach(segments, b, slip) for b in bl])
        swept = reach[reach >= MIN_SWEEP_SHARE * float(np.max(np.abs(slip)))]
        usual = float(np.median(swept)) if len(swept) else 0.0
        if usual > 0.0:  # a slip held at zero all session has no reach to exceed
            out[key] = usual
    return out


def rare_kind(
    segments: Sequence[Segment],
    block: Sequence[int],
    inputs: Mapping[str, Array | None],
    reach: Mapping[str, float] | None = None,
) -> Rare | None:
    """The block's :data:`Rare` if it runs at a rare condition, else None.

    'x'/'y' is the slip the sweep excites; the condition is its pressure and camber, rounded
    to the tolerances that make them rare, and how far the block sweeps either slip beyond
    the usual ``reach`` (:func:`usual_reach`) in factors of RARE_REACH; the load is rounded to
    LOAD_STEP.
    """
    idx = np.concatenate([segments[i].index for i in block])
    kappa, alpha = inputs["kappa"], inputs["alpha"]
    assert kappa is not None and alpha is not None
    reached = {
        "kappa": float(np.max(np.abs(kappa[idx]))),
        "alpha": float(np.max(np.abs(alpha[idx]))),
    }
    rare = False
    cond = []
    for key, usual in (reach or {}).items():
        ratio = reached[key] / usual
        level = int(np.floor(np.log(ratio) / np.log(RARE_REACH))) if ratio >= 1.0 else 0
        rare |= level >= 1
        cond.append(level)
    p = inputs.get("p")
    if p is not None:
        ref, here = float(np.median(p)), float(np.median(p[idx]))
        step = RARE_PRESSURE * max(abs(ref), 1e-9)
        rare |= abs(here - ref) > step
        cond.append(round((here - ref) / step))
    g = inputs["gamma"]
    assert g is not None
    dg = float(np.median(g[idx])) - float(np.median(g))
    rare |= abs(dg) > RARE_CAMBER_RAD
    cond.append(round(dg / RARE_CAMBER_RAD))
    if not rare:
        return None
    k, a = reached["kappa"], reached["alpha"]
    k_all, a_all = float(np.max(np.abs(kappa))), float(np.max(np.abs(alpha)))
    if k < max(0.01, MIN_SWEEP_SHARE * k_all) and a < max(np.radians(1.0), MIN_SWEEP_SHARE * a_all):
        return None  # a pause, a hold or the tail of a sweep at the condition: nothing to fit
    Fz = inputs["Fz"]
    assert Fz is not None
    ref_fz = max(float(np.median(Fz)), 1e-9)
    load = round((float(np.median(Fz[idx])) - ref_fz) / (LOAD_STEP * ref_fz))
    return ("x" if k / 0.1 > a / np.radians(5.0) else "y"), tuple(cond), load
