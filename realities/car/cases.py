"""The cases: which effects a session carries, their sizes, the programme style, the topics."""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field

import numpy as np

from tire_model_ros.model.params import PRESSURE_COEFFICIENTS

from . import config as C
from . import sim as S

CASES = (
    "heat_below", "heat_above", "heat_cross", "heat_recorded",
    "pressure_sealed", "pressure_leak", "pressure_recorded",
    "wear", "relaxation", "delay", "offset", "speed", "camber", "combined", "sidewall",
    "multi2_a", "multi2_b", "multi3",
    "null_1", "null_2", "null_3", "null_4", "null_5", "null_6",
)  # fmt: skip

MULTI_POOL = ("temperature", "pressure", "offset", "relaxation", "time_delay", "drift", "speed")
MULTI_LEADERS = ("temperature", "pressure", "offset", "time_delay")
NULL_IMPERFECTIONS = {
    "null_1": ("gain",),
    "null_2": ("spikes",),
    "null_3": ("dropouts",),
    "null_4": ("zero_walk",),
    "null_5": ("gain", "spikes", "dropouts"),
    "null_6": ("gain", "zero_walk", "spikes", "dropouts"),
}
FLAG_OF = {
    "temperature": S.TEMP,
    "pressure": S.PRESS,
    "relaxation": S.RELAX,
    "offset": S.OFFSET,
    "drift": S.WEAR,
    "speed": S.SPEED,
    "sidewall_contact": S.SIDEWALL,
    "camber": 0,
    "combined_slip": 0,
    "time_delay": 0,
}


@dataclass
class Effect:
    name: str  # INTERFACE.md word
    concealed: bool
    kind: str = ""  # heat side, pressure mode, ...
    scale: float = 1.0  # size knob (1 = as drawn)
    params: dict = field(default_factory=dict)
    ms_N2: float = 0.0
    detail: str = ""


@dataclass
class Setup:
    case: str
    seed: int
    minutes: float
    tyre: str
    effects: list
    null: bool
    record_temperature: bool
    record_pressure: bool
    warm_start: bool
    style: str
    imperfections: tuple
    rng_case: np.random.Generator
    notes: list = field(default_factory=list)


def case_rng(case: str, seed: int) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(case.encode())])


def make_setup(case: str, seed: int, minutes: float, rng: np.random.Generator) -> Setup:
    """Decide the case's effects (sizes are drawn later from the case rng)."""
    if case not in CASES:
        raise SystemExit(f"unknown case {case!r}; --list shows the cases")
    rc = case_rng(case, seed)
    tyre = "MF61" if rng.uniform() < 0.5 else "PacejkaBook"
    warm = rc.uniform() < 0.5
    style = "mixed"
    rec_T = False
    rec_p = False
    imp: tuple = ()
    eff: list = []
    null = False
    if case.startswith("heat_"):
        side = case[5:]
        if side == "recorded":
            side = ("below", "above", "cross")[int(rc.integers(3))]
            rec_T = True
        warm = {"below": rc.uniform() < 0.3, "above": rc.uniform() < 0.8, "cross": False}[side]
        eff.append(Effect("temperature", concealed=not rec_T, kind=side))
    elif case.startswith("pressure_"):
        mode = case[9:]
        if mode == "recorded":
            rec_p = True
        if mode == "sealed" or mode == "recorded":
            warm = rc.uniform() < 0.25
        eff.append(Effect("pressure", concealed=not rec_p, kind=mode))
    elif case == "wear":
        eff.append(Effect("drift", True, kind="wear"))
        style = "push"
    elif case == "relaxation":
        eff.append(Effect("relaxation", True))
    elif case == "delay":
        eff.append(Effect("time_delay", True))
    elif case == "offset":
        eff.append(Effect("offset", True))
    elif case == "speed":
        eff.append(Effect("speed", True))
        style = "push"
    elif case == "camber":
        eff.append(Effect("camber", True))
    elif case == "combined":
        eff.append(Effect("combined_slip", True))
        style = "push"
    elif case == "sidewall":
        tyre = "MF61"
        rec_p = True
        style = "push"
        eff.append(Effect("sidewall_contact", True))
    elif case.startswith("multi"):
        n = 3 if case == "multi3" else 2
        # the leader from the effects that can be made strong, the others from the whole pool
        lead = str(rc.choice(MULTI_LEADERS))
        rest = [q for q in MULTI_POOL if q != lead]
        names = [lead] + [str(q) for q in rc.choice(rest, size=n - 1, replace=False)]
        for nm in names:
            e = Effect(nm, True)
            if nm == "temperature":
                e.kind = ("below", "above", "cross")[int(rc.integers(3))]
                warm = {"below": False, "above": True, "cross": False}[e.kind]
            elif nm == "pressure":
                e.kind = "sealed" if rc.uniform() < 0.5 else "leak"
            elif nm == "drift":
                e.kind = "wear"
            eff.append(e)
    else:  # null
        null = True
        imp = NULL_IMPERFECTIONS[case]
        rec_T = rc.uniform() < 0.5
        rec_p = rc.uniform() < 0.5
    if not null and rc.uniform() < 0.25:
        imp = ("dropouts_mild",)
    return Setup(case, seed, minutes, tyre, eff, null, rec_T, rec_p, warm, style, imp, rc)


