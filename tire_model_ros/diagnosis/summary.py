"""A recording's diagnosis: the wheels searched together, each reported, and a summary."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tire_model_ros.blas import one_blas_thread
from tire_model_ros.model import TireModel
from tire_model_ros.model.states import Effects
from tire_model_ros.recording.series import WheelSeries
from tire_model_ros.vocabulary import TOLD_APART_BY

from .effects.base import Array, Index
from .predict import predict
from .prepare import make_context, prepare_wheel
from .result import (
    Effect,
    WheelDiagnosis,
    finish,
    fit_json_pooled,
    floor,
    reference_context,
    set_noise,
)
from .search import Key, Selection


@dataclass
class Diagnosis:
    """The diagnosis of a recording: per wheel, and the effects summed up across wheels."""

    wheels: dict[str, WheelDiagnosis]
    selection: Selection | None = None
    effects: list[Effect] = field(default_factory=list)
    fit: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.effects:
            self.effects = _summary(self.wheels, self.selection)
        if not self.fit:
            self.fit = fit_json_pooled(list(self.wheels.values()))

    # --- per-wheel views the report and the demo read, keyed by wheel prefix ---------------

    @property
    def improved_model(self) -> TireModel:
        """The improved model of the (first) wheel; see ``improved_models`` for each."""
        return next(iter(self.wheels.values())).improved_model

    @property
    def improved_models(self) -> dict[str, TireModel]:
        return {p: w.improved_model for p, w in self.wheels.items()}

    @property
    def baseline_model(self) -> TireModel:
        return next(iter(self.wheels.values())).baseline_model

    @property
    def predictions(self) -> dict[str, dict[str, Array]]:
        return {p: w.predictions for p, w in self.wheels.items()}

    @property
    def inferred(self) -> dict[str, dict[str, Array]]:
        return {p: w.inferred for p, w in self.wheels.items()}

    @property
    def train_mask(self) -> dict[str, Array]:
        return {p: w.train_mask for p, w in self.wheels.items()}

    @property
    def heldout_mask(self) -> dict[str, Array]:
        return {p: w.heldout_mask for p, w in self.wheels.items()}

    @property
    def sweeps(self) -> dict[str, list[Index]]:
        return {p: w.sweeps for p, w in self.wheels.items()}

    @property
    def details(self) -> dict[str, Any]:
        log = list(self.selection.log) if self.selection is not None else []
        log += [f"[{p}] {line}" for p, w in self.wheels.items() for line in w.log]
        return {
            "log": log,
            "sigma": {p: w.sigma for p, w in self.wheels.items()},
            "summaries": {p: w.summary for p, w in self.wheels.items()},
        }

    # --- outputs -----------------------------------------------------------------------------

    @property
    def look_alikes(self) -> dict[str, float]:
        """Words the recording does not tell from the named effects, strongest first: each
        alone predicted the held-out sweeps significantly better than the baseline (its share
        of the baseline's held-out mean square error, as ``explained``), beside the named
        effects not (:class:`.search.Selection`)."""
        found = self.selection.look_alikes if self.selection is not None else {}
        return dict(sorted(found.items(), key=lambda kv: -kv[1]))

    def to_json(self) -> dict[str, Any]:
        """The INTERFACE.md diagnosis object (and, for several wheels, each wheel's; the
        look-alikes of the named effects)."""
        out: dict[str, Any] = {"effects": [e.to_json() for e in self.effects], "fit": self.fit}
        out["look_alikes"] = [
            {"name": w, "explained_alone": share, "told_apart_by": TOLD_APART_BY.get(w, "")}
            for w, share in self.look_alikes.items()
        ]
        out["inputs_bridged"] = self.inputs_bridged
        out["inputs_dropped"] = self.inputs_dropped
        if len(self.wheels) > 1:
            out["wheels"] = {p: w.to_json() for p, w in self.wheels.items()}
        return out

    @property
    def inputs_bridged(self) -> dict[str, dict[str, int]]:
        """Per wheel, per input, the samples that were not finite: bridged linearly in time,
        left out of every fit and score (:func:`.prepare.bridge`)."""
        return {p: dict(w.ctx.wheel.gaps) for p, w in self.wheels.items() if w.ctx.wheel.gaps}

    @property
    def inputs_dropped(self) -> dict[str, list[str]]:
        """Per wheel, the optional inputs (speed, pressure, temperature) without a finite
        sample: taken as not recorded."""
        return {p: list(w.ctx.wheel.dropped) for p, w in self.wheels.items() if w.ctx.wheel.dropped}

    def node_effects(self, tir: str = "") -> Effects:
        """The node's effects file: each wheel's hidden states, and what is not carried."""
        wheels, not_carried = {}, []
        for p, w in self.wheels.items():
            wheels[p], nc = w.node_effects()
            not_carried += nc
        return Effects(wheels, tir, tuple(dict.fromkeys(not_carried)))

    def score_reference(self, twins: Sequence[WheelSeries]) -> dict[str, Any]:
        """Held-out RMSE of the baseline and improved models against a twin recording.

        ``twins`` is a second recording of the same session, sample for sample (for a virtual
        rig: its noise-free twin, true inputs and true forces). Both fitted models are replayed
        on its inputs (hidden states driven by its own forces) and compared with its forces on
        the samples held out here: the model error without the sensor noise. Also
        "heldout_floor": the held-out RMSE the true physics itself scores on the diagnosed
        recording (:func:`.result.floor`).

        Raises
        ------
        ValueError
            A wheel is missing or its samples do not match the diagnosed recording's.
        """
        by_prefix = {s.prefix: s for s in twins}
        refs, preds = [], []
        for p, wd in self.wheels.items():
            if p not in by_prefix:
                raise ValueError(f"{p}: not in the reference recording")
            ref = reference_context(wd, by_prefix[p])
            rows = ref.rows["all"]
            pr = {}
            for kind, (models, x) in (("baseline", wd.baseline), ("improved", wd.improved)):
                out = predict(models, x, ref, rows)
                pr.update(
                    {f"{kind}_{ch}": out[ch] for ch in ref.all_channels if ch in ref.wheel.meas}
                )
            refs.append(ref)
            preds.append(pr)
        pooled = fit_json_pooled([_Scored(r, p) for r, p in zip(refs, preds, strict=True)])
        scores = {k: pooled[k] for k in ("heldout_baseline", "heldout_improved")}
        ws = list(self.wheels.values())
        scores["heldout_floor"] = floor(
            [w.ctx for w in ws], refs, [w.predictions for w in ws], preds
        )
        return scores


@dataclass
class _Scored:
    """A context with predictions, the shape ``fit_json_pooled`` reads."""

    ctx: Any
    predictions: dict[str, Array]


@one_blas_thread
def diagnose(wheels: Sequence[WheelSeries], model: TireModel, *, seed: int = 0) -> Diagnosis:
    """Compare ``model`` with the recorded wheels and name the physics it leaves out.

    The wheels of a car are diagnosed together: each wheel gets its own parameters, the
    evidence that an effect is there is pooled over them (:mod:`.search`).
    """
    from .effects import Scaling, candidates
    from .search import search

    if not wheels:
        raise ValueError("no wheels to diagnose")
    rng = np.random.default_rng(seed)
    ctxs = [make_context(prepare_wheel(s, model, rng), model) for s in wheels]
    for c in ctxs:
        set_noise(c)
    sel = search(ctxs, [Scaling(c) for c in ctxs], [candidates(c) for c in ctxs])
    return Diagnosis({c.wheel.prefix: finish(c.wheel.prefix, sel) for c in ctxs}, sel)


def _summary(wheels: dict[str, WheelDiagnosis], sel: Selection | None) -> list[Effect]:
    """One effect per chosen model, strongest first (the share of all wheels' baseline
    held-out mean square error it explains), with the wheels it acts on; a single wheel's
    effects as they are."""
    if len(wheels) == 1 or sel is None:
        return next(iter(wheels.values())).effects
    by_word: dict[str, list[tuple[str, Effect]]] = {}
    for p, w in wheels.items():
        for e in w.effects:
            if e.name != "none":
                by_word.setdefault(e.name, []).append((p, e))
    shares = {sel_word(sel, k): v for k, v in sel.explained.items()}
    out = []
    for word, found in by_word.items():
        share = shares.get(word, 0.0)
        p0, e0 = max(found, key=lambda pe: pe[1].explained or 0.0)
        names = [p for p, _ in found]
        out.append(
            Effect(
                word,
                any(e.concealed for _, e in found),
                e0.channel,
                f"on {len(found)} of {len(wheels)} wheels ({', '.join(names)}); "
                f"most on {p0}: {e0.where}",
                e0.evidence,
                e0.parameters,
                e0.uncertainty,
                share,
                names,
            )
        )
    out.sort(key=lambda e: -(e.explained or 0.0))
    if not out:
        w0 = next(iter(wheels.values()))
        return [Effect("none", False, w0.effects[0].channel, f"on none of the {len(wheels)} wheels",
                       w0.effects[0].evidence, wheels=[])]  # fmt: skip
    return out


def sel_word(sel: Selection, key: Key) -> str:
    """The INTERFACE.md word of a chosen model."""
    model = next(iter(sel.final.effect(key).values()))
    return model.word


__all__ = ["Diagnosis", "Effect", "diagnose"]
