"""Generate one case: simulate, size the effects, add the DAQ, write the bags and the truth."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from realities._bag import write_bag

from . import cases as cs
from . import daq
from . import physics as ph

NAME = "flattrac"
PREFIX = "/rig/wheel"
DEG = np.pi / 180.0

DESCRIPTIONS = {
    "temperature": "tread grip follows a skewed temperature window of the tread surface/bulk "
                   "(three-node thermal model heated by frictional power), carcass stiffness "
                   "falls with bulk temperature",
    "pressure": "inflation pressure differs from the file's nominal one and acts through the "
                "tyre's own pressure terms",
    "drift": "grip lost to wear in proportion to the cumulative frictional energy (never recovers)",
    "relaxation": "forces lag the slip: first order in travelled distance, lengths growing with "
                  "load and shrinking with slip",
    "time_delay": "measured forces recorded late: transport delay plus the load-cell DAQ's "
                  "causal low-pass, slip channels undelayed",
    "offset": "ply-steer (slip-angle shift), conicity (lateral force proportional to Fz) and a "
              "load-cell zero on Fx",
    "speed": "friction depends on sliding speed (Savkoor-type law, peak at vm)",
    "camber": "the tyre's inclination terms act; model.tir has every inclination coefficient 0",
    "combined_slip": "the tyre's combined-slip weighting acts; model.tir's weighting is 1",
    "sidewall_contact": "deflection-gated extra lateral force drop beyond the peak at low "
                        "pressure and high load (sidewall touches the belt)",
}  # fmt: skip


def _ms(a: dict, b: dict) -> float:
    return float(np.mean((a["Fx"] - b["Fx"]) ** 2 + (a["Fy"] - b["Fy"]) ** 2))


def effect_sizes(s: ph.Session, effects: list) -> tuple[dict, dict]:
    on = frozenset(effects)
    full = ph.simulate(s, on)
    ms = {e: _ms(full, ph.simulate(s, on - {e})) for e in effects}
    return full, ms


def scale_effect(plan: cs.Plan, name: str, g: float) -> bool:
    """Multiply an effect's amplitude by g within its realistic range; False if it can't move."""
    E = plan.session.effects
    if name not in E:
        return False
    e = E[name]
    th = plan.session.thermal
    before = _knobs(e, th)
    if name == "temperature":
        max_depth = 0.012 * min(e["W_lo"], e["W_hi"]) / 0.607  # slope <= 1.2 %/K
        e["depth"] = float(np.clip(e["depth"] * g, 0.05, min(0.5, max_depth)))
        e["k_stiff_per_K"] = float(np.clip(e["k_stiff_per_K"] * g, 0.0005, 0.008))
    elif name == "pressure":
        if e.get("mode") == "leak":
            T = plan.minutes * 60.0
            f = float(np.clip(e["fraction"] * g, 0.03, 0.25))
            p0 = plan.session.p0
            e["fraction"] = f
            e["k_sqrtPa_per_s"] = float((np.sqrt(p0) - np.sqrt(p0 * (1 - f)))
                                        / max(T - e["t_leak_s"], 1.0))  # fmt: skip
        elif e.get("mode") == "sealed":
            th["r_g"] = float(np.clip(th["r_g"] * g**0.5, 0.5, 0.95))
            th["tau_g"] = float(np.clip(th["tau_g"] / g, 45.0, 300.0))
        else:
            return False
    elif name == "offset":
        e["ply_steer_rad"] = float(np.clip(e["ply_steer_rad"] * g, -0.25 * DEG, 0.25 * DEG))
        e["conicity_per_Fz"] = float(np.clip(e["conicity_per_Fz"] * g, -0.03, 0.03))
        e["zero_Fx_N"] = float(np.clip(e["zero_Fx_N"] * g, -0.02 * plan.tyre.Fz0,
                                       0.02 * plan.tyre.Fz0))  # fmt: skip
    elif name == "relaxation":
        R = plan.tyre.R0 / 0.3135
        e["sigma_alpha_m"] = float(np.clip(e["sigma_alpha_m"] * g, 0.2 * R, 0.8 * R))
        e["sigma_kappa_m"] = float(np.clip(e["sigma_kappa_m"] * g, 0.1 * R, 0.4 * R))
    elif name == "time_delay":
        e["transport_s"] = float(np.clip(e["transport_s"] * g, 0.005, 0.050))
    elif name == "drift":
        e["loss"] = float(np.clip(e["loss"] * g, 0.01, 0.08))
        e["k_wear_per_J"] = e["loss"] / max(e["E_total_J"], 1.0)
    elif name == "speed":
        e["r0"] = float(np.clip(1 - (1 - e["r0"]) * g, 0.35, 0.95))
    elif name == "sidewall_contact":
        e["depth"] = float(np.clip(e["depth"] * g, 0.05, 0.4))
    else:
        return False
    after = _knobs(e, th)
    return any(abs(a - b) > 0.02 * max(abs(b), 1e-12) for a, b in zip(after, before, strict=True))


def _knobs(e: dict, th: dict) -> list:
    """The numbers scale_effect moves (a change below 2 % counts as none)."""
    vals = [float(v) for k, v in sorted(e.items()) if isinstance(v, int | float)]
    return vals + [float(th["r_g"]), float(th["tau_g"])]


def size_plan(plan: cs.Plan, log) -> tuple[dict, dict]:
    """Simulate and size the effects: each visible (aim >= 2.5x the force-noise variance, at
    least ~1x), and in the multi cases the strongest >= 2x the second (aim 2.5x). Effects move
    only within their realistic ranges (``scale_effect``); the noise only within the sensor's
    spec (down to 10 N for a car tyre). Returns (true channels, ms per effect)."""
    s = plan.session
    eff = plan.effects
    nz = plan.noise
    var = lambda: nz["Fx_N"] ** 2 + nz["Fy_N"] ** 2  # noqa: E731
    k_size = float(np.sqrt(np.clip(plan.tyre.size, 0.5, 1.5)))
    if not eff:
        return ph.simulate(s, frozenset()), {}
    full, ms = effect_sizes(s, eff)
    stuck: set[str] = set()  # effects that do not respond to their knob any more

    def try_scale(name, g):
        if name in stuck:
            return None
        return (name, g, ms[name]) if scale_effect(plan, name, g) else None

    for _ in range(6):
        move = None
        order = sorted(ms, key=ms.get, reverse=True)
        if len(order) >= 2 and ms[order[0]] < 2.5 * ms[order[1]]:
            m1, m2 = ms[order[0]], ms[order[1]]
            g2 = float(np.sqrt(m1 / (2.5 * m2)))
            if m2 * g2 * g2 >= 2.5 * var():
                move = try_scale(order[1], g2)
            move = move or try_scale(order[0], float(np.sqrt(2.6 * m2 / m1)))
            move = move or try_scale(order[1], g2)
        if move is None:
            weakest = order[-1]
            target = 2.6 * var()
            if len(order) >= 2 and weakest == order[1]:
                target = min(target, ms[order[0]] / 2.5)
            if ms[weakest] < 2.5 * var() and target > 1.05 * ms[weakest]:
                g = float(np.sqrt(target / max(ms[weakest], 1e-9)))
                move = try_scale(weakest, min(g, 2.0))
            elif ms[weakest] < 2.5 * var() and len(order) >= 2 and weakest == order[1]:
                # the ratio holds the second back: grow the strongest first
                g = float(np.sqrt(2.6 * 2.5 * var() / ms[order[0]]))
                move = try_scale(order[0], min(max(g, 1.0), 2.0))
        if move is None:
            break
        full, ms = effect_sizes(s, eff)
        name, g, before = move
        want = g * g - 1.0
        if abs(ms[name] / max(before, 1e-9) - 1.0) < 0.3 * abs(want):
            stuck.add(name)
        log("  resized: " + ", ".join(f"{e} {ms[e]:.0f}" for e in eff))
    # last resort for visibility: a quieter load cell, within the sensor's spec
    weakest = min(ms, key=ms.get)
    if ms[weakest] < 2.5 * var():
        f = float(np.sqrt(ms[weakest] / (2.5 * var())))
        sx = max(nz["Fx_N"] * f, 10.0 * k_size)
        sy = max(nz["Fy_N"] * f, 10.0 * k_size)
        nz["Fx_N"], nz["Fy_N"], nz["Fz_N"] = (
            min(sx, nz["Fx_N"]),
            min(sy, nz["Fy_N"]),
            1.5 * min(sx, nz["Fx_N"]),
        )
    return full, ms


def _clean(obj):
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float):
        return float(f"{obj:.6g}")
    return obj


def generate(case: str, seed: int, outdir, minutes: float = 8.0, quiet: bool = False) -> dict:
    t_start = time.time()
    log = (lambda *a: None) if quiet else print
    out = Path(outdir)
    if out.exists():
        raise FileExistsError(f"{out} exists; give a new output directory")
    plan = cs.build(case, seed, minutes)
    s = plan.session
    full, ms = size_plan(plan, log)

    rng = np.random.default_rng([int(seed), plan.notes["rng_state"], 7])
    n = s.t.size
    imperf = daq.draw_imperfections(rng, plan.imperfections, n, s.dt, plan.noise)
    if not plan.imperfections and rng.random() < 0.25:  # mild: a few short dropouts
        imperf = daq.draw_imperfections(rng, ["dropouts"], n, s.dt, plan.noise, mild=True)
    t0 = 1.70e9 + float(rng.integers(0, 50_000_000))
    t_abs = np.round((t0 + s.t) * 1e6) / 1e6
    true = {"kappa": s.kappa, "alpha": s.alpha, "gamma": s.gamma, "V": s.V, **full}
    rec, twin = daq.make_channels(rng, t_abs, true, plan.noise, imperf, plan.record_pressure,
                                  plan.record_temperature, s.dt)  # fmt: skip

    out.mkdir(parents=True)
    write_bag(out / "recording", {PREFIX: rec})
    write_bag(out / "twin", {PREFIX: twin})
    plan.tyre.write_model_tir(out / "model.tir", plan.model_tir)

    var = plan.noise["Fx_N"] ** 2 + plan.noise["Fy_N"] ** 2
    eff_list = []
    for e in sorted(plan.effects, key=lambda x: ms[x], reverse=True):
        params = dict(s.effects.get(e, {}))
        if e == "temperature":
            params["side_of_optimum"] = plan.side
            params["start"] = s.thermal["start"]
            params["Ts_range_degC"] = [round(float(full["Ts"].min()), 1),
                                       round(float(full["Ts"].max()), 1)]  # fmt: skip
            params["Tb_range_degC"] = [round(float(full["Tb"].min()), 1),
                                       round(float(full["Tb"].max()), 1)]  # fmt: skip
            params["s_mu_range"] = [round(float(full["s_mu"].min()), 4),
                                    round(float(full["s_mu"].max()), 4)]  # fmt: skip
        if e == "pressure":
            params["p_range_kPa"] = [round(float(full["p"].min()) / 1e3, 2),
                                     round(float(full["p"].max()) / 1e3, 2)]  # fmt: skip
            params["p_nominal_kPa"] = s.p0 / 1e3
            if params.get("mode") == "sealed":
                params["Tg_range_degC"] = [round(float(full["Tg"].min()), 1),
                                           round(float(full["Tg"].max()), 1)]  # fmt: skip
        if e == "time_delay":
            gd = ph.butter_group_delay(params["filter_hz"], params["order"], 1.0 / s.dt)
            params["filter_group_delay_s"] = gd
            params["total_delay_s"] = params["transport_s"] + gd
        if e == "drift":
            params["final_grip_factor"] = round(1.0 - params["loss"], 4)
        eff_list.append({"name": e, "concealed": bool(plan.concealed.get(e, False)),
                         "ms_N2": round(ms[e], 3), "ms_over_noise_var": round(ms[e] / var, 3),
                         "detail": DESCRIPTIONS[e], "parameters": params})  # fmt: skip
    tyre = plan.tyre
    truth = {
        "generator": NAME, "case": case, "seed": int(seed), "minutes": float(minutes),
        "wheels": [PREFIX], "null": not plan.effects, "effects": eff_list,
        "imperfections": [{k: v for k, v in imp.items() if k != "list"} | (
            {"spikes": imp["list"]} if "list" in imp else {}) for imp in imperf],
        "tyre": tyre.name + (f" + own pressure terms (scale {tyre.pressure_scale:.3f})"
                             if tyre.own_pressure else ""),
        "noise": {**plan.noise, "var_FxFy_N2": var,
                  "note": "1-sigma, after the DAQ's linear-phase anti-alias FIR"},
        "topics": sorted(rec.keys()),
        "pressure_mode": s.pressure_mode,
        "thermal": s.thermal,
        "programme": plan.prog.describe(),
        "programme_conditions": plan.prog.conditions,
        "description": _description(plan, ms),
        "stamps": {"t0": float(t_abs[0]), "rate_hz": 100.0, "slip_samples": int(rec["slip"][0].size)},
    }  # fmt: skip
    (out / "truth.json").write_text(json.dumps(_clean(truth), indent=1) + "\n")
    log(f"{NAME} {case} seed {seed}: tyre {tyre.name}, {minutes:g} min, topics {truth['topics']}")
    for e in eff_list:
        log(
            f"  {e['name']:<17} concealed={e['concealed']!s:<5} ms={e['ms_N2']:10.1f} N^2 "
            f"({e['ms_over_noise_var']:.1f}x noise var {var:.0f})"
        )
    if not eff_list:
        log(f"  null; imperfections: {[i['kind'] for i in imperf]}; noise var {var:.0f} N^2")
    log(
        f"  Fx {full['Fx'].min():.0f}..{full['Fx'].max():.0f} N, Fy {full['Fy'].min():.0f}.."
        f"{full['Fy'].max():.0f} N, Ts {full['Ts'].min():.0f}..{full['Ts'].max():.0f} C, "
        f"p {full['p'].min() / 1e3:.0f}..{full['p'].max() / 1e3:.0f} kPa; "
        f"{time.time() - t_start:.1f} s"
    )
    return truth


def _description(plan: cs.Plan, ms: dict) -> str:
    s = plan.session
    th = s.thermal
    parts = [f"A {plan.tyre.name.replace('.tir', '')} tyre runs a {plan.minutes:g}-minute "
             f"Flat-Trac programme (belt at ambient {th['T_amb']:.1f} C, tyre {th['start']} at "
             f"the start)."]  # fmt: skip
    E = s.effects
    for e in sorted(plan.effects, key=lambda x: ms[x], reverse=True):
        if e == "temperature":
            t = E[e]
            parts.append(f"Its tread heats from frictional power and cools on the belt and in "
                         f"pauses; grip follows a window with optimum {t['T_opt']:.0f} C and the "
                         f"tyre runs {plan.side} it; stiffness falls "
                         f"{100 * t['k_stiff_per_K']:.2f} %/K with carcass temperature.")  # fmt: skip
        elif e == "pressure":
            m = E[e].get("mode")
            if m == "sealed":
                parts.append("The tyre is sealed: its gas warms and the pressure rises by the "
                             "gas law (no pressure topic).")  # fmt: skip
            elif m == "leak":
                parts.append(f"A slow leak lowers the pressure by {100 * E[e]['fraction']:.0f} % "
                             f"from t = {E[e]['t_leak_s']:.0f} s on (no pressure topic).")  # fmt: skip
            else:
                parts.append("The pressure changes between set points and is recorded, but "
                             "model.tir has no pressure terms.")  # fmt: skip
        elif e == "drift":
            parts.append(f"The tread wears: grip falls by {100 * E[e]['loss']:.1f} % over the "
                         f"session with the cumulative frictional energy.")  # fmt: skip
        elif e == "relaxation":
            parts.append(f"The forces lag the slip with relaxation lengths "
                         f"{E[e]['sigma_alpha_m']:.2f} m (lateral) / {E[e]['sigma_kappa_m']:.2f}"
                         f" m (longitudinal) at the nominal load.")  # fmt: skip
        elif e == "time_delay":
            parts.append(f"The force channels arrive {1000 * E[e]['transport_s']:.0f} ms late "
                         f"and through a {E[e]['filter_hz']:.0f} Hz causal filter.")  # fmt: skip
        elif e == "offset":
            parts.append(f"Ply-steer {E[e]['ply_steer_rad'] / DEG:+.3f} deg, conicity "
                         f"{100 * E[e]['conicity_per_Fz']:+.2f} % Fz and an Fx zero of "
                         f"{E[e]['zero_Fx_N']:+.1f} N offset the forces.")  # fmt: skip
        elif e == "speed":
            parts.append(f"Friction depends on sliding speed (peak at {E[e]['vm_mps']:.2f} m/s, "
                         f"floor {E[e]['r0']:.2f}).")  # fmt: skip
        elif e == "camber":
            parts.append("The inclination changes the forces but model.tir has no camber terms.")
        elif e == "combined_slip":
            parts.append("Drive/brake sweeps at slip angles make combined slip, which model.tir "
                         "does not weight.")  # fmt: skip
        elif e == "sidewall_contact":
            parts.append("At low pressure and high load the sidewall touches the belt beyond "
                         "the peak and the lateral force drops further.")  # fmt: skip
    if not plan.effects:
        parts.append("Nothing is missing from model.tir; the recording carries only sensor "
                     "noise and the listed imperfections.")  # fmt: skip
    return " ".join(parts)
