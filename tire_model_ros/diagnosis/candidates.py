"""One model per missing-physics candidate, and the predictor that composes them.

A candidate (a :class:`Component`) adds a few parameters to the recording's model and acts in
one or more of four places:

- ``coef``: updates of the Magic Formula coefficients (scaling factors, TTX/TTY, camber and
  combined-slip coefficients) -- global for the session;
- ``inputs``: transformed model inputs (a hidden temperature or gas-pressure state, lagged or
  delayed slip);
- ``mu_scale``: a per-sample friction scale (wear, speed-dependent friction, a friction
  step), applied by the similarity method (``_evaluate_similarity``);
- ``output``: additive force offsets.

The predictor evaluates the model once per wheel on the transformed inputs. Every component's
parameters have bounds and a typical scale (``x_scale`` for the optimiser).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from tire_model_ros.model.states import Node, gas_pressure_Pa

from .thermal import delayed, relaxed_slip, thermal_state_K

CHANNELS = ("Fx", "Fy", "Mz")
# Convention for a hidden temperature (PHYSICS.md: gain and TT coefficients are not separately
# identifiable with T hidden): the node's steady rise at the 95th-percentile frictional power
# is THERMAL_RISE_REF_K. The TTX/TTY coefficients are fitted on that scale.
THERMAL_RISE_REF_K = 20.0
# A tyre's thermal nodes cool within minutes (PHYSICS.md: bulk tau 1-5 min); a slower "thermal"
# change cannot be told from wear in a session and is left to the drift candidate.
TAU_MAX_S = 300.0
# The hidden thermal node is the fast (tread surface) node, tau of seconds (PHYSICS.md); it is
# always tried with the slow (carcass) node, whose time constants start where the fast ones end.
TAU_FAST_MAX_S = 20.0
TEMP_COEFS_X = ("TTX1", "TTX3")
TEMP_COEFS_Y = ("TTY1", "TTY3")


@dataclass
class Wheel:
    """One wheel's samples prepared for the diagnosis (full length, time from 0)."""

    prefix: str
    t: np.ndarray
    inputs: dict[str, np.ndarray | None]  # kappa, alpha, gamma, Fz, V, p, T
    meas: dict[str, np.ndarray]  # measured channels present: Fx, Fy, Mz
    P: np.ndarray  # frictional power [W] from measured forces
    E: np.ndarray  # cumulative frictional work [J]
    Vs: np.ndarray  # sliding speed [m/s]
    segments: list  # fit.sweeps.Segment, time order
    seg_id: np.ndarray  # segment number per sample
    fold: np.ndarray  # 0, 1 (selection folds) or 2 (final held-out) per sample
    scramble: np.ndarray  # sample order of a segment-shuffled copy of P (control)

    @property
    def n(self) -> int:
        return len(self.t)


@dataclass
class Context:
    """What every component may read: the file's model and the session-wide conventions."""

    model: object  # TireModel of FILE
    base: dict[str, float]
    wheels: list[Wheel]
    channels: tuple[str, ...]
    sigma: dict[str, float]  # noise level per channel [N or N m]
    T_amb: float  # ambient of a hidden thermal node = NOMTEMP [degC]
    k_thermal: float  # K per W (convention above)
    p_nom: float  # nominal gauge pressure [Pa]
    E_ref: float  # session's total frictional work per wheel (median) [J]
    t_end: float  # longest session [s]
    V0: float  # LONGVL [m/s]
    informative: dict[str, bool]  # "x": longitudinal slip swept, "y": lateral slip swept
    moving: dict[str, bool] = field(default_factory=dict)  # slip moves at all (transients)
    all_channels: tuple[str, ...] = ()  # every measured channel (reported), channels: fitted


