"""The closed-loop car: a planar vehicle, four wheels, a driver, and the tyres with their effects.

Everything that runs per time step is one numba function, :func:`simulate`. The steady-state
force law of each tyre is the project's Magic Formula kernel (``tire_model_ros.model``), called
for the four wheels at once; every effect around it (heat, pressure, relaxation, wear, speed,
sidewall contact, offsets) is written here.

Several *instances* of the tyre run side by side on the same inputs: instance 0 drives the car
(all effects on); every other instance is a shadow with one effect switched off (or the other
coefficient vector, for camber/combined), fed the very same slip, load, camber and speed, so
that an effect's size is measured on the same inputs (no driver compensation mixed in).
Shadows are evaluated at the output samples only; their slow states (temperatures, wear,
pressure) are integrated with the same scheme as the main instance's, so that with all
effects on a shadow would reproduce instance 0 exactly.
"""

from __future__ import annotations

import hashlib
import math
import os
from pathlib import Path

import numpy as np
from numba import njit

from tire_model_ros.model import coef as _c
from tire_model_ros.model import kernel as _kernel
from tire_model_ros.model.kernel import forces_loop


def _guard_cache() -> None:
    """numba keys a cached function on its own file only, but :func:`simulate` links the MF
    kernel into its compiled code: drop this module's cache when any model source (or this
    file) changed since the cache was built, so a changed kernel is never used stale."""
    here = Path(__file__).resolve()
    h = hashlib.sha256(here.read_bytes())
    for f in sorted(Path(_kernel.__file__).resolve().parent.glob("*.py")):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    digest = h.hexdigest()
    caches = [here.parent / "__pycache__"]
    try:  # a NUMBA_CACHE_DIR, when set, is where numba keeps this module's cache instead
        from numba import config
        from numba.core.caching import _CacheLocator

        if config.CACHE_DIR:
            sub = _CacheLocator.get_suitable_cache_subpath(str(here))
            caches.insert(0, Path(config.CACHE_DIR) / sub)
    except (ImportError, AttributeError, TypeError):
        pass
    for cache in caches:
        stamp = cache / "car_sim.sha256"
        try:
            if stamp.read_text() == digest:
                continue
        except OSError:
            pass
        try:
            cache.mkdir(parents=True, exist_ok=True)
            for f in cache.glob("sim.*"):
                if f.suffix in (".nbi", ".nbc"):
                    f.unlink(missing_ok=True)
            tmp = stamp.with_name(f"{stamp.name}.{os.getpid()}.tmp")
            tmp.write_text(digest)
            os.replace(tmp, stamp)
        except OSError:
            pass


_guard_cache()

NOMTEMP_IDX = _c.NOMTEMP
# rows of the kernel's output block
R_FX, R_FY, R_MX, R_MY, R_MZ, R_KXK = (
    _kernel.FX,
    _kernel.FY,
    _kernel.MX,
    _kernel.MY,
    _kernel.MZ,
    _kernel.KXK,
)
N_ROWS = _kernel.N_FORCES

# ---- effect flags (bit mask per instance) ----
TEMP = 1  # grip window on tread temperature, stiffness on carcass temperature
PRESS = 2  # inflation pressure varies (gas law / leak); off: fixed pressure P_OFF
RELAX = 4  # relaxation lengths
OFFSET = 8  # ply-steer / conicity (the transducer zero is added in the measurement chain)
WEAR = 16  # grip loss with frictional energy
SPEED = 32  # friction against sliding speed
SIDEWALL = 64  # sidewall contact at large deflection and slip

# ---- vehicle parameters VP ----
(
    V_M,
    V_IZ,
    V_A,
    V_B,
    V_TF,
    V_TR,
    V_H,
    V_CHIF,
    V_TAU_ROLL,
    V_TAU_PITCH,
    V_KPHI,
    V_CDA,
    V_CLA,
    V_AERO_F,
    V_PMAX,
    V_FTRACT,
    V_RE,
    V_RHO,
    V_G,
    V_CRR,
    V_KUS,
    V_LA0,
    V_LA1,
    V_KV,
    V_KI_YAW,
    V_TAU_STEER,
    V_STEER_RATE,
    V_KAP_ABS,
    V_KAP_TC,
    V_T_PREVIEW,
    V_V_INIT,
    V_DELTA_MAX,
    V_TAU_ABS,
    V_KP_YAW,
    V_MU_LAT,
    V_MU_BRK,
    V_ALIM,
    N_VP,
) = range(38)

