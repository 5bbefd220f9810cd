"""Generate one case: draw, calibrate, simulate (closed loop), measure, write the outputs."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
from scipy import signal

from realities._bag import write_bag
from tire_model_ros.model import TireModel, write_tir

from . import cases as K
from . import config as C
from . import measure as M
from . import sim as S
from .track import build_track, speed_profile

NAME = "car"
DT = 0.002  # simulation step [s]
SUB = 5  # steps per output sample (100 Hz)
T0 = 1_700_000_000.0  # first stamp [s] (an ordinary epoch time)


class Ctx:
    """Everything one simulation needs (mutable: the size knobs write into TP/WP/meas)."""


def _readonly(a):
    a = np.array(a, dtype=np.float64, copy=True)
    a.setflags(write=False)
    return a


def run_sim(ctx, flags, usealt, fast=False):
    return S.simulate(
        ctx.P0,
        ctx.P1,
        ctx.VP,
        ctx.TP,
        ctx.WP,
        ctx.trk,
        ctx.v,
        ctx.aff,
        ctx.road,
        np.asarray(flags, np.int64),
        np.asarray(usealt, np.int64),
        ctx.n_steps,
        DT,
        SUB,
        bool(fast),
    )


def road_profile(rng, n, VP):
    """Vertical load from road unevenness per wheel (band 1.5-15 Hz, ~1.5-3 % of static)."""
    b, a = signal.butter(2, [1.5, 15.0], btype="band", fs=1.0 / DT)
    x = signal.lfilter(b, a, rng.standard_normal((n, 4)), axis=0)
    x /= x.std(axis=0, keepdims=True)
    m, g, L = VP[S.V_M], VP[S.V_G], VP[S.V_A] + VP[S.V_B]
    stat = np.array([m * g * VP[S.V_B] / L / 2] * 2 + [m * g * VP[S.V_A] / L / 2] * 2)
    return np.ascontiguousarray(x * stat * rng.uniform(0.015, 0.03))


def make_profile(trk, laps, car, VP, pace_scale):
    lp = [dict(q, pace=q["pace"] * (pace_scale if q["pace"] > 0.85 else 1.0)) for q in laps]
    v, aff, _, _ = speed_profile(trk, lp, car, VP[S.V_V_INIT])
    return np.ascontiguousarray(v), np.ascontiguousarray(aff)


def spun(res) -> bool:
    o_in, o_v = res[0], res[3]
    return bool(np.abs(o_in[:, :, 1]).max() > math.radians(25.0) or o_v[:, S.L_VX].min() < 6.0)


# ----------------------------------------------------------------------------- size knobs
# effect -> [(where, key, lo, hi)]: the size parameters a knob scales, with their realistic
# ranges; where: TP index, "WP:<col>" (all wheels), "meas:<key>" or "param:<key>"
KNOBS = {
    "temperature": [
        (S.T_DC, "DC", 0.10, 0.45),
        (S.T_DH, "DH", 0.10, 0.45),
        (S.T_KK, "KK", 0.0005, 0.005),
    ],
    "pressure/sealed": [(S.T_GCG, "GCG", None, None), (S.T_EPSB, "EPSB", None, None)],
    "pressure/leak": [("param:leak_fraction", "frac", 0.05, 0.20)],
    "offset": [
        ("WP:%d" % S.W_C_OFF, "C_OFF", None, None),
        ("WP:%d" % S.W_MZ_OFF, "MZ", None, None),
        ("meas:zero", "zero", None, None),
    ],
    "relaxation": [(S.T_SIGA, "SIGA", 0.30, 0.80), (S.T_SIGK, "SIGK", 0.15, 0.40)],
    "time_delay": [("meas:delay_s", "delay", 0.010, 0.040)],
    "drift": [("param:loss_target", "loss", 0.015, 0.08)],
    "speed": [(S.T_CV, "CV", 0.01, 0.05)],
    "sidewall_contact": [(S.T_DSW, "DSW", 0.10, 0.35)],
}
# plain scale limits where a knob has no absolute range
SCALE_LIMITS = {"pressure/sealed": (0.5, 2.5), "offset": (0.4, 2.0)}


def _knob(e):
    if e.name == "pressure":
        return "pressure/leak" if e.kind == "leak" else "pressure/sealed"
    return e.name if e.name in KNOBS else None


def _get(ctx, e, where):
    if isinstance(where, str):
        kind, key = where.split(":")
        if kind == "WP":
            return ctx.WP[:, int(key)].copy()
        if kind == "meas":
            v = ctx.meas[key]
            return v.copy() if isinstance(v, np.ndarray) else v
        return e.params[key]
    return ctx.TP[where]


def _put(ctx, e, where, value):
    if isinstance(where, str):
        kind, key = where.split(":")
        if kind == "WP":
            ctx.WP[:, int(key)] = value
        elif kind == "meas":
            ctx.meas[key] = value
        else:
            e.params[key] = value
    else:
        ctx.TP[where] = value


def scale_limits(ctx, e):
    """(lo, hi) of e.scale that keep every size parameter inside its realistic range."""
    k = _knob(e)
    if k is None:
        return 1.0, 1.0
    if k in SCALE_LIMITS:
        return SCALE_LIMITS[k]
    b = e.params.setdefault("_base", {})
    lo, hi = 0.0, np.inf
    for where, key, vlo, vhi in KNOBS[k]:
        base = b.setdefault(key, _get(ctx, e, where))
        lo = max(lo, vlo / base)
        hi = min(hi, vhi / base)
    return lo, max(lo, hi)


def set_size(ctx, e):
    """Write effect e's size: its drawn base values times e.scale (kept inside the ranges)."""
    k = _knob(e)
    if k is None:
        return
    lo, hi = scale_limits(ctx, e)
    e.scale = float(np.clip(e.scale, lo, hi))
    b = e.params["_base"] if "_base" in e.params else e.params.setdefault("_base", {})
    for where, key, _vlo, _vhi in KNOBS[k]:
        base = b.setdefault(key, _get(ctx, e, where))
        _put(ctx, e, where, base * e.scale)
    if k == "pressure/leak":
        ctx.TP[S.T_TAU_LEAK] = -ctx.minutes * 60.0 / math.log(1.0 - e.params["leak_fraction"])
    elif k == "pressure/sealed":
        e.params["gas_heat_scale"] = e.scale
    elif k == "drift":
        ctx.TP[S.T_CW] = e.params["loss_target"] / ctx.ef_ref