@dataclass
class Component:
    """A candidate model part. ``name`` is the INTERFACE effect word; ``label`` the variant."""

    name: str
    label: str
    pnames: list[str]
    x0: list[float]
    lo: list[float]
    hi: list[float]
    scale: list[float]
    concealed: bool = False
    starts: list[dict[str, float]] = field(default_factory=list)  # extra starting points
    extends = ""  # name of the effect this component refines (not a new effect)

    def coef(self, x: np.ndarray, ctx: Context) -> dict[str, float]:
        return {}

    def inputs(self, x: np.ndarray, ctx: Context, w: Wheel, inp: dict) -> None:
        return None

    def mu_scale(self, x: np.ndarray, ctx: Context, w: Wheel) -> np.ndarray | None:
        return None

    def output(self, x: np.ndarray, ctx: Context, w: Wheel, wi: int, out: dict, rows) -> None:
        return None

    def settle(self, x: np.ndarray, ctx: Context, rows: list[np.ndarray]) -> np.ndarray:
        """``x`` with any parameter the fit's ``rows`` leave undetermined set to a neutral
        value (the fit has converged on ``rows``)."""
        return x

    def carry(self, x: np.ndarray, ctx: Context, wi: int) -> dict | None:
        """What a forward model of wheel ``wi`` runs of this part, as keyword arguments of
        :class:`~tire_model_ros.model.states.WheelEffects` ({}: nothing beyond the .tir
        coefficients); None: a part that no forward model carries (a session's history, a
        recording's artefact)."""
        return {}

    @property
    def n(self) -> int:
        return len(self.pnames)


# --- the baseline: a light refit of the file's scaling factors ---------------------------


class Scaling(Component):
    """Multiplicative scaling factors LMUX, LKX, LMUY, LKY (the fit that leaves physics out)."""

    def __init__(self, ctx: Context):
        names = []
        if ctx.informative["x"]:
            names += ["LMUX", "LKX"]
        if ctx.informative["y"]:
            names += ["LMUY", "LKY"]
        n = len(names)
        super().__init__("baseline", "scaling", names, [1.0] * n, [0.5] * n, [1.5] * n, [0.05] * n)

    def coef(self, x, ctx):
        return {k: ctx.base[k] * float(v) for k, v in zip(self.pnames, x, strict=True)}


# --- temperature ---------------------------------------------------------------------------


def _temp_coef_names(ctx: Context) -> list[str]:
    names: list[str] = []
    if ctx.informative["x"]:
        names += list(TEMP_COEFS_X)
    if ctx.informative["y"]:
        names += list(TEMP_COEFS_Y)
    return names


class ThermalHidden(Component):
    """Concealed temperature: one node heated by P_fric feeds the model's T input (TTX/TTY).

    ``mode``: "physical" (fitted tau), "memoryless" (tau ~ 0: T follows P_fric at once) or
    "scrambled" (the same node driven by a segment-shuffled P_fric) -- the last two are controls.
    """

    def __init__(self, ctx: Context, mode: str = "physical"):
        coefs = _temp_coef_names(ctx)
        names = ["tau_T_s", *coefs] if mode != "memoryless" else list(coefs)
        x0 = ([8.0] if mode != "memoryless" else []) + [0.0] * len(coefs)
        lo = ([0.3] if mode != "memoryless" else []) + [-3.0] * len(coefs)
        hi = ([TAU_FAST_MAX_S] if mode != "memoryless" else []) + [3.0] * len(coefs)
        sc = ([5.0] if mode != "memoryless" else []) + [0.1] * len(coefs)
        super().__init__(
            "temperature", f"hidden thermal node ({mode})", names, x0, lo, hi, sc, concealed=True
        )
        self.mode = mode
        self.ncoef = len(coefs)
        if mode != "memoryless":  # the time constant is the non-convex direction
            self.starts = [{"tau_T_s": 2.0}, {"tau_T_s": 15.0}]

    def tau_s(self, x) -> float:
        """The node's time constant [s] (the memoryless control: ~0)."""
        return 1e-3 if self.mode == "memoryless" else float(x[0])

    def coef(self, x, ctx):
        k0 = self.n - self.ncoef
        return {k: ctx.base[k] + float(v) for k, v in zip(self.pnames[k0:], x[k0:], strict=True)}

    def inputs(self, x, ctx, w, inp):
        P = w.P[w.scramble] if self.mode == "scrambled" else w.P
        inp["T"] = ctx.T_amb + thermal_state_K(P, w.t, self.tau_s(x), ctx.k_thermal)

    def carry(self, x, ctx, wi):
        return {"T_amb_C": ctx.T_amb, "thermal": Node(self.tau_s(x), ctx.k_thermal)}


