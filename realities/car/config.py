"""Random draws of the car, its tyres' effect parameters and the driving programme (per seed)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from tire_model_ros.model import TireModel, read_tir

from . import sim as S

# the shared checkout beside the project root (as test/conftest.py finds it)
TIR_DIR = Path(__file__).resolve().parents[3] / "shared" / "reference" / "tir"
TYRES = {"MF61": "MagicFormula61_Parameters.tir", "PacejkaBook": "PacejkaBook_Defaults.tir"}
G = 9.81
P_ATM = 101325.0

# coefficients of the inclination (camber) dependence that model.tir loses in the camber case
# (PEY3 is kept: it acts at zero camber too, an asymmetry of the curvature)
CAMBER_COEFFICIENTS = (
    "PDX3", "RBX3", "PDY3", "PEY4", "PEY5", "PKY3", "PKY5", "PKY6", "PKY7", "PHY3", "PVY3",
    "PVY4", "PPY5", "RBY4", "RVY3", "QSX2", "QSX7", "QSX10", "QSX12", "QSX14", "QSY5", "QSY6",
    "QBZ4", "QBZ5", "QDZ3", "QDZ4", "QDZ8", "QDZ9", "QDZ10", "QDZ11", "QEZ5", "QHZ3", "QHZ4",
    "SSZ3", "SSZ4", "Q_CAM", "Q_CAM1", "Q_CAM2", "Q_CAM3", "Q_FYS1", "Q_FYS2", "Q_FYS3",
)  # fmt: skip
# combined slip: the weighting slopes (Gxa = Gyk = 1) and the kappa-induced side force
COMBINED_COEFFICIENTS = ("RBX1", "RBX3", "RBY1", "RBY4", "RVY1", "RVY2", "RVY3")


def load_tyre(rng, name: str, case_pressure: bool):
    """The tyre's TirData (the truth's base). PacejkaBook gets pressure coefficients drawn here
    (the reference file has none; a 'characterised' variant of it)."""
    tir = read_tir(TIR_DIR / TYRES[name])
    upd = {}
    if name == "PacejkaBook":
        upd.update(
            {
                "PPX1": rng.uniform(-0.6, -0.25),
                "PPX2": rng.uniform(0.1, 0.5),
                "PPX3": rng.uniform(-0.05, 0.05),
                "PPX4": rng.uniform(-0.5, -0.1),
                "PPY1": rng.uniform(0.15, 0.4),
                "PPY2": rng.uniform(1.3, 1.8),
                "PPY3": rng.uniform(0.0, 0.12),
                "PPY4": rng.uniform(-0.15, 0.0),
                "PPZ1": rng.uniform(0.3, 0.9),
                "QSY8": -0.4,
            }
        )
    else:
        rng.uniform(size=9)  # keep the stream aligned between tyres
    if upd:
        tir = tir.with_params(upd)
    return tir


def model_of(tir):
    return TireModel(tir)


def tyre_numbers(model: TireModel, Fz_f: float, Fz_r: float):
    """Cornering stiffness, usable friction and peak slips at the static loads."""
    p = model.params
    a = np.radians(np.linspace(0.0, 14.0, 141))
    out = {}
    for key, Fz in (("f", Fz_f), ("r", Fz_r)):
        o = model.evaluate(Fz, 0.0, a, 0.0, 25.0)
        Fy = -o.Fy
        i_pk = int(np.argmax(Fy))
        cap = np.searchsorted(a, math.radians(8.0))
        out["Kya_" + key] = abs(float(o.Kya[0]))
        out["apk_" + key] = float(a[i_pk])
        out["mu_lat_" + key] = float(Fy[: cap + 1].max() / Fz)
        k = np.linspace(-0.3, 0.3, 301)
        o = model.evaluate(Fz, k, 0.0, 0.0, 25.0)
        out["kpk_brk_" + key] = float(-k[int(np.argmin(o.Fx))])
        out["kpk_drv_" + key] = float(k[int(np.argmax(o.Fx))])
        out["mux_" + key] = float(min(-o.Fx.min(), o.Fx.max()) / Fz)
        out["Kxk_" + key] = float(o.Kxk[150])
    o = model.evaluate(0.5 * (Fz_f + Fz_r), 0.0, 0.0, 0.0, 25.0, full=True)
    out["Re"] = float(o.Re)
    out["R0"] = float(p["UNLOADED_RADIUS"])
    return out


def draw_vehicle(rng, model: TireModel):
    """Vehicle parameters VP, per-wheel WP (geometry, camber, drive/brake shares) and a dict."""
    m = rng.uniform(1200, 1800)
    L = rng.uniform(2.45, 2.85)
    wf = rng.uniform(0.50, 0.60)
    a = L * (1 - wf)
    b = L * wf
    Iz = m * a * b * rng.uniform(0.9, 1.05)
    tf = rng.uniform(1.45, 1.65)
    tr = tf + rng.uniform(-0.04, 0.04)
    h = rng.uniform(0.45, 0.58)
    chif = rng.uniform(0.50, 0.65)
    drive = ["RWD", "FWD", "AWD"][int(rng.integers(3))]
    P_kw = rng.uniform(110, 260)
    brake_f = rng.uniform(0.60, 0.72)
    cda = rng.uniform(0.60, 0.80)
    cla = rng.uniform(0.0, 0.3)
    cam_f = -rng.uniform(1.0, 2.5)
    cam_r = -rng.uniform(0.8, 2.0)
    cg_f = rng.uniform(0.55, 0.80)
    cg_r = rng.uniform(0.50, 0.75)
    roll_grad = rng.uniform(3.0, 5.5)  # deg per g
    toe_f = rng.uniform(-0.10, 0.05)  # deg, toe-in positive
    toe_r = rng.uniform(0.0, 0.20)
    Iw_f = rng.uniform(0.9, 1.3)
    Iw_r = rng.uniform(0.9, 1.3)
    tau_roll = rng.uniform(0.08, 0.20)
    tau_pitch = rng.uniform(0.06, 0.15)
    Fz_f = m * G * b / L / 2
    Fz_r = m * G * a / L / 2
    tn = tyre_numbers(model, Fz_f, Fz_r)
    Cf = 2 * tn["Kya_f"]
    Cr = 2 * tn["Kya_r"]
    kus = m * b / (L * Cf) - m * a / (L * Cr)
    VP = np.zeros(S.N_VP)
    VP[S.V_M] = m
    VP[S.V_IZ] = Iz
    VP[S.V_A] = a
    VP[S.V_B] = b
    VP[S.V_TF] = tf
    VP[S.V_TR] = tr
    VP[S.V_H] = h
    VP[S.V_CHIF] = chif
    VP[S.V_TAU_ROLL] = tau_roll
    VP[S.V_TAU_PITCH] = tau_pitch
    VP[S.V_KPHI] = math.radians(roll_grad) / G
    VP[S.V_CDA] = cda
    VP[S.V_CLA] = cla
    VP[S.V_AERO_F] = rng.uniform(0.40, 0.50)
    VP[S.V_PMAX] = P_kw * 1000 * 0.9
    VP[S.V_FTRACT] = 0.9 * m * G
    VP[S.V_RE] = tn["Re"]
    VP[S.V_RHO] = 1.2
    VP[S.V_G] = G
    VP[S.V_CRR] = 0.012
    VP[S.V_KUS] = kus
    VP[S.V_LA0] = 6.0
    VP[S.V_LA1] = 0.45
    VP[S.V_KV] = 1.2
    VP[S.V_KI_YAW] = 0.5
    VP[S.V_TAU_STEER] = 0.06
    VP[S.V_STEER_RATE] = 0.7
    kpk_b = min(tn["kpk_brk_f"], tn["kpk_brk_r"])
    kpk_d = min(tn["kpk_drv_f"], tn["kpk_drv_r"])
    VP[S.V_KAP_ABS] = 0.8 * kpk_b
    VP[S.V_KAP_TC] = 0.8 * kpk_d
    VP[S.V_T_PREVIEW] = 0.25
    VP[S.V_V_INIT] = 16.0
    VP[S.V_DELTA_MAX] = 0.45
    VP[S.V_TAU_ABS] = 0.02
    VP[S.V_KP_YAW] = 0.08
    WP = np.zeros((4, S.N_WP))
    side = np.array([1.0, -1.0, 1.0, -1.0])
    WP[:, S.W_X] = [a, a, -b, -b]
    WP[:, S.W_Y] = [tf / 2, -tf / 2, tr / 2, -tr / 2]
    WP[:, S.W_STEERED] = [1, 1, 0, 0]
    share = {"RWD": [0, 0, 0.5, 0.5], "FWD": [0.5, 0.5, 0, 0], "AWD": [0.2, 0.2, 0.3, 0.3]}
    WP[:, S.W_DRIVE] = share[drive]
    WP[:, S.W_BRAKE] = [brake_f / 2, brake_f / 2, (1 - brake_f) / 2, (1 - brake_f) / 2]
    drv_inertia = 0.35
    WP[:, S.W_IW] = [Iw_f, Iw_f, Iw_r, Iw_r] + np.array(share[drive]) * 2 * drv_inertia
    # ISO-W inclination: negative camber (top inwards) is +gamma on the left, -gamma on the right
    WP[:, S.W_CAM0] = -np.radians([cam_f, cam_f, cam_r, cam_r]) * side
    WP[:, S.W_CGAIN] = [cg_f, cg_f, cg_r, cg_r]
    # toe-in: the left wheel steered right (negative), the right wheel left
    WP[:, S.W_TOE] = -np.radians([toe_f, toe_f, toe_r, toe_r]) * side
    # driver's grip estimate
    wd = {"RWD": a / L + 0.08, "FWD": b / L - 0.08, "AWD": 0.95}[drive]
    car = {
        "m": m,
        "g": G,
        "P": VP[S.V_PMAX],
        "cda": cda,
        "rho": 1.2,
        "crr": 0.012,
        "mu_lat": 0.94 * min(tn["mu_lat_f"], tn["mu_lat_r"]),
        "mu_brk": 0.85 * min(tn["mux_f"], tn["mux_r"]),
        "mu_drv": 0.85 * wd * min(tn["mux_f"], tn["mux_r"]),
    }
    info = {
        "mass_kg": m,
        "yaw_inertia_kgm2": Iz,
        "wheelbase_m": L,
        "cg_to_front_axle_m": a,
        "track_front_m": tf,
        "track_rear_m": tr,
        "cg_height_m": h,
        "roll_stiffness_front_share": chif,
        "roll_lag_s": tau_roll,
        "pitch_lag_s": tau_pitch,
        "roll_gradient_deg_per_g": roll_grad,
        "drive": drive,
        "power_kW": P_kw,
        "brake_balance_front": brake_f,
        "CdA_m2": cda,
        "ClA_m2": cla,
        "static_camber_deg": {"front": cam_f, "rear": cam_r},
        "camber_gain_per_roll": {"front": cg_f, "rear": cg_r},
        "toe_in_deg": {"front": toe_f, "rear": toe_r},
        "effective_radius_m": tn["Re"],
        "static_load_N": {"front": Fz_f, "rear": Fz_r},
        "understeer_gradient_rad_per_mps2": kus,
    }
    VP[S.V_ALIM] = min(max(tn["apk_f"], math.radians(5.0)), math.radians(9.0)) * 1.05
    VP[S.V_MU_LAT] = car["mu_lat"]
    VP[S.V_MU_BRK] = car["mu_brk"]
    return VP, WP, car, info, tn


def default_tp(rng, model: TireModel, T_amb: float):
    """Tyre effect parameters TP with every effect at a neutral/default value (drawn sizes)."""
    p = model.params
    TP = np.zeros(S.N_TP)
    sz = (p["WIDTH"] * p["UNLOADED_RADIUS"]) / (0.205 * 0.3135)  # heat capacities
    sa = sz**0.7  # conductances (surface areas grow slower than the rubber mass)
    j = lambda lo, hi: rng.uniform(lo, hi)  # noqa: E731
    TP[S.T_CS] = 900.0 * sz * j(0.8, 1.2)
    TP[S.T_CC] = 6500.0 * sz * j(0.8, 1.2)
    TP[S.T_CG] = 2500.0 * sz * j(0.8, 1.2)
    TP[S.T_GSC] = 160.0 * sa * j(0.8, 1.2)
    TP[S.T_GSA0] = 6.0 * sa
    TP[S.T_GSA1] = 1.4 * sa * j(0.8, 1.2)
    TP[S.T_GSR] = 12.0 * sa * j(0.8, 1.2)
    TP[S.T_GCA0] = 3.0 * sa
    TP[S.T_GCA1] = 0.5 * sa * j(0.8, 1.2)
    TP[S.T_GCG] = 14.0 * sa * j(0.8, 1.2)
    TP[S.T_GGA0] = 3.0 * sa
    TP[S.T_GGA1] = 0.7 * sa * j(0.8, 1.2)
    TP[S.T_FT] = j(0.65, 0.85)
    TP[S.T_ETAS] = j(0.7, 0.85)
    TP[S.T_FH] = j(0.009, 0.014)
    TP[S.T_EPSB] = j(0.01, 0.03)
    TP[S.T_TAMB] = T_amb
    TP[S.T_TROAD] = T_amb + j(3.0, 15.0)
    TP[S.T_TINIT_S] = T_amb
    TP[S.T_TINIT_C] = T_amb
    TP[S.T_TINIT_G] = T_amb
    TP[S.T_TOPT] = 80.0
    TP[S.T_DC] = j(0.22, 0.32)
    TP[S.T_WC] = j(30.0, 45.0)
    TP[S.T_DH] = j(0.25, 0.35)
    TP[S.T_WH] = j(20.0, 30.0)
    TP[S.T_WS] = j(0.5, 0.7)
    TP[S.T_TREFG] = 80.0
    TP[S.T_KK] = j(0.0015, 0.003)
    TP[S.T_TREFC] = 60.0
    TP[S.T_PMODE] = 0.0
    TP[S.T_PATM] = P_ATM
    TP[S.T_TSET] = T_amb
    TP[S.T_TAU_LEAK] = 1e9
    TP[S.T_SIGA] = j(0.5, 0.7)
    TP[S.T_SIGK] = j(0.2, 0.3)
    TP[S.T_FSIG] = p["FNOMIN"] * j(0.4, 0.6)
    TP[S.T_ASRED] = j(0.4, 0.7)
    TP[S.T_APK] = math.radians(7.0)
    TP[S.T_KPK] = 0.12
    TP[S.T_CW] = 0.0
    TP[S.T_CV] = j(0.01, 0.03)
    TP[S.T_VSREF] = j(1.5, 2.5)
    TP[S.T_CZ0] = p["VERTICAL_STIFFNESS"]
    TP[S.T_PFZ1] = p["PFZ1"]
    TP[S.T_PNOM] = p["NOMPRES"]
    TP[S.T_RHOC] = 1.0
    TP[S.T_RHOW] = 0.005
    TP[S.T_AON] = math.radians(6.0)
    TP[S.T_AW] = math.radians(j(1.5, 3.0))
    TP[S.T_DSW] = j(0.15, 0.3)
    return TP


def lap_plan(rng, track_len: float, minutes: float, car: dict, style: str = "mixed"):
    """Laps as dict(pace, vtop, kind): out-lap, pushed and moderate laps, a cool-down lap near
    mid-session; enough laps for the session (lap time estimated from the pace)."""
    T = minutes * 60.0
    laps = [{"pace": rng.uniform(0.62, 0.75), "vtop": 45.0, "kind": "out-lap"}]
    v_mean = lambda pace: 24.0 * math.sqrt(pace / 0.9)  # noqa: E731  (rough lap speed)
    t = track_len / v_mean(laps[0]["pace"])
    cool_at = rng.uniform(0.42, 0.58) * T
    cooled = False
    n_push = 0
    while t < T + 120.0:
        if not cooled and t >= cool_at:
            lp = {
                "pace": rng.uniform(0.40, 0.50),
                "vtop": rng.uniform(22.0, 27.0),
                "kind": "cool-down",
            }
            cooled = True
        else:
            push = rng.uniform() < (0.75 if style == "push" else 0.6)
            if n_push >= 2 and rng.uniform() < 0.5:
                push = False
            if push:
                lp = {"pace": rng.uniform(0.90, 0.96), "vtop": 70.0, "kind": "pushed"}
                n_push += 1
            else:
                lp = {"pace": rng.uniform(0.72, 0.84), "vtop": 70.0, "kind": "moderate"}
                n_push = 0
        laps.append(lp)
        t += track_len / v_mean(lp["pace"]) + (25.0 if lp["kind"] == "cool-down" else 0.0)
    return laps