def tunable(e) -> bool:
    return _knob(e) is not None


# ----------------------------------------------------------------------------- calibration
I20 = int(20 * M.RATE)


def place_topt(ctx, e, Tg, rc):
    """Put the grip optimum where the case wants it against a run's grip temperatures Tg."""
    TP = ctx.TP
    if e.kind == "below":
        TP[S.T_TOPT] = float(Tg.max() + rc.uniform(5.0, 15.0))
    elif e.kind == "above":
        TP[S.T_TOPT] = float(np.quantile(Tg[I20:], 0.02) - rc.uniform(2.0, 8.0))
    else:
        frac = rc.uniform(0.4, 0.65)
        TP[S.T_TOPT] = max(float(np.quantile(Tg, 1.0 - frac)), float(Tg[:I20].mean()) + 5.0)


def side_ok(ctx, e, Tg) -> bool:
    fa = float(np.mean(Tg > ctx.TP[S.T_TOPT]))
    if e.kind == "below":
        return fa <= 0.02
    if e.kind == "above":
        return float(np.mean(Tg[I20:] > ctx.TP[S.T_TOPT])) >= 0.95
    return float(Tg[:I20].mean()) < ctx.TP[S.T_TOPT] and 0.3 <= fa <= 0.8


def calibrate(ctx, setup):
    """A probe run without the state-dependent grip effects places the temperature window,
    the wear rate and the sidewall gate relative to what this car and driver actually do."""
    names = {e.name for e in setup.effects}
    if not names & {"temperature", "drift", "sidewall_contact"}:
        ctx.ef_ref = 1e6
        return None
    f = K.flags_for(setup.effects) & ~(S.TEMP | S.WEAR | S.SIDEWALL)
    o_in, o_th, o_F, o_v, o_lam, _ = run_sim(ctx, [f], [0])
    rc = setup.rng_case
    TP = ctx.TP
    info = {}
    ws = TP[S.T_WS]
    Tg = ws * o_th[:, :, 0] + (1 - ws) * o_th[:, :, 1]
    Tc = o_th[:, :, 1]
    i30 = int(30 * M.RATE)
    TP[S.T_TREFG] = float(np.median(Tg[i30:]))
    TP[S.T_TREFC] = float(np.median(Tc[i30:]))
    for e in setup.effects:
        if e.name == "temperature":
            place_topt(ctx, e, Tg, rc)
            info["probe_T_grip_range_degC"] = [float(Tg.min()), float(Tg.max())]
    ctx.ef_ref = float(o_th[-1, :, 3].max())
    for e in setup.effects:
        if e.name == "sidewall_contact":
            lw = ctx.low_wheel
            p = ctx.WP[lw, S.W_P_SET]
            dpi = (p - TP[S.T_PNOM]) / TP[S.T_PNOM]
            cz = TP[S.T_CZ0] * (1.0 + TP[S.T_PFZ1] * dpi)
            rho = o_in[:, lw, 3] / cz
            q = rc.uniform(0.78, 0.86)
            rho_c = float(np.quantile(rho, q))
            TP[S.T_RHOC] = rho_c
            TP[S.T_RHOW] = 0.12 * rho_c
            Fz_c = rho_c * cz * 1.1
            a = np.radians(np.linspace(0, 14, 281))
            Fy = ctx.truth_model.evaluate(Fz_c, 0.0, a, 0.0, 25.0, p=p).Fy
            a_pk = float(a[int(np.argmax(np.abs(Fy)))])
            a_on = a_pk * rc.uniform(0.92, 1.05)
            sel = np.abs(o_in[:, lw, 1])[rho > rho_c + TP[S.T_RHOW]]
            if sel.size and np.mean(sel > a_on) < 0.08:  # the driver does not get there often
                a_on = max(0.85 * a_pk, float(np.quantile(sel, 0.92)))
            TP[S.T_AON] = a_on
            e.params.update(
                {
                    "rho_contact_m": rho_c,
                    "alpha_peak_deg": math.degrees(a_pk),
                    "alpha_onset_deg": math.degrees(a_on),
                }
            )
    return info


# ----------------------------------------------------------------------------- effect sizes
def effect_sizes(ctx, setup, res):
    """ms_N2 of every effect: mean over samples and wheels of (dFx^2 + dFy^2), all effects on
    against that one switched off, on the same inputs, through the same measurement chain."""
    o_in, o_th, o_F, o_v, o_lam, fast = res
    meas = ctx.meas
    out = []
    for e in setup.effects:
        if e.name == "time_delay":
            Ff = M.delay_filter(fast[:, :, :2], 1.0 / DT, meas["delay_s"], meas["filter_hz"])
            D = Ff[::SUB][: o_F.shape[1]] - o_F[0][:, :, :2]
        else:
            j = ctx.shadow_of[e.name]
            D = o_F[0][:, :, :2] - o_F[j][:, :, :2]
            if "delay_s" in meas:
                D = M.delay_filter(D, M.RATE, meas["delay_s"], meas["filter_hz"])
            if e.name == "offset":
                D = D + meas["zero"][None, :, :]
        out.append(float(np.mean(np.sum(D * D, axis=-1))))
    return out