class ThermalBulk(Component):
    """Extension of a hidden thermal node: the slow (carcass) node's loss of grip.

    A second node integrates the frictional work and cools with tau_bulk (1-5 min, PHYSICS.md):
    dTb/dt = P_fric / E_ref - Tb / tau_bulk (Tb in units of the session's work), and grip scales
    by (1 - c Tb). Unlike wear it recovers when the tyre cools; it is part of the
    ``temperature`` effect, tried together with the hidden thermal node (core._parts).
    """

    extends = "temperature"

    def __init__(self, ctx: Context):
        super().__init__(
            "temperature",
            "slow (carcass) node lowering grip",
            ["tau_bulk_s", "bulk_mu_loss"],
            [120.0, 0.0],
            [TAU_FAST_MAX_S, -0.6],
            [TAU_MAX_S, 0.6],
            [50.0, 0.02],
            concealed=True,
        )
        self.starts = [{"tau_bulk_s": 40.0}, {"tau_bulk_s": 250.0}]

    def mu_scale(self, x, ctx, w):
        tau = float(x[0])
        slow = thermal_state_K(w.P, w.t, tau, tau / ctx.E_ref)
        return 1.0 - float(x[1]) * slow

    def carry(self, x, ctx, wi):
        tau = float(x[0])
        return {"bulk": Node(tau, tau / ctx.E_ref), "bulk_mu_loss": float(x[1])}


class ThermalRecorded(Component):
    """Recorded temperature: fit the TTX/TTY coefficients the file lacks or has wrong."""

    def __init__(self, ctx: Context):
        coefs = _temp_coef_names(ctx)
        n = len(coefs)
        super().__init__(
            "temperature",
            "recorded temperature, TTX/TTY refit",
            coefs,
            [0.0] * n,
            [-3.0] * n,
            [3.0] * n,
            [0.1] * n,
        )

    def coef(self, x, ctx):
        return {k: ctx.base[k] + float(v) for k, v in zip(self.pnames, x, strict=True)}


# --- pressure --------------------------------------------------------------------------------


class GasHidden(Component):
    """Concealed pressure: one gas node heated by P_fric -> gas law -> the file's pressure terms."""

    def __init__(self, ctx: Context):
        super().__init__(
            "pressure",
            "hidden gas node, gas law, file's pressure terms",
            ["tau_gas_s", "gain_gas_K_per_kW"],
            [30.0, 2.0],
            [2.0, 0.0],
            [TAU_MAX_S, 200.0],
            [20.0, 2.0],
            concealed=True,
        )
        self.starts = [{"tau_gas_s": 5.0}, {"tau_gas_s": 100.0}]

    def inputs(self, x, ctx, w, inp):
        rise = thermal_state_K(w.P, w.t, float(x[0]), float(x[1]) * 1e-3)
        p0 = inp["p"] if inp["p"] is not None else ctx.p_nom
        inp["p"] = gas_pressure_Pa(p0, rise, ctx.T_amb)

    def carry(self, x, ctx, wi):
        return {"T_amb_C": ctx.T_amb, "gas": Node(float(x[0]), float(x[1]) * 1e-3)}


