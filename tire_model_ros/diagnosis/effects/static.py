"""Static terms: force offsets, and the Magic Formula's camber and combined-slip terms.

An offset acts everywhere; camber and combined slip only in their region of the operating
range (their ``support``): away from zero inclination, where the other slip weighs a force
(the weighting functions are 1 in pure slip, eqs. 4.E51, 4.E59).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ..prepare import Context
from .base import Array, EffectModel, Index, Mask, Param, coefficient_params

CAMBER_MIN_RAD = np.radians(0.5)
WANDER_KNOT_S = 60.0  # a transducer zero wanders within its spec over minutes
# A usual weighting's B (rBx1, rBy1 about 10, C = 1): where it would change a force by more
# than the noise is where combined slip can show.
USUAL_B_COMBINED = 10.0
COMBINED_MIN_SHARE = 0.05  # of the samples where it can show, for combined slip to be tried


def inclination_moves(ctx: Context) -> bool:
    """Whether the wheel runs more than one inclination: what tells camber terms apart."""
    return bool(np.ptp(ctx.wheel.x("gamma")) > CAMBER_MIN_RAD)


class Offset(EffectModel):
    """Constant offsets: a load-cell zero on Fx and Fy, ply-steer as a slip-angle shift and
    conicity as a side force in proportion to the load (PHYSICS.md: Fy(alpha = 0) about 3 %
    of Fz, constant at zero slip, not scaling with inclination).

    ``wandering`` is its rival: the zeros piecewise linear in time between knots
    WANDER_KNOT_S apart, a transducer's zero wandering within its spec over minutes (an
    imperfection of the recording that a null may carry, not missing physics). A constant
    offset is one such zero; where the wandering one predicts held-out sweeps better, the
    offset is the zero's wander.
    """

    word = "offset"

    def __init__(self, ctx: Context, wandering: bool = False):
        self.wandering = wandering
        self.label = (
            "rival: force zeros wandering in time"
            if wandering
            else "force offsets, ply-steer and conicity"
        )
        self.knots = np.linspace(0.0, ctx.t_end, max(2, round(ctx.t_end / WANDER_KNOT_S) + 1))
        n = len(self.knots) if wandering else 1
        params = [
            Param(
                f"offset_{ch}_N{'_' + str(i) if wandering else ''}", 0.0, -1e5, 1e5, ctx.sigma[ch]
            )
            for ch in ctx.channels
            for i in range(n)
        ]
        if ctx.informative["y"]:
            params.append(Param("ply_steer_rad", 0.0, -0.02, 0.02, 5e-4))
            params.append(Param("conicity_Fy_N_at_FNOMIN", 0.0, -1e4, 1e4, ctx.sigma["Fy"]))
        super().__init__(params)

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        return [cls(ctx)]

    def rivals(self, ctx: Context) -> list[EffectModel]:
        return [Offset(ctx, wandering=True)]

    def inputs(self, x: Array, ctx: Context, inp: dict[str, Array | None]) -> None:
        v = self.values(x)
        if "ply_steer_rad" in v:
            alpha = inp["alpha"]
            assert alpha is not None
            inp["alpha"] = alpha + v["ply_steer_rad"]

    def output(self, x: Array, ctx: Context, out: dict[str, Array], rows: Index) -> None:
        v = self.values(x)
        for ch in ctx.channels:
            if not self.wandering:
                out[ch] = out[ch] + v.get(f"offset_{ch}_N", 0.0)
                continue
            zeros = [v[f"offset_{ch}_N_{i}"] for i in range(len(self.knots))]
            out[ch] = out[ch] + np.interp(ctx.wheel.t[rows], self.knots, zeros)
        if "conicity_Fy_N_at_FNOMIN" in v:
            load = ctx.wheel.x("Fz")[rows] / ctx.base["FNOMIN"]
            out["Fy"] = out["Fy"] + v["conicity_Fy_N_at_FNOMIN"] * load

    def carry(self, x: Array, ctx: Context) -> dict[str, Any] | None:
        v = self.values(x)
        offsets = {k.split("_")[1]: (val, 0.0) for k, val in v.items() if k.startswith("offset_")}
        if "conicity_Fy_N_at_FNOMIN" in v:
            offsets["Fy"] = (offsets.get("Fy", (0.0, 0.0))[0], v["conicity_Fy_N_at_FNOMIN"])
        return {"offsets": offsets, "alpha_shift_rad": v.get("ply_steer_rad", 0.0)}


class _CoefficientRefit(EffectModel):
    """Additive changes of named Magic Formula coefficients."""

    def coef(self, x: Array, ctx: Context) -> dict[str, float]:
        return {k: ctx.base[k] + float(v) for k, v in zip(self.pnames, x, strict=True)}


class Camber(_CoefficientRefit):
    """The MF camber coefficients refitted, with their load dependence (Fy: PVY3, PVY4 of
    SVyg, 4.E28; PKY6, PKY7 of Kyg0, 4.E30; PKY3 of Kya, 4.E25; PEY4 of Ey, 4.E24; PDY3 of
    muy, 4.E23; PHY3 (MF 5.2); Fx: PDX3, 4.E13): the tyre's (one set for the wheels of a
    car, which run them at their own inclinations and loads).

    ``combined``: with those of the combined-slip terms too (RBX3 of Bxa, 4.E54; RBY4 of Byk,
    4.E62; RVY3 of DVyk, 4.E67: a cambered wheel under drive or braking), where combined slip
    shows; a second form, as a rig's few combined sweeps at camber cannot hold them.
    """

    word = "camber"
    tyre = True

    def __init__(self, ctx: Context, combined: bool = False):
        self.combined = combined
        self.label = "Magic Formula camber coefficients" + (
            " with their combined-slip terms" if combined else ""
        )
        names, scales = [], []
        if ctx.informative["y"]:
            names += ["PVY3", "PVY4", "PKY6", "PKY7", "PKY3", "PEY4", "PHY3", "PDY3"]
            scales += [0.1, 0.1, 0.1, 0.1, 0.2, 2.0, 0.01, 0.5]
        if ctx.informative["x"]:
            names += ["PDX3"]
            scales += [1.0]
        if combined:
            names += ["RBX3", "RBY4", "RVY3"]
            scales += [100.0, 100.0, 0.1]
        super().__init__(coefficient_params(ctx, names, scales, span=50.0))

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        if not inclination_moves(ctx):
            return []
        out: list[EffectModel] = [cls(ctx)]
        return out + ([cls(ctx, combined=True)] if combined_shows(ctx) else [])

    def on(self, ctx: Context) -> EffectModel | None:
        return Camber(ctx, self.combined)

    def support(self, ctx: Context, x: Array | None = None) -> Mask | None:
        return np.asarray(np.abs(ctx.wheel.x("gamma")) > CAMBER_MIN_RAD, dtype=np.bool_)


class CombinedSlip(_CoefficientRefit):
    """The combined-slip weighting functions (Gxa: rBx1, rBx2, rCx1; Gyk: rBy1, rBy2, rCy1)
    and the slip-ratio-induced side force SVyk (rVy1, rVy2, rVy4, rVy5, rVy6) refitted
    (Pacejka 2012 eqs. 4.E50-4.E67); where the inclination moves, with their camber terms
    (rBx3 of Bxa, 4.E54; rBy4 of Byk, 4.E62; rVy3 of DVyk, 4.E67), which belong to both
    physics: the model a recording admits first holds them."""

    word = "combined_slip"
    label = "combined-slip weighting and induced side force (rBx, rCx, rBy, rCy, rVy)"
    tyre = True  # the tyre's coefficients: one set for the wheels of a car
    # Coefficient: (typical scale, a usual value to start from where the file has 0 (with
    # B = 0 a weighting is flat in B; with rVy4-6 = 0 the induced force has no gradient)).
    COEFS: ClassVar[dict[str, tuple[float, float]]] = {
        "RBX1": (1.0, 10.0), "RBX2": (1.0, 10.0), "RCX1": (0.1, 1.0), "RBY1": (1.0, 10.0),
        "RBY2": (1.0, 5.0), "RCY1": (0.1, 1.0), "RVY1": (0.01, 0.0), "RVY2": (0.01, 0.0),
        "RVY4": (5.0, 20.0), "RVY5": (0.2, 2.0), "RVY6": (1.0, 10.0),
    }  # fmt: skip
    CAMBER: ClassVar[dict[str, tuple[float, float]]] = {
        "RBX3": (100.0, 0.0), "RBY4": (100.0, 0.0), "RVY3": (0.1, 0.0),
    }  # fmt: skip

    def __init__(self, ctx: Context):
        coefs = self.COEFS | (self.CAMBER if inclination_moves(ctx) else {})
        names = list(coefs)  # proposed only where both slips are swept
        params = coefficient_params(ctx, names, [coefs[k][0] for k in names], 50.0)
        out = []
        for p in params:
            usual = coefs[p.name][1]
            if ctx.base[p.name] == 0.0 and usual:
                p = Param(p.name, usual, min(p.lo, -2 * usual), max(p.hi, 2 * usual), p.scale)
            out.append(p)
        super().__init__(out)

    @classmethod
    def propose(cls, ctx: Context) -> list[EffectModel]:
        return [cls(ctx)] if combined_shows(ctx) else []

    def support(self, ctx: Context, x: Array | None = None) -> Mask | None:
        return _combined_region(ctx)


def combined_shows(ctx: Context) -> bool:
    """Whether both slips are informative and combined slip can show on enough samples."""
    informative = ctx.informative["x"] and ctx.informative["y"]
    return bool(informative and _combined_region(ctx).mean() > COMBINED_MIN_SHARE)


def _combined_region(ctx: Context) -> Mask:
    """Where a usual combined-slip weighting would change a measured force by more than its
    noise: Fx by 1 - Gxa at the slip angle, Fy by 1 - Gyk at the slip ratio (eqs. 4.E54,
    4.E62 with B = USUAL_B_COMBINED, C = 1). A car cornering under a little drive torque has a
    slip ratio of a few thousandths, and its Fx is still weighted by the slip angle."""
    w = ctx.wheel

    def departs(slip: Array) -> Array:
        return np.asarray(1.0 - 1.0 / np.sqrt(1.0 + (USUAL_B_COMBINED * slip) ** 2))

    acts = np.zeros(w.n, dtype=np.bool_)
    for ch, slip in (("Fx", np.tan(w.x("alpha"))), ("Fy", w.x("kappa"))):
        if ch in w.meas:
            f = np.nan_to_num(np.abs(w.meas[ch]))
            acts |= departs(slip) * f > ctx.sigma[ch]
    return acts