def tyre_files(setup: Setup, tir, T_amb: float):
    """(truth TirData, model.tir TirData, alternative truth for shadows or None)."""
    names = {e.name for e in setup.effects}
    truth = tir
    if setup.case == "sidewall":
        truth = truth.with_params({"PRESMIN": 100000.0})
    model = truth.with_params({"NOMTEMP": T_amb})
    truth = truth.with_params({"NOMTEMP": T_amb})
    alt = None
    if "camber" in names:
        model = model.with_params({k: 0.0 for k in C.CAMBER_COEFFICIENTS})
        alt = model
    if "combined_slip" in names:
        model = model.with_params({k: 0.0 for k in C.COMBINED_COEFFICIENTS})
        alt = model
    if "pressure" in names and any(e.kind == "recorded" for e in setup.effects):
        model = model.with_params({k: 0.0 for k in PRESSURE_COEFFICIENTS})
    return truth, model, alt


def draw_effect_params(setup: Setup, TP, WP, meas, tn, model_params, only=None):
    """Draw each effect's size into TP / WP / meas (the measurement-chain settings)."""
    rc = setup.rng_case
    pnom = model_params["NOMPRES"]
    if only is None:
        WP[:, S.W_P_SET] = pnom
        WP[:, S.W_P_OFF] = pnom
    for e in setup.effects if only is None else only:
        if e.name == "temperature":
            TP[S.T_DC] = rc.uniform(0.22, 0.32)
            TP[S.T_DH] = rc.uniform(0.25, 0.35)
            TP[S.T_KK] = rc.uniform(0.0015, 0.003)
        elif e.name == "pressure":
            if e.kind in ("sealed", "recorded"):
                TP[S.T_PMODE] = 1.0
                if e.kind == "recorded":
                    front = rc.uniform(0.85, 1.05)
                    rear = rc.uniform(0.85, 1.05)
                    WP[:, S.W_P_SET] = (
                        pnom * np.array([front, front, rear, rear]) * rc.uniform(0.98, 1.02, 4)
                    )
                e.params["gas_heat_scale"] = 1.0
            else:  # leak
                TP[S.T_PMODE] = 2.0
                allw = rc.uniform() < 0.5
                frac = rc.uniform(0.08, 0.2)
                if allw:
                    WP[:, S.W_LEAK] = 1.0
                else:
                    WP[int(rc.integers(4)), S.W_LEAK] = 1.0
                e.params["leak_fraction"] = frac
                TP[S.T_TAU_LEAK] = -setup.minutes * 60.0 / math.log(1.0 - frac)
        elif e.name == "relaxation":
            TP[S.T_SIGA] = rc.uniform(0.45, 0.7)
            TP[S.T_SIGK] = rc.uniform(0.18, 0.3)
            TP[S.T_APK] = max(tn["apk_f"], math.radians(4.0))
            TP[S.T_KPK] = tn["kpk_drv_f"]
        elif e.name == "offset":
            side = np.array([1.0, -1.0, 1.0, -1.0])
            c_ps = rc.uniform(0.004, 0.012) * rc.choice([-1.0, 1.0])
            c_con = rc.uniform(0.004, 0.012) * rc.choice([-1.0, 1.0])
            WP[:, S.W_C_OFF] = c_ps + side * c_con
            WP[:, S.W_MZ_OFF] = rc.uniform(2.0, 8.0, 4) * rc.choice([-1.0, 1.0], 4)
            meas["zero"] = np.stack(
                [
                    rc.uniform(15, 60, 4) * rc.choice([-1.0, 1.0], 4),
                    rc.uniform(15, 60, 4) * rc.choice([-1.0, 1.0], 4),
                ],
                1,
            )
            e.params.update({"ply_steer_Fy_per_Fz": c_ps, "conicity_Fy_per_Fz": c_con})
        elif e.name == "time_delay":
            meas["delay_s"] = rc.uniform(0.010, 0.040)
            meas["filter_hz"] = rc.uniform(15.0, 40.0)
        elif e.name == "drift":
            e.params["loss_target"] = rc.uniform(0.025, 0.06)
        elif e.name == "speed":
            TP[S.T_CV] = rc.uniform(0.01, 0.03)
            TP[S.T_VSREF] = rc.uniform(1.5, 2.5)
        elif e.name == "camber":
            pass
        elif e.name == "sidewall_contact":
            TP[S.T_DSW] = rc.uniform(0.15, 0.3)
            TP[S.T_AW] = math.radians(rc.uniform(1.5, 3.0))
            e.params["p_low"] = rc.uniform(110e3, 150e3)


def flags_for(effects, skip: str | None = None) -> int:
    f = 0
    for e in effects:
        if e.name != skip:
            f |= FLAG_OF[e.name]
    return f