class PressureRecorded(Component):
    """Recorded pressure: refit the file's main pressure terms."""

    # MF 6.1: Kxk (PPX1, PPX2), mux (PPX3, PPX4), Kya (PPY1, PPY2), muy (PPY3, PPY4)
    NAMES = ("PPX1", "PPX2", "PPX3", "PPX4", "PPY1", "PPY2", "PPY3", "PPY4")

    def __init__(self, ctx: Context):
        names = [
            k
            for k in self.NAMES
            if (k[2] == "X" and ctx.informative["x"]) or (k[2] == "Y" and ctx.informative["y"])
        ]
        n = len(names)
        super().__init__(
            "pressure",
            "recorded pressure, pressure terms refit",
            names,
            [0.0] * n,
            [-3.0] * n,
            [3.0] * n,
            [0.1] * n,
        )

    def coef(self, x, ctx):
        return {k: ctx.base.get(k, 0.0) + float(v) for k, v in zip(self.pnames, x, strict=True)}


# --- transients --------------------------------------------------------------------------------


class Relaxation(Component):
    """First-order lag of slip in travelled distance, the MF 6.1 relaxation lengths.

    sigma_alpha = Kya / Cy and sigma_kappa = Kxk / Cx (Pacejka 2012 §7.2.1, MF 6.1): with the
    carcass stiffness taken constant, the lengths follow the file's slip stiffnesses in load.
    Fitted: the lengths at the nominal load FNOMIN.
    """

    def __init__(self, ctx: Context):
        names, x0 = [], []
        if ctx.moving["y"]:
            names.append("sigma_alpha_m")
            x0.append(0.3)
        # sigma_kappa is fitted only where slip ratio is swept in every fold; where it merely
        # moves, it follows sigma_alpha at the usual ratio (PHYSICS.md: 0.25 m vs ~0.5 m), so
        # that a lag is not left in one channel while nothing can calibrate a free length.
        self.kappa_ratio = 0.0
        if ctx.informative["x"] or (ctx.moving["x"] and not ctx.moving["y"]):
            names.append("sigma_kappa_m")
            x0.append(0.2)
        elif ctx.moving["x"]:
            self.kappa_ratio = 0.5
        n = len(names)
        super().__init__(
            "relaxation",
            "first-order lag in travelled distance (MF 6.1 lengths)",
            names,
            x0,
            [0.0] * n,
            [5.0] * n,
            [0.2] * n,
        )
        self.shape = {w.prefix: _stiffness_shape(ctx, w) for w in ctx.wheels}

    def inputs(self, x, ctx, w, inp):
        shape = self.shape[w.prefix]
        for k, v in zip(self.pnames, x, strict=True):
            key = "alpha" if k == "sigma_alpha_m" else "kappa"
            inp[key] = relaxed_slip(inp[key], w.t, inp["V"], float(v) * shape[key])
            if key == "alpha" and self.kappa_ratio > 0:
                sk = self.kappa_ratio * float(v) * shape["kappa"]
                inp["kappa"] = relaxed_slip(inp["kappa"], w.t, inp["V"], sk)

    def carry(self, x, ctx, wi):
        return None  # a simulator's own transient tyre model does this


def _stiffness_shape(ctx: Context, w: Wheel) -> dict[str, np.ndarray]:
    """Kya(Fz)/Kya(FNOMIN) and Kxk(Fz)/Kxk(FNOMIN) of the file's model, per sample."""
    Fz = np.maximum(w.inputs["Fz"], 0.0)
    FN = ctx.base["FNOMIN"]
    o = ctx.model.evaluate(np.append(Fz, FN), 0.0, 0.0, 0.0)
    out = {}
    for key, K in (("alpha", np.abs(np.asarray(o.Kya))), ("kappa", np.abs(np.asarray(o.Kxk)))):
        ref = K[-1] if np.isfinite(K[-1]) and K[-1] > 0 else 1.0
        sh = np.nan_to_num(K[:-1] / ref, nan=1.0)
        out[key] = np.clip(sh, 0.05, 3.0)
    return out