# ---- per-wheel parameters WP[i, :] ----
(
    W_X,
    W_Y,
    W_STEERED,
    W_DRIVE,
    W_BRAKE,
    W_IW,
    W_CAM0,
    W_CGAIN,
    W_TOE,
    W_P_SET,
    W_P_OFF,
    W_LEAK,
    W_SW,
    W_C_OFF,
    W_MZ_OFF,
    N_WP,
) = range(16)

# ---- tyre effect parameters TP ----
(
    T_CS,
    T_CC,
    T_CG,
    T_GSC,
    T_GSA0,
    T_GSA1,
    T_GSR,
    T_GCA0,
    T_GCA1,
    T_GCG,
    T_GGA0,
    T_GGA1,
    T_FT,
    T_ETAS,
    T_FH,
    T_EPSB,
    T_TAMB,
    T_TROAD,
    T_TINIT_S,
    T_TINIT_C,
    T_TINIT_G,
    T_TOPT,
    T_DC,
    T_WC,
    T_DH,
    T_WH,
    T_WS,
    T_TREFG,
    T_KK,
    T_TREFC,
    T_PMODE,
    T_PATM,
    T_TSET,
    T_TAU_LEAK,
    T_SIGA,
    T_SIGK,
    T_FSIG,
    T_ASRED,
    T_APK,
    T_KPK,
    T_CW,
    T_CV,
    T_VSREF,
    T_CZ0,
    T_PFZ1,
    T_PNOM,
    T_RHOC,
    T_RHOW,
    T_AON,
    T_AW,
    T_DSW,
    N_TP,
) = range(52)

# ---- states per instance and wheel ----
S_KR, S_AR, S_TS, S_TC, S_TG, S_EF, S_P, N_S = range(8)

# ---- vehicle log columns ----
(L_X, L_Y, L_PSI, L_VX, L_VY, L_R, L_DELTA, L_S, L_VREF, L_AX, L_AY, L_KV, L_EY, N_L) = range(14)


@njit(cache=True)
def window(T, TP):
    """Skewed grip window g(T): 1 at T_opt, Gaussian-like fall, its own width on each side."""
    x = T - TP[T_TOPT]
    if x < 0.0:
        return 1.0 - TP[T_DC] * (1.0 - math.exp(-((x / TP[T_WC]) ** 2)))
    return 1.0 - TP[T_DH] * (1.0 - math.exp(-((x / TP[T_WH]) ** 2)))


@njit(cache=True)
def temp_factors(Ts, Tc, TP):
    """(lambda_mu, lambda_K) of the thermal state, 1 at the characterisation temperatures."""
    Tg = TP[T_WS] * Ts + (1.0 - TP[T_WS]) * Tc
    lm = window(Tg, TP) / window(TP[T_TREFG], TP)
    lk = math.exp(-TP[T_KK] * (Tc - TP[T_TREFC]))
    if lk < 0.7:
        lk = 0.7
    elif lk > 1.3:
        lk = 1.3
    return lm, lk


@njit(cache=True)
def smoothstep(x):
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return x * x * (3.0 - 2.0 * x)


@njit(cache=True)
def relax_update(st, kap, alp, Fz, Vx, TP, dt, flags, ck):
    """Advance the relaxation states (exact first order in travelled distance)."""
    for i in range(4):
        if flags & RELAX:
            V = abs(Vx[i])
            fl = math.tanh(Fz[i] / TP[T_FSIG])
            ua = abs(st[i, S_AR]) / TP[T_APK]
            uk = abs(st[i, S_KR]) / TP[T_KPK]
            sa = TP[T_SIGA] * fl * (1.0 - TP[T_ASRED] * min(1.0, ua))
            sk = TP[T_SIGK] * fl * (1.0 - TP[T_ASRED] * min(1.0, uk))
            sa = max(sa, 0.03)
            sk = max(sk, 0.02)
            ca = 1.0 - math.exp(-V * dt / sa)
            cb = 1.0 - math.exp(-V * dt / sk)
            st[i, S_AR] += ca * (alp[i] - st[i, S_AR])
            st[i, S_KR] += cb * (kap[i] - st[i, S_KR])
            ck[i] = cb
        else:
            st[i, S_AR] = alp[i]
            st[i, S_KR] = kap[i]
            ck[i] = 1.0