def _power(e, ms_now):
    """Exponent p of ms ~ scale^p from this effect's own history (2 when unknown)."""
    h = e.params.setdefault("_hist", [])
    h.append((e.scale, ms_now))
    for s0, m0 in reversed(h[:-1]):
        if abs(math.log(e.scale / s0)) > 0.05 and m0 > 0 and ms_now > 0:
            return float(np.clip(math.log(ms_now / m0) / math.log(e.scale / s0), 0.5, 3.0))
    return 2.0


def resize(ctx, setup, ms, nv) -> bool:
    """Keep every effect >= ~1.5x the noise variance and, with several, the leader >= 2.5x the
    others. ms ~ scale^p (p learnt from the runs so far); sizes stay inside their realistic
    ranges. The leader is chosen once: the strongest if it already leads, else the one that can
    become the strongest. True when a knob moved."""
    effs = setup.effects
    n = len(effs)
    lim = [scale_limits(ctx, e) for e in effs]
    pw = [_power(e, m) for e, m in zip(effs, ms, strict=True)]
    reach_hi = [ms[k] * (lim[k][1] / effs[k].scale) ** pw[k] for k in range(n)]
    reach_lo = [ms[k] * (lim[k][0] / effs[k].scale) ** pw[k] for k in range(n)]
    target = [2.0 * nv if m < 1.5 * nv else m for m in ms]
    target = [min(t, r) for t, r in zip(target, reach_hi, strict=True)]
    if n > 1:
        names = [e.name for e in effs]
        lead = getattr(ctx, "leader", None)
        if lead not in names:
            order = sorted(range(n), key=lambda k: -ms[k])
            k0 = (
                order[0]
                if ms[order[0]] >= 2.5 * ms[order[1]]
                else max(range(n), key=lambda k: reach_hi[k])
            )
            lead = names[k0]
            ctx.leader = lead
        kl = names.index(lead)
        others = [k for k in range(n) if k != kl]
        cap = reach_hi[kl] if not tunable(effs[kl]) else max(ms[kl], reach_hi[kl])
        for k in others:  # followers: visible, but well below what the leader can reach
            if target[k] * 2.6 > cap:
                target[k] = max(reach_lo[k], min(target[k], max(1.6 * nv, cap / 3.0)))
        if target[kl] < 2.6 * max(target[k] for k in others):
            target[kl] = min(3.0 * max(target[k] for k in others), cap)
    changed = False
    for k, e in enumerate(effs):
        if lim[k][0] == lim[k][1] or ms[k] <= 0 or abs(target[k] - ms[k]) < 1e-9 * ms[k]:
            continue
        new = float(np.clip(e.scale * (target[k] / ms[k]) ** (1.0 / pw[k]), *lim[k]))
        if abs(new - e.scale) > 1e-3 * e.scale:
            e.scale = new
            set_size(ctx, e)
            changed = True
    return changed


def instances(ctx, setup):
    """Flags of instance 0 (every effect) and of one shadow per tyre-level effect."""
    fl_main = K.flags_for(setup.effects)
    flags, usealt = [fl_main], [0]
    ctx.shadow_of = {}
    for e in setup.effects:
        if e.name == "time_delay":
            continue
        ctx.shadow_of[e.name] = len(flags)
        flags.append(fl_main & ~K.FLAG_OF[e.name])
        usealt.append(1 if e.name in ("camber", "combined_slip") else 0)
    return flags, usealt


def swap_candidate(ctx, setup, ms, nv):
    """Index of a non-leading effect whose largest realistic size stays below ~1.3x noise."""
    lead = int(np.argmax(ms))
    for k, e in enumerate(setup.effects):
        if k == lead or not tunable(e):
            continue
        lo, hi = scale_limits(ctx, e)
        if ms[k] * (hi / e.scale) ** 2 < 1.3 * nv:
            return k
    return None


def unset_effect(ctx, e):
    """Remove what a dropped effect left in the parameters (the flags go with the list)."""
    if e.name == "time_delay":
        ctx.meas.pop("delay_s", None)
        ctx.meas.pop("filter_hz", None)
    elif e.name == "offset":
        ctx.meas.pop("zero", None)
        ctx.WP[:, S.W_C_OFF] = 0.0
        ctx.WP[:, S.W_MZ_OFF] = 0.0
    elif e.name == "pressure":
        ctx.TP[S.T_PMODE] = 0.0
        ctx.WP[:, S.W_LEAK] = 0.0