class Delay(Component):
    """Pure delay of the measured forces against the inputs (fitted over both signs)."""

    def __init__(self, ctx: Context):
        super().__init__(
            "time_delay", "pure delay of all inputs", ["tau_delay_s"], [0.01], [-0.3], [0.5], [0.01]
        )

    def inputs(self, x, ctx, w, inp):
        tau = float(x[0])
        for key in ("kappa", "alpha", "gamma", "Fz"):
            inp[key] = delayed(inp[key], w.t, tau)

    def carry(self, x, ctx, wi):
        return None  # an artefact of the recording, not of the tyre


# --- static terms ------------------------------------------------------------------------------


class Offset(Component):
    """Force offsets per wheel and channel: a constant (load-cell zero) and a part
    proportional to load (ply-steer, conicity: PHYSICS.md, Fy(alpha = 0) ~ 3 % of Fz).

    With ``drift_at`` [s] the constants may change at that time (the control of an offset's
    constancy: a real offset does not follow the session).
    """

    def __init__(
        self, ctx: Context, drift_at: float | None = None, channels: Sequence[str] | None = None
    ):
        self.channels = tuple(ctx.channels if channels is None else channels)
        names = []
        for i, w in enumerate(ctx.wheels):
            for ch in self.channels:
                if ch in w.meas:
                    names.append(f"offset_{ch}_{i}")
                    if np.ptp(w.inputs["Fz"]) > 0.2 * ctx.base["FNOMIN"]:
                        names.append(f"offsetperFz_{ch}_{i}")
                    if drift_at is not None:
                        names.append(f"offsetlate_{ch}_{i}")
        scales = [max(ctx.sigma[n.split("_")[1]], 1.0) for n in names]
        big = [1e5] * len(names)
        label = f"{'/'.join(self.channels)} offsets (constant + proportional to load)"
        if drift_at is not None:
            label = f"{'/'.join(self.channels)} offsets changing at t = {drift_at:.0f} s"
        super().__init__("offset", label, names, [0.0] * len(names), [-b for b in big], big, scales)
        self.drift_at = drift_at

    def output(self, x, ctx, w, wi, out, rows):
        for k, v in zip(self.pnames, x, strict=True):
            kind, ch, i = k.split("_")
            if int(i) != wi or ch not in out:
                continue
            if kind == "offset":
                out[ch] = out[ch] + float(v)
            elif kind == "offsetlate":
                out[ch] = out[ch] + float(v) * (w.t[rows] >= self.drift_at)
            else:  # N at FNOMIN, scaled with the load
                out[ch] = out[ch] + float(v) * w.inputs["Fz"][rows] / ctx.base["FNOMIN"]

    def carry(self, x, ctx, wi):
        if self.drift_at is not None:
            return None
        offsets: dict[str, tuple[float, float]] = {}
        for k, v in zip(self.pnames, x, strict=True):
            kind, ch, i = k.split("_")
            if int(i) == wi:
                a, b = offsets.get(ch, (0.0, 0.0))  # N, N at FNOMIN
                offsets[ch] = (float(v), b) if kind == "offset" else (a, float(v))
        return {"offsets": offsets}


class CoefRefit(Component):
    """Additive refit of named Magic Formula coefficients (camber, combined slip)."""

    def __init__(
        self,
        ctx: Context,
        name: str,
        label: str,
        names: list[str],
        scales: list[float],
        multiplicative: bool = False,
    ):
        names = [k for k in names if k in ctx.base]
        sc = [s for k, s in zip(names, scales, strict=False)]
        if multiplicative:
            super().__init__(
                name,
                label,
                names,
                [1.0] * len(names),
                [0.2] * len(names),
                [5.0] * len(names),
                [0.1] * len(names),
            )
        else:
            big = [50.0 * max(s, abs(ctx.base[k])) for k, s in zip(names, sc, strict=True)]
            super().__init__(
                name,
                label,
                names,
                [0.0] * len(names),
                [-b for b in big],
                big,
                [max(s, 0.1 * abs(ctx.base[k])) for k, s in zip(names, sc, strict=True)],
            )
        self.multiplicative = multiplicative

    def coef(self, x, ctx):
        if self.multiplicative:
            return {k: ctx.base[k] * float(v) for k, v in zip(self.pnames, x, strict=True)}
        return {k: ctx.base[k] + float(v) for k, v in zip(self.pnames, x, strict=True)}