@njit(cache=True)
def tyre_forces(
    P, flags, st, gam, Fz, Vx, TP, WP, bFz, bk, ba, bg, bV, bp, bT, bph, out, res, lam, kloc
):
    """Forces of one instance on the four wheels: res[i] = Fx Fy Fz Mx My Mz.

    The slips used are the instance's relaxed slips st[:, S_KR/S_AR] (equal to the inputs
    without RELAX). Friction and stiffness scalings enter by similarity:
    F = lambda_mu * F_MF(slip * lambda_K / lambda_mu).
    """
    for i in range(4):
        ke = st[i, S_KR]
        ae = st[i, S_AR]
        lm = 1.0
        lk = 1.0
        if flags & TEMP:
            a, b = temp_factors(st[i, S_TS], st[i, S_TC], TP)
            lm *= a
            lk *= b
        if flags & WEAR:
            lm *= max(0.5, 1.0 - TP[T_CW] * st[i, S_EF])
        if flags & SPEED:
            vs = abs(Vx[i]) * math.sqrt(ke * ke + math.tan(ae) ** 2)
            lm *= (1.0 + TP[T_CV] * TP[T_VSREF]) / (1.0 + TP[T_CV] * vs)
        rr = lk / lm
        bk[i] = ke * rr
        ba[i] = math.atan(math.tan(ae) * rr)
        bFz[i] = Fz[i]
        bg[i] = gam[i]
        bV[i] = Vx[i]
        if flags & PRESS:
            bp[i] = st[i, S_P]
        else:
            bp[i] = WP[i, W_P_OFF]
        bT[i] = P[NOMTEMP_IDX]
        bph[i] = 0.0
        lam[i, 0] = lm
        lam[i, 1] = lk
    forces_loop(P, bFz, bk, ba, bg, bV, bp, bT, bph, True, out)
    for i in range(4):
        lm = lam[i, 0]
        Fx = lm * out[R_FX, i]
        Fy = lm * out[R_FY, i]
        Mz = lm * out[R_MZ, i]
        if (flags & SIDEWALL) and WP[i, W_SW] > 0.0:
            dpi = (bp[i] - TP[T_PNOM]) / TP[T_PNOM]
            cz = TP[T_CZ0] * max(0.2, 1.0 + TP[T_PFZ1] * dpi)
            rho = Fz[i] / cz
            g_rho = smoothstep((rho - TP[T_RHOC]) / TP[T_RHOW])
            if g_rho > 0.0:
                a_on = TP[T_AON] * math.sqrt(TP[T_RHOC] / max(rho, TP[T_RHOC]))
                ex = abs(st[i, S_AR]) - a_on
                if ex > 0.0:
                    f = 1.0 - TP[T_DSW] * g_rho * (1.0 - math.exp(-ex / TP[T_AW]))
                    Fx *= f
                    Fy *= f
                    Mz *= f
        if flags & OFFSET:
            Fy += WP[i, W_C_OFF] * Fz[i]
            Mz += WP[i, W_MZ_OFF]
        res[i, 0] = Fx
        res[i, 1] = Fy
        res[i, 2] = Fz[i]
        res[i, 3] = out[R_MX, i]
        res[i, 4] = out[R_MY, i]
        res[i, 5] = Mz
        kloc[i] = out[R_KXK, i] * lam[i, 1]


