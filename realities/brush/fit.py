"""Fit an MF 6.1 property file to the brush tyre's nominal steady state (own least squares).

The brush (cold, isothermal, no effects) is evaluated on a grid of the programmes' loads,
pressures, inclinations and slips (pure lateral sweeps, and drive/brake sweeps at several
slip angles); candidate coefficient sets are evaluated with ``tire_model_ros.model.TireModel``
(allowed by the brief for this purpose only) and fitted in stages with scipy least_squares:
Fy0 -> Fx0 -> combined -> all forces jointly -> Mz. Mx and My follow from the brush's simple
forms exactly (QSX2, QSX3, QSY*). The result is cached per tyre variant in ``fitted/``.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from tire_model_ros.model import TireModel, read_tir, write_tir

from . import tyre as ty

HERE = Path(__file__).resolve().parent
FITTED = HERE / "fitted"
# the shared checkout beside the project root (as test/conftest.py finds it)
TEMPLATE = (
    Path(__file__).resolve().parents[3] / "shared" / "reference" / "tir" / "FSAE_Defaults.tir"
)
FIT_VERSION = "6"

LAT = ["PCY1", "PDY1", "PDY2", "PDY3", "PEY1", "PEY2", "PEY4", "PEY5", "PKY1", "PKY2",
       "PKY3", "PKY4", "PKY5", "PKY6", "PKY7", "PVY3", "PVY4", "PPY1", "PPY2", "PPY3", "PPY4",
       "PPY5"]  # fmt: skip
LON = ["PCX1", "PDX1", "PDX2", "PDX3", "PEX1", "PEX2", "PEX3", "PEX4", "PKX1", "PKX2", "PKX3",
       "PPX1", "PPX2", "PPX3", "PPX4"]  # fmt: skip
COMB = ["RBX1", "RBX2", "RBX3", "RCX1", "REX1", "REX2", "RHX1", "RBY1", "RBY2", "RBY3", "RBY4",
        "RCY1", "REY1", "REY2", "RHY1", "RHY2"]  # fmt: skip
MZ = ["QBZ1", "QBZ2", "QBZ3", "QBZ4", "QBZ5", "QBZ9", "QBZ10", "QCZ1", "QDZ1", "QDZ2", "QDZ3",
      "QDZ4", "QDZ6", "QDZ7", "QDZ8", "QDZ9", "QDZ10", "QDZ11", "QEZ1", "QEZ2", "QEZ3", "QEZ4",
      "QEZ5", "QHZ1", "QHZ2", "QHZ3", "QHZ4", "PPZ1", "PPZ2", "SSZ1", "SSZ2", "SSZ3", "SSZ4"]  # fmt: skip

# coefficient groups zeroed by the cases (what "model.tir lacks")
CAMBER_TERMS = ["PDX3", "PDY3", "PEY3", "PEY4", "PEY5", "PKY3", "PKY5", "PKY6", "PKY7", "PVY3",
                "PVY4", "PPY5", "RBX3", "RBY4", "RVY3", "QBZ4", "QBZ5", "QDZ3", "QDZ4", "QDZ8",
                "QDZ9", "QDZ10", "QDZ11", "QEZ5", "QHZ3", "QHZ4", "SSZ3", "SSZ4", "QSX2",
                "QSX7", "QSX10", "QSX12", "QSX14", "QSY5", "QSY6", "PPMX1"]  # fmt: skip
# PEY3 is the sign(alpha) asymmetry of the curvature: the fitted file uses it only for the
# camber-induced asymmetry of the brush, so it goes with the camber terms.
COMBINED_ZERO = {"RBX1": 0.0, "RBX2": 0.0, "RBX3": 0.0, "RHX1": 0.0, "RBY1": 0.0, "RBY2": 0.0,
                 "RBY3": 0.0, "RBY4": 0.0, "RHY1": 0.0, "RHY2": 0.0, "RVY1": 0.0, "RVY2": 0.0,
                 "RVY3": 0.0}  # fmt: skip
PRESSURE_TERMS = ["PFZ1", "PCFX3", "PCFY3", "PCMZ1", "PPX1", "PPX2", "PPX3", "PPX4", "PPMX1",
                  "PPY1", "PPY2", "PPY3", "PPY4", "PPY5", "QSY8", "PPZ1", "PPZ2"]  # fmt: skip


# boxes that keep weakly determined coefficients sane (the E factors are clipped at 1 by the
# model, which leaves flat directions in the least squares)
BOUNDS = {
    "PCY1": (0.8, 2.2), "PCX1": (0.8, 2.2), "QCZ1": (0.5, 2.5), "RCX1": (0.3, 2.0),
    "RCY1": (0.3, 2.0), "PEY1": (-3.0, 1.0), "PEX1": (-3.0, 1.0), "REX1": (-3.0, 1.0),
    "REY1": (-3.0, 1.0), "QEZ1": (-10.0, 1.0), "PEY2": (-3.0, 3.0), "PEX2": (-3.0, 3.0),
    "PEX3": (-3.0, 3.0), "PEX4": (-100.0, 100.0), "PEY3": (-1.0, 1.0), "PEY4": (-50.0, 50.0),
    "PEY5": (-500.0, 500.0), "PDX3": (-50.0, 50.0), "PDY3": (-50.0, 50.0),
    "PKY2": (0.2, 10.0), "PKY4": (0.5, 3.0), "PKY3": (-3.0, 3.0), "PKY5": (-200.0, 200.0),
    "PKY6": (-5.0, 5.0), "PKY7": (-5.0, 5.0), "PVY3": (-3.0, 3.0), "PVY4": (-3.0, 3.0),
    "PPY1": (-2.0, 2.0), "PPY2": (-2.0, 3.0), "PPY3": (-1.0, 1.0), "PPY4": (-1.0, 1.0),
    "PPY5": (-3.0, 3.0), "PPX1": (-2.0, 2.0), "PPX2": (-2.0, 2.0), "PPX3": (-1.0, 1.0),
    "PPX4": (-1.0, 1.0), "PKX1": (1.0, 200.0), "PKX2": (-50.0, 50.0), "PKX3": (-2.0, 2.0),
    "PHY1": (-0.05, 0.05), "PHY2": (-0.05, 0.05),
    "RBX1": (0.0, 100.0), "RBX2": (-100.0, 100.0), "RBX3": (-5000.0, 5000.0),
    "REX2": (-3.0, 3.0), "RHX1": (-0.1, 0.1), "RBY1": (0.0, 100.0), "RBY2": (-100.0, 100.0),
    "RBY3": (-0.3, 0.3), "RBY4": (-5000.0, 5000.0), "REY2": (-3.0, 3.0),
    "RHY1": (-0.1, 0.1), "RHY2": (-0.1, 0.1), "RVY1": (-1.0, 1.0), "RVY2": (-1.0, 1.0),
    "RVY3": (-10.0, 10.0), "RVY4": (0.0, 100.0), "RVY5": (-5.0, 5.0), "RVY6": (-100.0, 100.0),
    "QBZ1": (0.0, 50.0), "QBZ2": (-20.0, 20.0), "QBZ3": (-20.0, 20.0), "QBZ4": (-20.0, 20.0),
    "QBZ5": (-20.0, 20.0), "QBZ9": (0.0, 200.0), "QBZ10": (-50.0, 50.0),
    "QDZ1": (0.0, 1.0), "QEZ2": (-10.0, 10.0), "QEZ3": (-10.0, 10.0), "QEZ4": (-3.0, 3.0),
    "QEZ5": (-50.0, 50.0),
}  # fmt: skip


def fit_grid(variant: ty.Variant):
    """Operating points of the fit: (Fz, kappa, alpha, gamma, p) arrays and a lateral mask."""
    T = ty.tyre_vector(variant)
    Fz0, p0 = T[ty.FZ0], T[ty.P0]
    loads = sorted(set(list(variant.loads) + [1.4 if variant.kind == "fsae" else 1.75]))
    loads = np.array(loads) * Fz0
    press = np.array(sorted(set(list(variant.pressures) + [0.6]))) * p0
    gams = np.radians([0.0, 2.0, 4.0])
    alph = np.radians(np.linspace(-14.0, 14.0, 29))
    kap = np.concatenate([np.linspace(-0.25, -0.05, 6), np.linspace(-0.03, 0.03, 7),
                          np.linspace(0.05, 0.25, 6)])  # fmt: skip
    alpha_db = np.radians([0.0, -3.0, -6.0])
    rows = []
    for Fz in loads:
        for p in press:
            for g in gams:
                for a in alph:
                    rows.append((Fz, 0.0, a, g, p, 1))
                for a in alpha_db:
                    # combined slip only where the programmes run it: gamma 0 or 2 deg,
                    # 0.75..1.25 NOMPRES (set point, leak, sealed gas)
                    if a != 0.0 and (abs(p / p0 - 1.0) > 0.25 or g > math.radians(2.5)):
                        continue
                    for k in kap:
                        if k == 0.0:
                            continue
                        rows.append((Fz, k, a, g, p, 0))
    R = np.array(rows)
    return T, R[:, 0], R[:, 1], R[:, 2], R[:, 3], R[:, 4], R[:, 5].astype(bool)


def fit_weights(T, Fz, p, a):
    """Weight 1 where most programmes run; 0.3 at the sidewall corner's extra pressure and
    load (only the sidewall case goes there, and its Fy is changed there anyway) and for
    combined slip away from NOMPRES (only the leak and sealed-gas sessions run it there)."""
    w = np.ones_like(Fz)
    w[p < 0.65 * T[ty.P0]] = 0.3
    w[Fz > 1.3 * T[ty.FZ0] * (1.0 if T[ty.FZ0] < 2000 else 1.2)] = 0.3
    w[(a != 0.0) & (np.abs(p - T[ty.P0]) > 1.0)] = 0.3
    return w


def _base_tir(variant: ty.Variant, T: np.ndarray):
    tir = read_tir(TEMPLATE)
    Fz0, p0 = T[ty.FZ0], T[ty.P0]
    upd = {
        "UNLOADED_RADIUS": T[ty.R0], "WIDTH": variant.width, "ASPECT_RATIO": variant.aspect,
        "RIM_RADIUS": variant.rim_radius, "RIM_WIDTH": variant.width * 1.05,
        "FNOMIN": Fz0, "NOMPRES": p0, "INFLPRES": p0, "LONGVL": T[ty.VREF],
        "VERTICAL_STIFFNESS": T[ty.KZ0], "PFZ1": T[ty.PFZ], "LATERAL_STIFFNESS": T[ty.CLAT],
        "Q_RA1": T[ty.QA] * math.sqrt(2.0), "Q_RA2": 0.0,
        "PRESMIN": 0.5 * p0, "PRESMAX": 1.5 * p0, "FZMIN": 0.02 * Fz0, "FZMAX": 2.5 * Fz0,
        "KPUMIN": -0.6, "KPUMAX": 0.6, "ALPMIN": -0.45, "ALPMAX": 0.45,
        "CAMMIN": -0.2, "CAMMAX": 0.2,
        "QSX1": 0.0, "QSX2": T[ty.QSX2], "QSX3": Fz0 / (T[ty.R0] * T[ty.CLAT]), "QSX4": 0.0,
        "QSX5": 0.0, "QSX6": 0.0, "QSX7": 0.0, "QSX8": 0.0, "QSX9": 0.0, "QSX10": 0.0,
        "QSX11": 0.0, "QSX12": 0.0, "QSX13": 0.0, "QSX14": 0.0, "PPMX1": 0.0,
        "QSY1": T[ty.QSY1], "QSY2": 0.0, "QSY3": T[ty.QSY3], "QSY4": T[ty.QSY4], "QSY5": 0.0,
        "QSY6": 0.0, "QSY7": T[ty.QSY7], "QSY8": T[ty.QSY8],
        "PHX1": 0.0, "PHX2": 0.0, "PVX1": 0.0, "PVX2": 0.0, "PVY1": 0.0, "PVY2": 0.0,
        "PHY1": 0.0, "PHY2": 0.0, "NOMTEMP": 25.0,
    }  # fmt: skip
    # starting values from the brush
    Kya = -ty.evaluate(T, Fz0, 0.0, 1e-4)["Fy"] / 1e-4
    Kxk = ty.evaluate(T, Fz0, 1e-4, 0.0)["Fx"] / 1e-4
    a = np.radians(np.linspace(0, 14, 57))
    muy = float(np.max(-ty.evaluate(T, Fz0, 0.0, a)["Fy"]) / Fz0)
    mux = float(np.max(ty.evaluate(T, Fz0, np.linspace(0, 0.25, 51), 0.0)["Fx"]) / Fz0)
    upd.update({
        "PCY1": 1.4, "PDY1": muy, "PDY2": -0.1, "PDY3": 0.0, "PEY1": 0.0, "PEY2": 0.0,
        "PEY3": 0.0, "PEY4": 0.0, "PEY5": 0.0, "PKY1": -Kya / Fz0 * 1.6, "PKY2": 1.5,
        "PKY3": 0.0, "PKY4": 1.6, "PKY5": 0.0, "PKY6": -variant.targets["Kyg_rel"],
        "PKY7": 0.0, "PVY3": 0.0, "PVY4": 0.0, "PPY1": 0.0, "PPY2": 0.0, "PPY3": 0.0,
        "PPY4": 0.0, "PPY5": 0.0,
        "PCX1": 1.5, "PDX1": mux, "PDX2": -0.1, "PDX3": 0.0, "PEX1": 0.0, "PEX2": 0.0,
        "PEX3": 0.0, "PEX4": 0.0, "PKX1": Kxk / Fz0, "PKX2": 0.0, "PKX3": 0.0, "PPX1": 0.0,
        "PPX2": 0.0, "PPX3": 0.0, "PPX4": 0.0,
        "RBX1": 12.0, "RBX2": 10.0, "RBX3": 0.0, "RCX1": 1.0, "REX1": 0.0, "REX2": 0.0,
        "RHX1": 0.0, "RBY1": 8.0, "RBY2": 5.0, "RBY3": 0.0, "RBY4": 0.0, "RCY1": 1.0,
        "REY1": 0.0, "REY2": 0.0, "RHY1": 0.0, "RHY2": 0.0, "RVY1": 0.0, "RVY2": 0.0,
        "RVY3": 0.0, "RVY4": 0.0, "RVY5": 0.0, "RVY6": 0.0,
        "QBZ1": 8.0, "QBZ2": 0.0, "QBZ3": 0.0, "QBZ4": 0.0, "QBZ5": 0.0, "QBZ9": 10.0,
        "QBZ10": 0.0, "QCZ1": 1.2, "QDZ1": 0.08, "QDZ2": 0.0, "QDZ3": 0.0, "QDZ4": 0.0,
        "QDZ6": 0.0, "QDZ7": 0.0, "QDZ8": 0.0, "QDZ9": 0.0, "QDZ10": 0.0, "QDZ11": 0.0,
        "QEZ1": 0.0, "QEZ2": 0.0, "QEZ3": 0.0, "QEZ4": 0.0, "QEZ5": 0.0, "QHZ1": 0.0,
        "QHZ2": 0.0, "QHZ3": 0.0, "QHZ4": 0.0, "PPZ1": 0.0, "PPZ2": 0.0,
        "SSZ1": 0.0, "SSZ2": -Fz0 / (T[ty.R0] * T[ty.CLAT]), "SSZ3": 0.0, "SSZ4": 0.0,
    })  # fmt: skip
    return tir.with_params(upd)


class _Fitter:
    def __init__(self, tir, grid, target, weight=None):
        self.tir = tir
        self.Fz, self.k, self.a, self.g, self.p = grid
        self.target = target
        self.sw = np.sqrt(weight) if weight is not None else np.ones_like(self.Fz)
        self.params = dict(tir.params)

    def model(self, upd):
        return TireModel(self.tir.with_params({**self.params, **upd}))

    def run(self, names, channels, mask, scale, max_nfev=200):
        x0 = np.array([self.params[n] for n in names])
        sel = np.flatnonzero(mask)
        args = (self.Fz[sel], self.k[sel], self.a[sel], self.g[sel])
        p = self.p[sel]

        def resid(x):
            try:
                m = self.model(dict(zip(names, x, strict=True)))
            except ValueError:
                return np.full(len(sel) * len(channels), 1e6)
            out = m.evaluate(*args, p=p, full=False)
            w = self.sw[sel]
            r = [w * (getattr(out, ch) - self.target[ch][sel]) / scale[ch] for ch in channels]
            r = np.concatenate(r)
            return np.where(np.isfinite(r), r, 1e6)

        lb = np.array([BOUNDS.get(n, (-np.inf, np.inf))[0] for n in names], float)
        ub = np.array([BOUNDS.get(n, (-np.inf, np.inf))[1] for n in names], float)
        x0 = np.clip(x0, lb + 1e-9, ub - 1e-9)
        sol = least_squares(resid, x0, bounds=(lb, ub), x_scale="jac", max_nfev=max_nfev,
                            diff_step=1e-6)  # fmt: skip
        self.params.update(dict(zip(names, sol.x, strict=True)))
        return sol


def _hash(variant: ty.Variant) -> str:
    blob = json.dumps({"v": FIT_VERSION, "b": ty.BRUSH_VERSION, "p": variant.params,
                       "t": variant.targets, "l": variant.loads, "pr": variant.pressures},
                      sort_keys=True)  # fmt: skip
    return hashlib.sha1(blob.encode()).hexdigest()[:10]


def fit_variant(variant: ty.Variant, verbose: bool = True):
    """Fit and return (TirData, report dict)."""
    T, Fz, k, a, g, p, lat = fit_grid(variant)
    tgt = ty.evaluate(T, Fz, k, a, g, p=p)
    target = {"Fx": tgt["Fx"], "Fy": tgt["Fy"], "Mz": tgt["Mz"]}
    tir = _base_tir(variant, T)
    F = _Fitter(tir, (Fz, k, a, g, p), target, fit_weights(T, Fz, p, a * (~lat)))
    sc = {"Fx": 1.0, "Fy": 1.0, "Mz": 1.0}
    P0 = T[ty.P0]
    lat0 = lat & (g == 0.0) & (p == P0)
    lon = (~lat) & (a == 0.0)
    lon0 = lon & (g == 0.0) & (p == P0)
    every = np.ones_like(lat)
    stages = [
        (["PCY1", "PDY1", "PDY2", "PKY1", "PKY2", "PKY4", "PEY1", "PEY2"], ["Fy"], lat0, 200),
        (LAT, ["Fy"], lat, 200),
        (["PCX1", "PDX1", "PDX2", "PEX1", "PEX2", "PKX1", "PKX2", "PKX3"], ["Fx"], lon0, 200),
        (LON, ["Fx"], lon, 200),
        (COMB, ["Fx", "Fy"], ~lat, 200),
        (LAT + LON + COMB, ["Fx", "Fy"], every, 400),
        (MZ, ["Mz"], every, 300),
    ]
    for names, chans, mask, nfev in stages:
        F.run(names, chans, mask, sc, max_nfev=nfev)
        if verbose:
            m = F.model({})
            o = m.evaluate(Fz[mask], k[mask], a[mask], g[mask], p=p[mask], full=False)
            errs = [float(np.sqrt(np.mean((getattr(o, ch) - target[ch][mask]) ** 2)))
                    for ch in chans]  # fmt: skip
            print(
                f"  stage {names[0]}..({len(names)}) {chans}: rms {np.round(errs, 2)}", flush=True
            )
    model = F.model({})
    out = model.evaluate(Fz, k, a, g, p=p, full=False)
    rep = {}
    for ch in ("Fx", "Fy", "Mz"):
        e = getattr(out, ch) - target[ch]
        rep[ch] = {"rms": float(np.sqrt(np.mean(e**2))), "max": float(np.max(np.abs(e))),
                   "rms_lateral_sweeps": float(np.sqrt(np.mean(e[lat] ** 2))),
                   "rms_drive_brake": float(np.sqrt(np.mean(e[~lat] ** 2)))}  # fmt: skip
    if verbose:
        for ch, r in rep.items():
            print(
                f"  {ch}: rms {r['rms']:.2f}  max {r['max']:.2f}  "
                f"(lateral {r['rms_lateral_sweeps']:.2f}, drive/brake {r['rms_drive_brake']:.2f})"
            )
    return model.tir, rep


def fitted_path(variant: ty.Variant) -> Path:
    return FITTED / f"{variant.name}-{_hash(variant)}.tir"


def get_fitted(variant: ty.Variant, verbose: bool = False):
    """(TirData, report) for the variant: from the cache in ``fitted/``, fitting if missing."""
    path = fitted_path(variant)
    rep_path = path.with_suffix(".json")
    if path.exists() and rep_path.exists():
        return read_tir(path), json.loads(rep_path.read_text())
    tir, rep = fit_variant(variant, verbose=verbose)
    FITTED.mkdir(exist_ok=True)
    for old in FITTED.glob(f"{variant.name}-*"):
        old.unlink()
    write_tir(tir, path, overwrite=True)
    rep_path.write_text(json.dumps(rep, indent=1))
    return read_tir(path), rep


if __name__ == "__main__":
    import sys
    import time

    for name in sys.argv[1:] or list(ty.VARIANTS):
        t0 = time.time()
        get_fitted(ty.VARIANTS[name], verbose=True)
        print(f"{name}: {time.time() - t0:.1f} s")