def camber_component(ctx: Context) -> Component:
    names, scales = [], []
    if ctx.informative["y"]:
        names += ["PVY3", "PKY6", "PHY3", "PDY3"]
        scales += [0.1, 0.1, 0.01, 0.5]
    if ctx.informative["x"]:
        names += ["PDX3"]
        scales += [1.0]
    return CoefRefit(ctx, "camber", "Magic Formula camber coefficients", names, scales)


def combined_component(ctx: Context) -> Component:
    c = CoefRefit(
        ctx,
        "combined_slip",
        "combined-slip weighting (rBx1, rBy1, rCx1, rCy1)",
        ["RBX1", "RBY1", "RCX1", "RCY1"],
        [1.0, 1.0, 0.1, 0.1],
    )
    # With B = 0 the weighting is flat in B (cos is even): start a zeroed file at a usual B.
    for i, k in enumerate(c.pnames):
        if k in ("RBX1", "RBY1") and ctx.base[k] == 0.0:
            c.x0[i] = 10.0
        if k in ("RCX1", "RCY1") and ctx.base[k] == 0.0:
            c.x0[i] = 1.0
    return c


# --- per-sample friction scales ----------------------------------------------------------------


class Speed(Component):
    """Speed-dependent friction mu / (1 + LMUV Vs / V0) (the MF 6.1 form, Vs sliding speed)."""

    def __init__(self, ctx: Context):
        super().__init__("speed", "mu/(1+LMUV Vs/V0)", ["LMUV"], [0.0], [-0.5], [5.0], [0.05])

    def mu_scale(self, x, ctx, w):
        return 1.0 / np.maximum(1.0 + float(x[0]) * w.Vs / ctx.V0, 0.05)


class SpeedTable(Component):
    """Friction against sliding speed as a table: linear in ln Vs between fixed knots.

    A generic curve (no law assumed; it can rise, peak and fall), for friction that is not
    monotone in Vs. The knots are log-spaced over the sliding speeds where the tyre slides
    (5th to 99th percentile of Vs above 0.05 m/s); the one nearest the median is held at 1
    (the scaling factors carry the level), so the fitted values are relative to it.
    """

    KNOTS = 5

    def __init__(self, ctx: Context):
        Vs = np.concatenate([w.Vs for w in ctx.wheels])
        Vs = Vs[Vs > 0.05]
        lo, hi = np.percentile(Vs, [5, 99]) if len(Vs) > 10 else (0.1, 3.0)
        self.lnV = np.linspace(np.log(lo), np.log(max(hi, 2.0 * lo)), self.KNOTS)
        self.ref = int(np.argmin(np.abs(self.lnV - np.log(np.median(Vs) if len(Vs) else 1.0))))
        names = [f"mu_at_{np.exp(v):.2g}_mps" for i, v in enumerate(self.lnV) if i != self.ref]
        n = len(names)
        super().__init__(
            "speed",
            "friction table in ln Vs (piecewise linear)",
            names,
            [1.0] * n,
            [0.3] * n,
            [2.0] * n,
            [0.02] * n,
        )

    def mu_scale(self, x, ctx, w):
        return np.interp(np.log(np.maximum(w.Vs, 1e-4)), self.lnV, self._knots(x))

    def _knots(self, x) -> np.ndarray:
        return np.insert(np.asarray(x, float), self.ref, 1.0)

    def carry(self, x, ctx, wi):
        return {"speed_table": (tuple(map(float, self.lnV)), tuple(map(float, self._knots(x))))}