# ----------------------------------------------------------------------------- main entry
def generate(
    case: str,
    seed: int,
    outdir,
    minutes: float = 8.0,
    verbose: bool = True,
    debug_npz=None,
    write: bool = True,
) -> dict:
    t_start = time.time()
    c_start = time.process_time()
    outdir = Path(outdir)
    if outdir.exists():
        raise SystemExit(f"{outdir} exists; give a new output directory")
    rng = np.random.default_rng(seed)
    setup = K.make_setup(case, seed, minutes, rng)
    rc = setup.rng_case
    # ---- tyre, car, track, sensors (per seed)
    base_tir = C.load_tyre(rng, setup.tyre, False)
    T_amb = float(rng.uniform(10.0, 30.0))
    truth_tir, model_tir, alt_tir = K.tyre_files(setup, base_tir, T_amb)
    truth_model = TireModel(truth_tir)
    VP, WP, car, vinfo, tn = C.draw_vehicle(rng, truth_model)
    TP = C.default_tp(rng, truth_model, T_amb)
    mirror = bool(rng.uniform() < 0.5)
    trk = build_track(rng, mirror)
    noise = M.draw_noise(rng)
    n_steps = int(round(minutes * 60.0 / DT))
    road = road_profile(rng, n_steps, VP)
    rng_meas = np.random.default_rng([seed, 7, 7])
    # ---- programme (per case)
    laps = C.lap_plan(rc, trk["length"], minutes, car, setup.style)
    v, aff = make_profile(trk, laps, car, VP, 1.0)
    ctx = Ctx()
    ctx.minutes = minutes
    ctx.truth_model = truth_model
    ctx.P0 = truth_model.coefficient_vector
    ctx.P1 = TireModel(alt_tir).coefficient_vector if alt_tir is not None else ctx.P0
    ctx.VP, ctx.TP, ctx.WP = VP, TP, WP
    ctx.trk = np.ascontiguousarray(np.stack([trk["x"], trk["y"], trk["th"], trk["k"]], 1))
    ctx.v, ctx.aff = v, aff
    ctx.road = road
    ctx.n_steps = n_steps
    ctx.meas = {}
    ctx.low_wheel = 0 if mirror else 1  # the outer front of the dominant corner direction
    ctx.tried = []
    K.draw_effect_params(setup, TP, WP, ctx.meas, tn, truth_model.params)
    # start state: cold, or pre-warmed in tyre blankets
    if setup.warm_start:
        Tb = rc.uniform(55.0, 80.0)
        TP[S.T_TINIT_S] = Tb - rc.uniform(0.0, 8.0)
        TP[S.T_TINIT_C] = Tb
        TP[S.T_TINIT_G] = Tb - rc.uniform(5.0, 15.0)
    for e in setup.effects:
        if e.name == "sidewall_contact":
            lw = ctx.low_wheel
            WP[lw, S.W_P_SET] = WP[lw, S.W_P_OFF] = e.params["p_low"]
            WP[lw, S.W_SW] = 1.0
            e.params["wheel"] = M.WHEELS[lw]
    t_setup = time.time() - t_start
    calib = calibrate(ctx, setup)
    for e in setup.effects:
        set_size(ctx, e)
    nv = 2.0 * noise["Fx_Fy_N"] ** 2
    flags, usealt = instances(ctx, setup)
    runs = 0
    spins = 0
    sized = 0
    swaps = 0
    pace_scale = 1.0
    while True:
        res = run_sim(ctx, flags, usealt, "delay_s" in ctx.meas)
        runs += 1
        if spun(res) and spins < 3:
            # the car left the road (a spin): the driver takes it easier, same programme
            spins += 1
            pace_scale *= 0.96
            setup.notes.append(f"spin in run {runs}: pushed-lap pace x{pace_scale:.2f}")
            ctx.v, ctx.aff = make_profile(trk, laps, car, VP, pace_scale)
            continue
        ms = effect_sizes(ctx, setup, res)
        if setup.null or sized >= (4 if len(setup.effects) > 1 else 3):
            break
        sized += 1
        changed = False
        for e in setup.effects:
            if e.name == "temperature":
                ws = TP[S.T_WS]
                Tg = ws * res[1][:, :, 0] + (1 - ws) * res[1][:, :, 1]
                if not side_ok(ctx, e, Tg):
                    place_topt(ctx, e, Tg, rc)
                    changed = True
        if not changed and len(setup.effects) > 1 and swaps < 2:
            # a follower that cannot be made visible inside its range is replaced by another
            # effect of the pool (one that needs no calibration run)
            k = swap_candidate(ctx, setup, ms, nv)
            if k is not None:
                used = {e.name for e in setup.effects} | set(ctx.tried)
                pool = [
                    q
                    for q in ("offset", "time_delay", "pressure", "relaxation", "speed")
                    if q not in used
                ]
                if pool:
                    old = setup.effects[k]
                    new = K.Effect(str(rc.choice(pool)), True)
                    if new.name == "pressure":
                        new.kind = "sealed" if rc.uniform() < 0.5 else "leak"
                    ctx.tried.append(old.name)
                    unset_effect(ctx, old)
                    setup.effects[k] = new
                    K.draw_effect_params(
                        setup, TP, WP, ctx.meas, tn, truth_model.params, only=[new]
                    )
                    set_size(ctx, new)
                    setup.notes.append(
                        f"{old.name} (at most {ms[k] / nv:.1f}x noise in range)"
                        f" replaced by {new.name}"
                    )
                    flags, usealt = instances(ctx, setup)
                    swaps += 1
                    sized -= 1
                    changed = True
        if not changed:
            changed = resize(ctx, setup, ms, nv)
        if not changed:
            break
    ctx.pace_scale = pace_scale
    if spun(res):
        setup.notes.append("WARNING: the final run still contains a spin")
    for e, m in zip(setup.effects, ms, strict=True):
        e.ms_N2 = m
    t_sim = time.time() - t_start - t_setup
    o_in, o_th, o_F, o_v, o_lam, fast = res
    n_out = o_F.shape[1]
    if debug_npz:
        np.savez(debug_npz, o_in=o_in, o_th=o_th, o_F=o_F, o_v=o_v, o_lam=o_lam)
    # ---- the measured (twin) forces: the transducers' own effects, no noise
    twinF = o_F[0].copy()
    if "delay_s" in ctx.meas:
        ff = M.delay_filter(fast, 1.0 / DT, ctx.meas["delay_s"], ctx.meas["filter_hz"])
        twinF = ff[::SUB][:n_out].copy()
    if "zero" in ctx.meas:
        twinF[:, :, 0:2] += ctx.meas["zero"][None, :, :]
    channels_rec, channels_twin, imperf = build_channels(
        setup, o_in, o_th, twinF, noise, rng_meas, n_out
    )
    outdir.mkdir(parents=True)
    if write:
        write_bag(outdir / "recording", channels_rec)
        write_bag(outdir / "twin", channels_twin)
    write_tir(model_tir, outdir / "model.tir")
    t_write = time.time() - t_start - t_setup - t_sim
    truth = make_truth(
        setup, ctx, truth_tir, model_tir, vinfo, trk, laps, noise, imperf, calib, res, twinF, runs
    )
    (outdir / "truth.json").write_text(json.dumps(truth, indent=2, default=_json_default))
    timing = {
        "setup_s": t_setup,
        "simulate_s": t_sim,
        "runs": runs,
        "write_s": t_write,
        "total_s": time.time() - t_start,
        "cpu_s": time.process_time() - c_start,
    }
    if verbose:
        print_summary(truth, res, twinF, nv, timing)
    return {"truth": truth, "timing": timing}


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    raise TypeError(type(o))