@njit(cache=True)
def slow_update(st, res, Vx, Fz, pb, TP, WP, dt, t, flags):
    """Temperatures (3 nodes), frictional energy and pressure of one instance, step dt."""
    for i in range(4):
        V = abs(Vx[i])
        ke = st[i, S_KR]
        ae = st[i, S_AR]
        pf = abs(res[i, 0] * ke * V) + abs(res[i, 1] * math.tan(ae) * V)
        ph = TP[T_FH] * Fz[i] * V
        v8 = V**0.8
        Ts = st[i, S_TS]
        Tc = st[i, S_TC]
        Tg = st[i, S_TG]
        Ta = TP[T_TAMB]
        qs = TP[T_FT] * TP[T_ETAS] * pf
        qc = TP[T_FT] * (1.0 - TP[T_ETAS]) * pf + ph
        gsc = TP[T_GSC] * (Ts - Tc)
        dTs = (
            qs - gsc - (TP[T_GSA0] + TP[T_GSA1] * v8) * (Ts - Ta) - TP[T_GSR] * (Ts - TP[T_TROAD])
        ) / TP[T_CS]
        gcg = TP[T_GCG] * (Tc - Tg)
        dTc = (qc + gsc - gcg - (TP[T_GCA0] + TP[T_GCA1] * v8) * (Tc - Ta)) / TP[T_CC]
        dTg = (gcg + TP[T_EPSB] * pb[i] - (TP[T_GGA0] + TP[T_GGA1] * v8) * (Tg - Ta)) / TP[T_CG]
        st[i, S_TS] = Ts + dt * dTs
        st[i, S_TC] = Tc + dt * dTc
        st[i, S_TG] = Tg + dt * dTg
        st[i, S_EF] += dt * pf
        if flags & PRESS:
            st[i, S_P] = pressure_of(st[i, S_TG], t + dt, TP, WP, i)


@njit(cache=True)
def pressure_of(Tg, t, TP, WP, i):
    mode = TP[T_PMODE]
    if mode == 1.0:  # sealed: gas law at constant volume on the gas node
        return (WP[i, W_P_SET] + TP[T_PATM]) * (Tg + 273.15) / (TP[T_TSET] + 273.15) - TP[T_PATM]
    if mode == 2.0 and WP[i, W_LEAK] > 0.0:  # slow leak (orifice: gauge decays exponentially)
        return WP[i, W_P_SET] * math.exp(-t / TP[T_TAU_LEAK])
    return WP[i, W_P_SET]


@njit(cache=True)
def _track_at(trk, s):
    n = trk.shape[0]
    sl = s % n
    j = int(sl)
    f = sl - j
    j1 = (j + 1) % n
    x = trk[j, 0] + f * (trk[j1, 0] - trk[j, 0])
    y = trk[j, 1] + f * (trk[j1, 1] - trk[j, 1])
    dth = trk[j1, 2] - trk[j, 2]
    dth = (dth + math.pi) % (2.0 * math.pi) - math.pi
    th = trk[j, 2] + f * dth
    return x, y, th


@njit(cache=True)
def _interp(arr, s):
    n = arr.shape[0]
    if s <= 0.0:
        return arr[0]
    j = int(s)
    if j >= n - 1:
        return arr[n - 1]
    f = s - j
    return arr[j] + f * (arr[j + 1] - arr[j])