class FrictionStep(Component):
    """A step in friction at a fitted time (belt or road change between runs).

    mu scale = 1 - d H(t - t_c), with H a logistic of width STEP_WIDTH_S (after ``settle``, a
    ramp across the gap between fitted sweeps that holds t_c, or a step at the belt stop in
    that gap). The cost is flat in t_c across a pause (no force there) and has a local minimum
    at each one, so the fit starts from every pause (at most MAX_STARTS of them, evenly
    picked), where a change between runs happens, and keeps the best.
    """

    STEP_WIDTH_S = 1.0
    MAX_STARTS = 24
    # A belt stop: the belt speed below STOP_SPEED_MPS for STOP_MIN_S or more (between runs).
    STOP_SPEED_MPS = 0.5
    STOP_MIN_S = 5.0

    def __init__(self, ctx: Context):
        super().__init__(
            "drift",
            "friction step at a fitted time",
            ["t_step_s", "step_mu_loss"],
            [0.5 * ctx.t_end, 0.0],
            [0.0, -0.6],
            [ctx.t_end, 0.6],
            [0.05 * ctx.t_end, 0.02],
        )
        mids = sorted(
            float(np.mean(w.t[seg.index[[0, -1]]]))
            for w in ctx.wheels
            for seg in w.segments
            if seg.kind == "pause"
        )
        if len(mids) > self.MAX_STARTS:
            mids = [mids[i] for i in np.linspace(0, len(mids) - 1, self.MAX_STARTS).astype(int)]
        self.stops = sorted(m for w in ctx.wheels for m in self._stops(w))
        self.starts = [{"t_step_s": m} for m in sorted({*mids, *self.stops})]
        self.gap: tuple[float, float] | None = None  # set by ``settle``: where t_c may lie

    @classmethod
    def _stops(cls, w: Wheel) -> list[float]:
        """Middles of the wheel's belt stops [s from start]."""
        V = w.inputs["V"]
        if V is None:
            return []
        halted = np.concatenate([[False], np.abs(V) < cls.STOP_SPEED_MPS, [False]])
        edges = np.flatnonzero(np.diff(halted.astype(np.int8)))
        return [
            0.5 * (w.t[i0] + w.t[i1 - 1])
            for i0, i1 in zip(edges[::2], edges[1::2], strict=True)
            if w.t[i1 - 1] - w.t[i0] >= cls.STOP_MIN_S
        ]

    def settle(self, x, ctx, rows):
        """The change point to the belt stop in the gap between the fitted sweeps it lies in,
        else to the middle of the gap.

        Between two fitted sweeps (pauses, held-out sweeps) the cost is flat in t_c: the data
        place the change anywhere in the gap. A belt or road change happens between runs
        (PHYSICS.md), so a belt stop in the gap is where it is. Without one, its time is
        reported at the middle, and across the gap the model predicts the expected friction
        for a change time uniform in it (a linear ramp): a sweep in the gap that the fit did
        not see is then never given the wrong side of the step in full. Several stops in the
        gap: the same ramp, from the first stop to the last.
        """
        tc = float(x[0])
        seen = np.concatenate(
            [
                w.t[r][
                    (np.abs(w.inputs["kappa"][r]) > 0.005) | (np.abs(w.inputs["alpha"][r]) > 0.01)
                ]
                for w, r in zip(ctx.wheels, rows, strict=True)
            ]
        )
        before, after = seen[seen < tc], seen[seen >= tc]
        if len(before) and len(after):
            x = np.array(x, dtype=float)
            self.gap = (float(before.max()), float(after.min()))
            stops = [m for m in self.stops if self.gap[0] < m < self.gap[1]]
            if stops:
                self.gap = (stops[0], stops[-1])
            x[0] = 0.5 * sum(self.gap)
        return x

    def mu_scale(self, x, ctx, w):
        tc, d = float(x[0]), float(x[1])
        lo, hi = self.gap if self.gap and self.gap[0] <= tc <= self.gap[1] else (tc, tc)
        if hi - lo > self.STEP_WIDTH_S:
            return 1.0 - d * np.clip((w.t - lo) / (hi - lo), 0.0, 1.0)
        z = np.clip((w.t - tc) / self.STEP_WIDTH_S, -50.0, 50.0)
        return 1.0 - d / (1.0 + np.exp(-z))

    def carry(self, x, ctx, wi):
        return None  # the session's history