# ----------------------------------------------------------------------------- channels
def build_channels(setup, o_in, o_th, twinF, noise, rng, n_out):
    """Recording (noise, quantisation, imperfections) and twin (true) channels per wheel."""
    t = T0 + np.arange(n_out) / M.RATE
    rec, twin = {}, {}
    imperf = []
    imp = set(setup.imperfections)
    gains = np.ones(4)
    if "gain" in imp:
        gains = 1.0 + rng.uniform(0.005, 0.03, 4) * rng.choice([-1.0, 1.0], 4)
        imperf.append(
            {
                "kind": "gain",
                "detail": "load-cell gain error on every transducer "
                "channel (forces, moments, load)",
                "gain_minus_1": dict(zip(M.WHEELS, (gains - 1).tolist(), strict=True)),
            }
        )
    walk = {}
    if "zero_walk" in imp:
        sig, tau = rng.uniform(2.0, 5.0), rng.uniform(30.0, 120.0)
        imperf.append(
            {
                "kind": "zero_walk",
                "detail": "transducer zero wandering (Ornstein-Uhlenbeck) on Fx, Fy, Fz",
                "sigma_N": sig,
                "tau_s": tau,
            }
        )
        for i in range(4):
            walk[i] = np.stack([M.ou_walk(rng, n_out, sig, tau) for _ in range(3)], 1)
    spike_log = []
    drop_log = []
    sF = noise["Fx_Fy_N"]
    sigmas = np.array([sF, sF, noise["Fz_N"], noise["M_Nm"], noise["M_Nm"], noise["M_Nm"]])
    for i, pre in enumerate(M.WHEELS):
        slip_true = o_in[:, i, 0:3]
        slip = slip_true + rng.standard_normal((n_out, 3)) * [
            noise["kappa"],
            noise["alpha_rad"],
            noise["gamma_rad"],
        ]
        slip = M.quant(slip, 1e-6)
        F = twinF[:, i, :] * gains[i]
        if i in walk:
            F[:, 0:3] += walk[i]
        F = F + rng.standard_normal((n_out, 6)) * sigmas
        if "spikes" in imp:
            for q in range(6):
                nsp = rng.binomial(n_out, 1.0 / 5000.0)
                idx = rng.integers(0, n_out, nsp)
                amp = rng.uniform(5.0, 30.0, nsp) * sigmas[q] * rng.choice([-1.0, 1.0], nsp)
                F[idx, q] += amp
                spike_log += [
                    {
                        "wheel": pre,
                        "channel": "FxFyFzMxMyMz"[2 * q : 2 * q + 2],
                        "t_s": float(t[k] - T0),
                        "size_sigma": float(abs(a) / sigmas[q]),
                    }
                    for k, a in zip(idx, amp, strict=True)
                ]
        F[:, 0:3] = M.quant(F[:, 0:3], noise["quant_force_N"])
        F[:, 3:6] = M.quant(F[:, 3:6], noise["quant_moment_Nm"])
        Vx = o_in[:, i, 4]
        vel = Vx + rng.standard_normal(n_out) * noise["Vx_mps"]
        keep = {ch: np.ones(n_out, bool) for ch in ("slip", "load", "measured_forces", "velocity")}
        if "dropouts" in imp or "dropouts_mild" in imp:
            mild = "dropouts" not in imp
            count = int(rng.integers(1, 4)) if mild else int(rng.integers(3, 8))
            topics = (
                ("velocity", "measured_forces")
                if mild
                else ("slip", "load", "measured_forces", "velocity")
            )
            for _ in range(count):
                ch = topics[int(rng.integers(len(topics)))]
                m, spans = M.gaps(rng, n_out, 1)
                keep[ch] &= m
                drop_log += [{"wheel": pre, "topic": ch, "from_s": a, "to_s": b} for a, b in spans]
        r = {}
        w = {}
        ks = keep["slip"]
        r["slip"] = (t[ks], slip[ks])
        w["slip"] = (t[ks], slip_true[ks])
        kl = keep["load"]
        r["load"] = (t[kl], F[kl, 2])
        w["load"] = (t, twinF[:, i, 2])
        kf = keep["measured_forces"]
        r["measured_forces"] = (t[kf], F[kf])
        w["measured_forces"] = (t, twinF[:, i, :])
        sv = np.zeros(n_out, bool)
        sv[:: M.VEL_EVERY] = True
        r["velocity"] = (t[sv & keep["velocity"]], vel[sv & keep["velocity"]])
        w["velocity"] = (t[sv], Vx[sv])
        st = np.zeros(n_out, bool)
        st[:: M.TEMP_EVERY] = True
        Ts = o_th[:, i, 0]
        w["temperature"] = (t[st], Ts[st])
        if setup.record_temperature:
            a = math.exp(-1.0 / (M.RATE * noise["T_lag_s"]))
            lag = signal.lfilter([1 - a], [1, -a], Ts, zi=[a * Ts[0]])[0]
            Tm = M.quant(lag + rng.standard_normal(n_out) * noise["T_degC"], noise["quant_T_degC"])
            r["temperature"] = (t[st], Tm[st])
        sp = np.zeros(n_out, bool)
        sp[:: M.PRES_EVERY] = True
        p = o_in[:, i, 5]
        w["pressure"] = (t[sp], p[sp])
        if setup.record_pressure:
            pm = M.quant(p + rng.standard_normal(n_out) * noise["p_Pa"], noise["quant_p_Pa"])
            r["pressure"] = (t[sp], pm[sp])
        rec[pre] = r
        twin[pre] = w
    if spike_log:
        imperf.append(
            {
                "kind": "spikes",
                "detail": "single-sample spikes on the transducer "
                "channels, about 1 in 5000 samples per channel",
                "count": len(spike_log),
                "list": spike_log,
            }
        )
    if drop_log:
        imperf.append(
            {
                "kind": "dropouts" if "dropouts" in imp else "dropouts_mild",
                "detail": "gaps of 0.05-0.5 s in some topics (the twin drops the same "
                "slip samples)",
                "count": len(drop_log),
                "list": drop_log,
            }
        )
    return rec, twin, imperf