@njit(cache=True)
def simulate(
    P0, P1, VP, TP, WP, trk, prof_v, prof_a, road, flags, usealt, n_steps, dt, sub, fast_log
):
    n_inst = flags.shape[0]
    n_out = n_steps // sub
    o_in = np.zeros((n_out, 4, 6))
    o_th = np.zeros((n_out, 4, 4))
    o_F = np.zeros((n_inst, n_out, 4, 6))
    o_v = np.zeros((n_out, N_L))
    o_lam = np.zeros((n_out, 4, 3))
    o_fast = np.zeros((n_steps if fast_log else 1, 4, 6))

    m = VP[V_M]
    a = VP[V_A]
    b = VP[V_B]
    L = a + b
    g = VP[V_G]
    h = VP[V_H]
    Re = VP[V_RE]
    # states
    s_tot = 0.0
    X, Y, psi = _track_at(trk, 0.0)
    vx = VP[V_V_INIT]
    vy = 0.0
    r = 0.0
    delta = 0.0
    d_int = 0.0
    kv = 1.0
    ax_f = 0.0
    ay_f = 0.0
    omega = np.full(4, vx / Re)
    u_abs = np.ones(4)
    u_tc = np.ones(4)
    pb = np.zeros(4)
    st = np.zeros((n_inst, 4, N_S))
    for j in range(n_inst):
        for i in range(4):
            st[j, i, S_TS] = TP[T_TINIT_S]
            st[j, i, S_TC] = TP[T_TINIT_C]
            st[j, i, S_TG] = TP[T_TINIT_G]
            st[j, i, S_P] = pressure_of(TP[T_TINIT_G], 0.0, TP, WP, i)
    # buffers
    kap = np.zeros(4)
    alp = np.zeros(4)
    gam = np.zeros(4)
    Fz = np.zeros(4)
    Vw = np.zeros(4)
    ck = np.ones(4)
    ck_s = np.ones(4)
    bFz = np.zeros(4)
    bk = np.zeros(4)
    ba = np.zeros(4)
    bg = np.zeros(4)
    bV = np.zeros(4)
    bp = np.zeros(4)
    bT = np.zeros(4)
    bph = np.zeros(4)
    out = np.zeros((N_ROWS, 4))
    res = np.zeros((4, 6))
    res_s = np.zeros((4, 6))
    lam = np.zeros((4, 2))
    kloc = np.zeros(4)
    dl = np.zeros(4)
    Fstat_f = m * g * b / (2.0 * L)
    Fstat_r = m * g * a / (2.0 * L)

    for step in range(n_steps):
        t = step * dt
        # ---------------- driver ----------------
        for _ in range(2):  # project the car on the centre line
            px, py, pth = _track_at(trk, s_tot)
            ds_ = (X - px) * math.cos(pth) + (Y - py) * math.sin(pth)
            s_tot += ds_
        px, py, pth = _track_at(trk, s_tot)
        e_y = -(X - px) * math.sin(pth) + (Y - py) * math.cos(pth)
        la = VP[V_LA0] + VP[V_LA1] * vx
        tx, ty, _ = _track_at(trk, s_tot + la)
        dxw = tx - X
        dyw = ty - Y
        dxb = math.cos(psi) * dxw + math.sin(psi) * dyw
        dyb = -math.sin(psi) * dxw + math.cos(psi) * dyw
        k_pp = 2.0 * dyb / (dxb * dxb + dyb * dyb)
        r_des = vx * k_pp
        d_int += VP[V_KI_YAW] * (r_des - r) * dt
        d_int = min(0.08, max(-0.08, d_int))
        d_cmd = (L + VP[V_KUS] * vx * vx) * k_pp + d_int + VP[V_KP_YAW] * (r_des - r)
        ddot = (d_cmd - delta) / VP[V_TAU_STEER]
        ddot = min(VP[V_STEER_RATE], max(-VP[V_STEER_RATE], ddot))
        delta += ddot * dt
        delta = min(VP[V_DELTA_MAX], max(-VP[V_DELTA_MAX], delta))
        # speed: the driver lifts when running wide
        # and backs off when the tyres slide beyond the slip angle they like (grip feel)
        ey_a = abs(e_y)
        slide = 0.0
        for i in range(4):
            slide = max(slide, abs(alp[i]))
        if ey_a > 1.5:
            kv -= 0.03 * (ey_a - 1.5) * dt
        if slide > VP[V_ALIM]:
            kv -= 0.6 * (slide / VP[V_ALIM] - 1.0) * dt
        elif ey_a < 1.0 and slide < 0.8 * VP[V_ALIM]:
            kv += 0.004 * dt
        kv = min(1.0, max(0.75, kv))
        s_pv = s_tot + vx * VP[V_T_PREVIEW]
        v_ref = _interp(prof_v, s_pv) * kv
        a_ff = _interp(prof_a, s_pv) * kv * kv
        a_cmd = a_ff + VP[V_KV] * (v_ref - vx)
        # friction circle: no more braking than the lateral load leaves
        ul = min(1.0, abs(ay_f) / (VP[V_MU_LAT] * g))
        a_brk_max = VP[V_MU_BRK] * g * math.sqrt(max(0.04, 1.0 - ul * ul))
        if slide > 0.9 * VP[V_ALIM]:  # sliding: lift off, do not brake mid-corner
            a_brk_max = min(a_brk_max, 0.1 * g)
        if a_cmd < -a_brk_max:
            a_cmd = -a_brk_max
        drag = 0.5 * VP[V_RHO] * VP[V_CDA] * vx * abs(vx)
        F_dem = m * a_cmd + drag + VP[V_CRR] * m * g
        if F_dem > 0.0:
            F_drive = min(F_dem, VP[V_PMAX] / max(vx, 3.0), VP[V_FTRACT])
            F_brake = 0.0
        else:
            F_drive = 0.0
            F_brake = -F_dem
        # ---------------- loads, camber, slips ----------------
        down = 0.5 * VP[V_RHO] * VP[V_CLA] * vx * vx
        dFx = m * ax_f * h / L
        dFyf = VP[V_CHIF] * m * ay_f * h / VP[V_TF]
        dFyr = (1.0 - VP[V_CHIF]) * m * ay_f * h / VP[V_TR]
        Fz[0] = Fstat_f + 0.5 * down * VP[V_AERO_F] - 0.5 * dFx - dFyf
        Fz[1] = Fstat_f + 0.5 * down * VP[V_AERO_F] - 0.5 * dFx + dFyf
        Fz[2] = Fstat_r + 0.5 * down * (1.0 - VP[V_AERO_F]) + 0.5 * dFx - dFyr
        Fz[3] = Fstat_r + 0.5 * down * (1.0 - VP[V_AERO_F]) + 0.5 * dFx + dFyr
        phi = VP[V_KPHI] * ay_f
        for i in range(4):
            Fz[i] = max(100.0, Fz[i] + road[step, i])
            xi = WP[i, W_X]
            yi = WP[i, W_Y]
            vxi = vx - r * yi
            vyi = vy + r * xi
            di = delta * WP[i, W_STEERED] + WP[i, W_TOE]
            dl[i] = di
            cd = math.cos(di)
            sd = math.sin(di)
            Vxw = vxi * cd + vyi * sd
            Vyw = -vxi * sd + vyi * cd
            Vw[i] = Vxw
            kap[i] = (omega[i] * Re - Vxw) / max(abs(Vxw), 1.0)
            alp[i] = math.atan(Vyw / max(abs(Vxw), 1.0))
            gam[i] = WP[i, W_CAM0] + WP[i, W_CGAIN] * phi
        # ---------------- tyres: the main instance ----------------
        relax_update(st[0], kap, alp, Fz, Vw, TP, dt, flags[0], ck)
        P = P1 if usealt[0] else P0
        tyre_forces(
            P,
            flags[0],
            st[0],
            gam,
            Fz,
            Vw,
            TP,
            WP,
            bFz,
            bk,
            ba,
            bg,
            bV,
            bp,
            bT,
            bph,
            out,
            res,
            lam,
            kloc,
        )
        for j in range(1, n_inst):
            relax_update(st[j], kap, alp, Fz, Vw, TP, dt, flags[j], ck_s)
        if fast_log:
            for i in range(4):
                for q in range(6):
                    o_fast[step, i, q] = res[i, q]
        # ---------------- output sample, shadows, slow states ----------------
        if step % sub == 0:
            k = step // sub
            if k < n_out:
                for i in range(4):
                    o_in[k, i, 0] = kap[i]
                    o_in[k, i, 1] = alp[i]
                    o_in[k, i, 2] = gam[i]
                    o_in[k, i, 3] = Fz[i]
                    o_in[k, i, 4] = Vw[i]
                    o_in[k, i, 5] = bp[i]
                    o_th[k, i, 0] = st[0, i, S_TS]
                    o_th[k, i, 1] = st[0, i, S_TC]
                    o_th[k, i, 2] = st[0, i, S_TG]
                    o_th[k, i, 3] = st[0, i, S_EF]
                    o_lam[k, i, 0] = lam[i, 0]
                    o_lam[k, i, 1] = lam[i, 1]
                    o_lam[k, i, 2] = abs(res[i, 0] * st[0, i, S_KR] * abs(Vw[i])) + abs(
                        res[i, 1] * math.tan(st[0, i, S_AR]) * abs(Vw[i])
                    )
                    for q in range(6):
                        o_F[0, k, i, q] = res[i, q]
                o_v[k, L_X] = X
                o_v[k, L_Y] = Y
                o_v[k, L_PSI] = psi
                o_v[k, L_VX] = vx
                o_v[k, L_VY] = vy
                o_v[k, L_R] = r
                o_v[k, L_DELTA] = delta
                o_v[k, L_S] = s_tot
                o_v[k, L_VREF] = v_ref
                o_v[k, L_AX] = ax_f
                o_v[k, L_AY] = ay_f
                o_v[k, L_KV] = kv
                o_v[k, L_EY] = e_y
                for j in range(1, n_inst):
                    Pj = P1 if usealt[j] else P0
                    tyre_forces(
                        Pj,
                        flags[j],
                        st[j],
                        gam,
                        Fz,
                        Vw,
                        TP,
                        WP,
                        bFz,
                        bk,
                        ba,
                        bg,
                        bV,
                        bp,
                        bT,
                        bph,
                        out,
                        res_s,
                        lam,
                        ck_s,
                    )
                    for i in range(4):
                        for q in range(6):
                            o_F[j, k, i, q] = res_s[i, q]
                    slow_update(st[j], res_s, Vw, Fz, pb, TP, WP, dt * sub, t, flags[j])
                slow_update(st[0], res, Vw, Fz, pb, TP, WP, dt * sub, t, flags[0])
        # ---------------- vehicle dynamics ----------------
        sFx = 0.0
        sFy = 0.0
        sMz = 0.0
        for i in range(4):
            cd = math.cos(dl[i])
            sd = math.sin(dl[i])
            Fxb = res[i, 0] * cd - res[i, 1] * sd
            Fyb = res[i, 0] * sd + res[i, 1] * cd
            sFx += Fxb
            sFy += Fyb
            sMz += WP[i, W_X] * Fyb - WP[i, W_Y] * Fxb + res[i, 5]
        ax = (sFx - drag) / m
        ay = sFy / m
        # wheels: semi-implicit in the slip stiffness (stable at any speed)
        for i in range(4):
            u_t = 1.0
            if kap[i] > VP[V_KAP_TC]:
                u_t = max(0.0, 1.0 - (kap[i] - VP[V_KAP_TC]) / 0.03)
            u_tc[i] += (u_t - u_tc[i]) * dt / VP[V_TAU_ABS]
            u_b = 1.0
            if kap[i] < -VP[V_KAP_ABS]:
                u_b = max(0.0, 1.0 - (-kap[i] - VP[V_KAP_ABS]) / 0.03)
            u_abs[i] += (u_b - u_abs[i]) * dt / VP[V_TAU_ABS]
            Td = u_tc[i] * F_drive * Re * WP[i, W_DRIVE]
            Tb = u_abs[i] * F_brake * Re * WP[i, W_BRAKE]
            pb[i] = Tb * omega[i]
            Iw = WP[i, W_IW]
            num = Td - Tb - Re * res[i, 0] + res[i, 4]
            den = 1.0 + dt * Re * Re * max(kloc[i], 0.0) * ck[i] / (Iw * max(abs(Vw[i]), 1.0))
            omega[i] += dt * num / Iw / den
            if omega[i] < 0.0:
                omega[i] = 0.0
        vx += dt * (ax + r * vy)
        vy += dt * (ay - r * vx)
        r += dt * sMz / VP[V_IZ]
        psi += dt * r
        X += dt * (vx * math.cos(psi) - vy * math.sin(psi))
        Y += dt * (vx * math.sin(psi) + vy * math.cos(psi))
        ax_f += (ax - ax_f) * dt / VP[V_TAU_PITCH]
        ay_f += (ay - ay_f) * dt / VP[V_TAU_ROLL]
        if vx < 3.0:
            vx = 3.0
    return o_in, o_th, o_F, o_v, o_lam, o_fast
