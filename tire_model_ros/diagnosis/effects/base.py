"""The shape of an effect model: what the selection engine needs to know of one physics.

An effect model adds a few bounded parameters to the recording's model and acts in one or
more of four places, which the predictor (:mod:`..predict`) composes:

- ``coef``: updates of Magic Formula coefficients (TTX/TTY, camber, combined slip ...), global
  for the session;
- ``inputs``: transformed model inputs over the whole session (a hidden temperature or
  pressure, lagged or delayed slip: whatever needs the samples before);
- ``per_sample``: then, at the rows evaluated only, transforms of each sample on its own (a
  slip stiffness that changes with a state), after every model's ``inputs``;
- ``mu_scale``: a per-sample friction scale at those rows (wear, sliding-speed friction, a
  friction step), applied by the similarity method;
- ``output``: additive force offsets, or a force factor (sidewall contact).

Beyond its equations, an effect model says where in the operating range it can show
(``support``), which simpler models it must beat to be believed (``controls``: a memoryless
twin, a time-scrambled driver, a plain time trend), which imperfection of the recording must
not explain it better (``rivals``: a zero that wanders), whether it is a constant physics of the
session (``stable_in_time``: fitted on the early and on the late half, it does the same to the
forces), and
what a forward model carries of it (``carry``, the node's effects file). The engine never asks
which effect it is.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from tire_model_ros.model.params import PARAMETERS

from ..prepare import Context

Array = npt.NDArray[np.float64]
Mask = npt.NDArray[np.bool_]
Index = npt.NDArray[np.int64]


@dataclass(frozen=True)
class Param:
    """One parameter: start, physical bounds and typical scale (for the optimiser); one that
    is not ``fitted`` is set by the model's ``settle`` after the fit. A model whose detail
    would lead a descent astray is fitted in two ``stage``s: a guide (1) is fitted in the
    first only, then handed over (``EffectModel.handover``) and held; a refinement (2) is
    held at its start in the first and fitted in the second; 0: in both."""

    name: str
    x0: float
    lo: float
    hi: float
    scale: float
    fitted: bool = True
    stage: int = 0


class EffectModel:
    """A model of one missing physics (``word``: the INTERFACE.md name it is reported by)."""

    word: ClassVar[str] = ""
    label: str = ""  # which model of the word this is
    concealed: bool = False  # fitted without the channel that would show it
    # A physics of the session does the same to the forces fitted on the early or on the late
    # half (not a step, nor a state that the first half sees rise and the second saturate).
    stable_in_time = True
    # Its parameters are the tyre's own (not a wheel's state or a sensor's): on the wheels of
    # a car, one set is fitted to all of them (:func:`shared`), so that a wheel that reaches
    # the same conditions without the effect tells against it.
    tyre: ClassVar[bool] = False
    # A plain function of time, with no drive (a trend) ...
    of_time = False
    # ... and a model whose word only its drive tells (its law in the forces is free, as a
    # hidden temperature's grip table and stiffness): such a control predicting what it
    # predicts shows a change in time, not the cause it names. A model whose law is the
    # file's (a pressure through its pressure terms) is told by that law, whatever drives it.
    shown_by_drive: ClassVar[bool] = False

    def __init__(self, params: list[Param], starts: list[dict[str, float]] | None = None):
        self.params = params
        self.starts = starts or []  # alternative starts of the non-convex parameters
        self._memo: dict[str, tuple[Context, tuple[float, ...], tuple[Array, ...], Any]] = {}

    # --- what the engine asks ------------------------------------------------------------

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        """The models of this kind the recording can tell anything about ([]: none)."""
        return []

    def support(self, ctx: Context, x: Array | None = None) -> Mask | None:
        """Samples where this physics can change the forces (None: anywhere); with ``x``, this
        model's fitted parameters, where the fitted model does (a region whose bounds are
        the tyre's own, fitted). Most of what it gains on held-out sweeps must come from
        there: a gain made elsewhere is the refitted baseline standing in for another
        effect."""
        return None

    def controls(self, ctx: Context) -> list[EffectModel]:
        """Simpler models of the same mismatch that this one must predict better than."""
        return []

    def on(self, ctx: Context) -> EffectModel | None:
        """This form of a tyre's model on another wheel of the car, which the tyre's one
        parameter set acts on whether or not that wheel alone could tell it (None: the wheel
        never reaches where it acts)."""
        return type(self)(ctx)  # type: ignore[arg-type]  # a model is made from its wheel

    def rivals(self, ctx: Context) -> list[EffectModel]:
        """Imperfections of the recording, not missing physics, that would leave the same
        mismatch: a rival that predicts held-out sweeps better than this model (as a control
        that is not beaten) says the mismatch is the recording's."""
        return []

    # --- the model ----------------------------------------------------------------------

    def coef(self, x: Array, ctx: Context) -> dict[str, float]:
        return {}

    def inputs(self, x: Array, ctx: Context, inp: dict[str, Array | None]) -> None:
        """Transform the session's inputs ``inp`` (every sample) in place."""
        return None

    def per_sample(self, x: Array, ctx: Context, inp: dict[str, Array | None], rows: Index) -> None:
        """Transform the inputs ``inp`` at ``rows`` in place, each sample on its own."""
        return None

    def mu_scale(self, x: Array, ctx: Context, rows: Index) -> Array | None:
        """The friction scale at ``rows`` (None: 1)."""
        return None

    def output(self, x: Array, ctx: Context, out: dict[str, Array], rows: Index) -> None:
        return None

    def penalty(self, x: Array, ctx: Context) -> Array:
        """Residuals (noise units) that hold the model inside its physics where bounds on its
        parameters cannot (e.g. a grip factor that must stay positive over the temperatures
        it is applied to); zero when it is. Added to the fit's residuals, not to scores."""
        return np.zeros(0)

    def settle(self, x: Array, seen: Sequence[tuple[Context, Index]]) -> Array:
        """``x`` with any parameter the fitted rows leave undetermined set to a neutral value
        (after the fit has converged); ``seen``: each fitted wheel's context and rows (every
        wheel of a car for a tyre effect, one otherwise)."""
        return x

    def handover(self, x: Array, ctx: Context) -> Array:
        """``x`` after the first stage of a staged fit (``Param.stage``) with its guides'
        shape handed to the refinements and the guides at their neutral values."""
        return x

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        """What a forward model runs of this effect, as keyword arguments of
        :class:`~tire_model_ros.model.states.WheelEffects` ({}: nothing beyond the .tir
        coefficients); None: nothing a forward model can carry (a session's history, a
        recording's artefact)."""
        return {}

    def reported(self, x: Array, ctx: Context) -> dict[str, float]:
        """The parameters as the report gives them (the fitted ones, and any convention they
        are read on)."""
        return self.values(x)

    def inferred(self, x: Array, ctx: Context, inp: Mapping[str, Array | None]) -> dict[str, Array]:
        """Hidden states this model infers, for the report (e.g. ``{"T": ...}``)."""
        return {}

    # --- bookkeeping ----------------------------------------------------------------------

    def remembered(
        self,
        slot: str,
        ctx: Context,
        key: tuple[float, ...],
        make: Callable[[], Any],
        sources: tuple[Array, ...] = (),
    ) -> Any:
        """``make()``, computed again only when ``ctx``, the parameters ``key`` it depends on or
        the arrays ``sources`` it transforms (the very same objects) changed since the last call
        for ``slot``: a fit's difference columns move one parameter at a time, and a whole-session
        state that does not depend on it is not integrated again. Arrays made are read-only."""
        m = self._memo.get(slot)
        if (
            m is not None
            and m[0] is ctx
            and m[1] == key
            and len(m[2]) == len(sources)
            and all(a is b for a, b in zip(m[2], sources, strict=True))
        ):
            return m[3]
        value = make()
        for a in value if isinstance(value, tuple) else (value,):
            if isinstance(a, np.ndarray):
                a.flags.writeable = False
        self._memo[slot] = (ctx, key, sources, value)
        return value

    @property
    def n(self) -> int:
        return len(self.params)

    @property
    def pnames(self) -> list[str]:
        return [p.name for p in self.params]

    @property
    def x0(self) -> Array:
        return np.array([p.x0 for p in self.params], dtype=np.float64)

    def values(self, x: Array) -> dict[str, float]:
        return {p.name: float(v) for p, v in zip(self.params, x, strict=True)}

    def __repr__(self) -> str:
        return f"{self.word}[{self.label}]"