# ----------------------------------------------------------------------------- truth
def _effect_entry(e, ctx, setup, res):
    o_in, o_th, o_F, o_v, o_lam, _ = res
    TP, WP, meas = ctx.TP, ctx.WP, ctx.meas
    par = {k: v for k, v in e.params.items() if not k.startswith("_")}
    deg = math.degrees
    if e.name == "temperature":
        ws = TP[S.T_WS]
        Tg = ws * o_th[:, :, 0] + (1 - ws) * o_th[:, :, 1]
        frac_above = float(np.mean(Tg > TP[S.T_TOPT]))
        par.update(
            {
                "side": e.kind,
                "T_opt_degC": TP[S.T_TOPT],
                "grip_drop_cold": TP[S.T_DC],
                "width_cold_K": TP[S.T_WC],
                "grip_drop_hot": TP[S.T_DH],
                "width_hot_K": TP[S.T_WH],
                "surface_weight": ws,
                "T_ref_grip_degC": TP[S.T_TREFG],
                "stiffness_per_K_carcass": TP[S.T_KK],
                "T_ref_carcass_degC": TP[S.T_TREFC],
                "T_grip_range_degC": [float(Tg.min()), float(Tg.max())],
                "fraction_above_optimum": frac_above,
                "grip_factor_range": [float(o_lam[:, :, 0].min()), float(o_lam[:, :, 0].max())],
                "stiffness_factor_range": [
                    float(o_lam[:, :, 1].min()),
                    float(o_lam[:, :, 1].max()),
                ],
                "start": "pre-warmed (blankets)" if setup.warm_start else "cold",
                "T_surface_range_degC": [float(o_th[:, :, 0].min()), float(o_th[:, :, 0].max())],
            }
        )
        detail = (
            f"tread grip window on T = {ws:.2f} surface + {1 - ws:.2f} carcass, optimum "
            f"{TP[S.T_TOPT]:.1f} degC (skewed: -{TP[S.T_DC]:.2f} over {TP[S.T_WC]:.0f} K "
            f"cold, -{TP[S.T_DH]:.2f} over {TP[S.T_WH]:.0f} K hot); the tyre runs "
            f"{e.kind} the optimum ({100 * frac_above:.0f} % of samples above); "
            f"stiffness exp(-{TP[S.T_KK]:.4f} (Tc - {TP[S.T_TREFC]:.1f}))"
        )
    elif e.name == "pressure":
        p = o_in[:, :, 5]
        par.update(
            {
                "mode": e.kind,
                "set_pressure_Pa": dict(zip(M.WHEELS, WP[:, S.W_P_SET], strict=True)),
                "pressure_range_Pa": dict(
                    zip(M.WHEELS, np.stack([p.min(0), p.max(0)], 1), strict=True)
                ),
                "gas_T_range_degC": [float(o_th[:, :, 2].min()), float(o_th[:, :, 2].max())],
            }
        )
        if e.kind == "leak":
            par["leaking_wheels"] = [M.WHEELS[i] for i in range(4) if WP[i, S.W_LEAK] > 0]
            par["leak_time_constant_s"] = TP[S.T_TAU_LEAK]
            detail = (
                f"slow leak on {', '.join(par['leaking_wheels'])}: gauge pressure "
                f"falls {100 * e.params['leak_fraction']:.0f} % over the session "
                "(exponential), no link to heat"
            )
        else:
            detail = (
                "sealed tyre: gas node heated by the carcass (and brake heat through the "
                "rim); p_abs = p_set_abs (T_gas + 273.15)/(T_set + 273.15); pressure "
                f"{p.min() / 1e3:.0f}..{p.max() / 1e3:.0f} kPa gauge; forces change "
                "through the .tir pressure terms only"
            )
            if e.kind == "recorded":
                detail += "; per-wheel set points; model.tir has every pressure coefficient 0"
    elif e.name == "relaxation":
        par.update(
            {
                "sigma_alpha_max_m": TP[S.T_SIGA],
                "sigma_kappa_max_m": TP[S.T_SIGK],
                "load_scale_N": TP[S.T_FSIG],
                "slip_reduction": TP[S.T_ASRED],
                "alpha_ref_deg": deg(TP[S.T_APK]),
                "kappa_ref": TP[S.T_KPK],
            }
        )
        detail = (
            f"first order in travelled distance, sigma = sigma_max tanh(Fz/{TP[S.T_FSIG]:.0f}"
            f" N) (1 - {TP[S.T_ASRED]:.2f} min(1, |slip|/slip_ref)); sigma_alpha_max "
            f"{TP[S.T_SIGA]:.2f} m, sigma_kappa_max {TP[S.T_SIGK]:.2f} m"
        )
    elif e.name == "time_delay":
        par.update(
            {
                "delay_s": meas["delay_s"],
                "filter": "2nd-order Butterworth low-pass",
                "filter_hz": meas["filter_hz"],
                "channels": "measured_forces and load (the wheel-force transducers)",
            }
        )
        detail = (
            f"transducer data {1e3 * meas['delay_s']:.1f} ms late against the slip, then "
            f"a causal {meas['filter_hz']:.0f} Hz 2nd-order low-pass"
        )
    elif e.name == "offset":
        par.update(
            {
                "Fy_offset_per_Fz": dict(zip(M.WHEELS, WP[:, S.W_C_OFF], strict=True)),
                "Mz_offset_Nm": dict(zip(M.WHEELS, WP[:, S.W_MZ_OFF], strict=True)),
                "transducer_zero_Fx_Fy_N": dict(zip(M.WHEELS, meas["zero"], strict=True)),
            }
        )
        detail = (
            "ply-steer (same sign on every wheel) and conicity (sign flips left/right) as "
            "Fy = c Fz with a small Mz, plus a constant transducer zero on Fx and Fy"
        )
    elif e.name == "drift":
        ef = o_th[-1, :, 3]
        par.update(
            {
                "grip_loss_per_J": TP[S.T_CW],
                "frictional_energy_end_J": dict(zip(M.WHEELS, ef, strict=True)),
                "grip_loss_end": dict(zip(M.WHEELS, TP[S.T_CW] * ef, strict=True)),
            }
        )
        detail = (
            f"wear: grip x (1 - {TP[S.T_CW]:.3g} E_f), E_f the frictional energy (J); "
            f"loss at the end {100 * TP[S.T_CW] * ef.min():.1f}..{100 * TP[S.T_CW] * ef.max():.1f} %"
            ", irreversible"
        )
    elif e.name == "speed":
        par.update({"c_v_s_per_m": TP[S.T_CV], "Vs_ref_mps": TP[S.T_VSREF]})
        detail = (
            f"friction x (1 + {TP[S.T_CV]:.3f} Vs_ref)/(1 + {TP[S.T_CV]:.3f} Vs), "
            f"Vs = V sqrt(kappa^2 + tan^2 alpha), Vs_ref {TP[S.T_VSREF]:.2f} m/s"
        )
    elif e.name == "camber":
        g = o_in[:, :, 2]
        par.update(
            {
                "zeroed_in_model_tir": list(C.CAMBER_COEFFICIENTS),
                "gamma_range_deg": [deg(g.min()), deg(g.max())],
            }
        )
        detail = (
            "the tyre keeps its .tir camber terms; model.tir has every inclination "
            f"coefficient 0; gamma {deg(g.min()):.1f}..{deg(g.max()):.1f} deg (static "
            "camber plus roll)"
        )
    elif e.name == "combined_slip":
        par.update({"zeroed_in_model_tir": list(C.COMBINED_COEFFICIENTS)})
        detail = (
            "the tyre keeps its .tir combined-slip weighting; model.tir has Gxa = Gyk = 1 "
            "and no kappa-induced side force; trail braking and power out of corners"
        )
    elif e.name == "sidewall_contact":
        lw = ctx.low_wheel
        cz = TP[S.T_CZ0] * (1 + TP[S.T_PFZ1] * (WP[lw, S.W_P_SET] - TP[S.T_PNOM]) / TP[S.T_PNOM])
        rho = o_in[:, lw, 3] / cz
        a_on = TP[S.T_AON] * np.sqrt(TP[S.T_RHOC] / np.maximum(rho, TP[S.T_RHOC]))
        touch = (rho > TP[S.T_RHOC]) & (np.abs(o_in[:, lw, 1]) > a_on)
        par.update(
            {
                "drop_max": TP[S.T_DSW],
                "alpha_width_deg": deg(TP[S.T_AW]),
                "rho_width_m": TP[S.T_RHOW],
                "vertical_stiffness_N_per_m": cz,
                "fraction_of_wheel_samples_in_contact": float(touch.mean()),
            }
        )
        detail = (
            f"{M.WHEELS[lw]} at {WP[lw, S.W_P_SET] / 1e3:.0f} kPa: beyond deflection "
            f"{1e3 * TP[S.T_RHOC]:.1f} mm (Fz/Cz(p)) and slip angle "
            f"{deg(TP[S.T_AON]):.1f} deg (smaller at larger deflection) the forces drop by "
            f"up to {100 * TP[S.T_DSW]:.0f} %"
        )
    else:
        detail = ""
    if tunable(e):
        par["size_scale"] = e.scale
    return {
        "name": e.name,
        "concealed": bool(e.concealed),
        "ms_N2": float(e.ms_N2),
        "detail": detail,
        "parameters": par,
    }