class Wear(Component):
    """Never-recovering drift: friction scale linear in cumulative frictional work (wear)."""

    def __init__(self, ctx: Context, driver: str = "work"):
        label = (
            "friction falls with cumulative frictional work"
            if driver == "work"
            else "friction changes linearly with time (plain trend)"
        )
        super().__init__("drift", label, ["drift_mu_per_session"], [0.0], [-0.6], [0.6], [0.02])
        self.driver = driver

    def mu_scale(self, x, ctx, w):
        z = w.E / ctx.E_ref if self.driver == "work" else w.t / ctx.t_end
        return 1.0 - float(x[0]) * z

    def carry(self, x, ctx, wi):
        return None  # the session's history


# --- the predictor -----------------------------------------------------------------------------


def split_x(components: list[Component], x: np.ndarray) -> list[np.ndarray]:
    out, i = [], 0
    for c in components:
        out.append(np.asarray(x[i : i + c.n], dtype=np.float64))
        i += c.n
    return out


def predict(
    components: list[Component], x: np.ndarray, ctx: Context, wi: int, rows: np.ndarray
) -> dict[str, np.ndarray]:
    """Model forces of wheel ``wi`` at sample indices ``rows`` for parameters ``x``."""
    w = ctx.wheels[wi]
    xs = split_x(components, x)
    upd: dict[str, float] = {}
    for c, xc in zip(components, xs, strict=True):
        upd.update(c.coef(xc, ctx))
    inp = dict(w.inputs)
    for c, xc in zip(components, xs, strict=True):
        c.inputs(xc, ctx, w, inp)
    s = None
    for c, xc in zip(components, xs, strict=True):
        m = c.mu_scale(xc, ctx, w)
        if m is not None:
            s = m if s is None else s * m
    args = {
        k: (None if inp[k] is None else inp[k][rows])
        for k in ("Fz", "kappa", "alpha", "gamma", "V", "p", "T")
    }
    if s is None:
        out = _evaluate(ctx.model, upd, args)
    else:
        out = _evaluate_similarity(ctx.model, upd, args, s[rows])
    for c, xc in zip(components, xs, strict=True):
        c.output(xc, ctx, w, wi, out, rows)
    return out


def _evaluate_similarity(model, upd: dict, a: dict, s: np.ndarray) -> dict[str, np.ndarray]:
    """A per-sample friction scale s by the similarity method (Pacejka 2012 §4.3.2):
    F = s F0(kappa / s, tan(alpha) / s), the slip stiffnesses kept."""
    a = dict(a)
    s = np.maximum(s, 0.05)
    a["kappa"] = a["kappa"] / s
    a["alpha"] = np.arctan(np.tan(a["alpha"]) / s)
    out = _evaluate(model, upd, a)
    return {ch: v * s for ch, v in out.items()}


def _evaluate(model, upd: dict, a: dict) -> dict[str, np.ndarray]:
    m = model.with_params(upd) if upd else model
    o = m.evaluate(
        a["Fz"], a["kappa"], a["alpha"], a["gamma"], Vx=a["V"], p=a["p"], T=a["T"], full=False
    )
    return {"Fx": np.asarray(o.Fx), "Fy": np.asarray(o.Fy), "Mz": np.asarray(o.Mz)}