def shared(models: Sequence[EffectModel]) -> None:
    """Give the wheels' models of one tyre effect one parameter space: the union of their
    parameters (a wheel that sweeps no slip ratio proposes no Fx coefficient, yet the tyre's
    value acts on it too), each one's bounds spanning every wheel's that has it, its start
    their median; the alternative starts all of theirs and each wheel's own start (each wheel
    proposes from its own operating range)."""
    if len(models) < 2:
        return
    by_name: dict[str, list[Param]] = {}
    for m in models:
        for p in m.params:
            by_name.setdefault(p.name, []).append(p)
    params = []
    for ps in by_name.values():
        lo, hi = min(p.lo for p in ps), max(p.hi for p in ps)
        x0 = float(np.clip(np.median([p.x0 for p in ps]), lo, hi))
        params.append(replace(ps[0], x0=x0, lo=lo, hi=hi, scale=max(p.scale for p in ps)))
    starts = [{p.name: p.x0 for p in m.params} for m in models]
    starts += [st for m in models for st in m.starts]
    for m in models:
        m.params, m.starts = list(params), list(starts)


def coefficient_params(
    ctx: Context, names: list[str], scales: list[float], span: float = 3.0
) -> list[Param]:
    """Additive changes of .tir coefficients (0 = the file's value), bounded at +-``span``
    times the larger of the typical scale and the file's magnitude, and within the
    coefficient's range (``model.params``: the node refuses a file outside it)."""
    out = []
    for k, s in zip(names, scales, strict=True):
        if k not in ctx.base:
            continue
        big = span * max(s, abs(ctx.base[k]))
        lo, hi = _table_range(k, ctx.base[k])
        out.append(Param(k, 0.0, max(-big, lo), min(big, hi), max(s, 0.1 * abs(ctx.base[k]))))
    return out


def _table_range(name: str, value: float) -> tuple[float, float]:
    """The change of ``name`` from ``value`` its range allows (0 always: the file's own)."""
    spec = PARAMETERS.get(name)
    lo, hi = -np.inf, np.inf
    if spec is not None and spec.minimum is not None:
        margin = 1e-3 * max(abs(spec.minimum), abs(value), 1e-3) if spec.strict_min else 0.0
        lo = min(spec.minimum + margin - value, 0.0)
    if spec is not None and spec.maximum is not None:
        hi = max(spec.maximum - value, 0.0)
    return lo, hi