def make_truth(
    setup, ctx, truth_tir, model_tir, vinfo, trk, laps, noise, imperf, calib, res, twinF, runs
):
    o_in, o_th, o_F, o_v, o_lam, _ = res
    effects = sorted(
        (_effect_entry(e, ctx, setup, res) for e in setup.effects), key=lambda d: -d["ms_N2"]
    )
    L = trk["length"]
    s = o_v[:, S.L_S]
    lap_no = np.floor(s / L).astype(int)
    starts = [0.0] + [float(k / M.RATE) for k in np.nonzero(np.diff(lap_no) > 0)[0] + 1]
    prog = []
    for j, t0 in enumerate(starts):
        lp = laps[min(j, len(laps) - 1)]
        pc = lp["pace"] * (ctx.pace_scale if lp["pace"] > 0.85 else 1.0)
        prog.append(f"lap {j + 1} ({lp['kind']}, pace {pc:.2f}) from {t0:.0f} s")
    a = np.degrees(np.abs(o_in[:, :, 1]))
    k = o_in[:, :, 0]
    programme = (
        f"{setup.minutes:g} min on a {L / 1000:.2f} km {trk['direction']} track "
        f"({trk['description']}); "
        + "; ".join(prog)
        + f". Speeds {o_v[:, S.L_VX].min():.0f}..{o_v[:, S.L_VX].max():.0f} m/s, "
        f"|ay| up to {np.abs(o_v[:, S.L_AY]).max() / 9.81:.2f} g, slip angle 99.5th "
        f"percentile {np.quantile(a, 0.995):.1f} deg, kappa "
        f"{np.quantile(k, 0.002):.3f}..{np.quantile(k, 0.998):.3f}."
    )
    desc = (
        f"A {vinfo['mass_kg']:.0f} kg {vinfo['drive']} car with four {setup.tyre} tyres "
        f"({Path(C.TIR_DIR / C.TYRES[setup.tyre]).name}) laps a track at "
        f"{ctx.TP[S.T_TAMB]:.0f} degC ambient; a closed-loop driver follows the racing line "
        "with a speed profile (pushed, moderate and a cool-down lap), braking into corners "
        "and accelerating out. Load transfer (roll/pitch lag), camber from static setting and"
        " roll, and the tyre forces drive the car. Hub wheel-force transducers record Fx, Fy,"
        " Fz, Mx, My, Mz; the slip comes from wheel speed and the velocity at each wheel. "
    )
    if setup.null:
        desc += (
            "Nothing is missing from model.tir: the tyres follow it exactly; only sensor "
            "imperfections (" + ", ".join(i["kind"] for i in imperf) + ") disturb the "
            "recording."
        )
    else:
        desc += (
            "Missing from model.tir: "
            + "; ".join(f"{e['name']} ({e['detail']})" for e in effects)
            + "."
        )
    thermal = {
        k: float(ctx.TP[getattr(S, "T_" + k)])
        for k in (
            "CS",
            "CC",
            "CG",
            "GSC",
            "GSA0",
            "GSA1",
            "GSR",
            "GCA0",
            "GCA1",
            "GCG",
            "GGA0",
            "GGA1",
            "FT",
            "ETAS",
            "FH",
            "EPSB",
            "TAMB",
            "TROAD",
            "TINIT_S",
            "TINIT_C",
            "TINIT_G",
        )
    }
    return {
        "generator": NAME,
        "case": setup.case,
        "seed": setup.seed,
        "minutes": setup.minutes,
        "wheels": list(M.WHEELS),
        "null": setup.null,
        "effects": effects,
        "imperfections": imperf,
        "tyre": f"{C.TYRES[setup.tyre]}"
        + (" (+ drawn pressure coefficients)" if setup.tyre == "PacejkaBook" else "")
        + (", PRESMIN 100 kPa" if setup.case == "sidewall" else ""),
        "noise": dict(
            noise,
            force_noise_variance_N2=2 * noise["Fx_Fy_N"] ** 2,
            note="white Gaussian per sample, sigma as given; sum over Fx and Fy in "
            "force_noise_variance_N2",
        ),
        "programme": programme,
        "description": desc,
        "topics_recorded": {
            "temperature": setup.record_temperature,
            "pressure": setup.record_pressure,
            "velocity": True,
        },
        "car": vinfo,
        "thermal_model": thermal,
        "calibration": calib or {},
        "simulation": {
            "dt_s": DT,
            "output_rate_Hz": M.RATE,
            "closed_loop_runs": runs,
            "calibration_run": bool(calib),
            "stamp_origin_s": T0,
            "notes": setup.notes,
        },
    }


def print_summary(truth, res, twinF, nv, timing):
    o_in = res[0]
    print(
        f"[car] case {truth['case']} seed {truth['seed']}: {truth['tyre']}, "
        f"{truth['car']['mass_kg']:.0f} kg {truth['car']['drive']}, "
        f"noise var (Fx+Fy) {nv:.0f} N^2"
    )
    for e in truth["effects"]:
        print(
            f"  effect {e['name']:<16s} concealed={e['concealed']!s:<5s} ms_N2 {e['ms_N2']:10.0f}"
            f"  = {e['ms_N2'] / nv:7.1f} x noise"
        )
    for i in truth["imperfections"]:
        print(f"  imperfection {i['kind']}")
    a = np.degrees(o_in[:, :, 1])
    print(
        f"  alpha {a.min():.1f}..{a.max():.1f} deg, kappa {o_in[:, :, 0].min():.3f}.."
        f"{o_in[:, :, 0].max():.3f}, Fz {o_in[:, :, 3].min():.0f}..{o_in[:, :, 3].max():.0f} N,"
        f" |Fy| max {np.abs(twinF[:, :, 1]).max():.0f} N"
    )
    print(
        f"  time: setup {timing['setup_s']:.1f} s, simulate {timing['simulate_s']:.1f} s "
        f"({timing['runs']} runs), write {timing['write_s']:.1f} s, total "
        f"{timing['total_s']:.1f} s wall, {timing['cpu_s']:.1f} s cpu"
    )
