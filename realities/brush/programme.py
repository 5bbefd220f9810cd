"""TTC-like rig programmes: continuous lateral sweeps and drive/brake runs, no pauses.

A programme is a list of units (a warm-up, cornering sweeps 0 -> +A -> -A -> 0, drive/brake
slip-ratio sweeps at a held slip angle); between two units whose conditions differ there is a
short transition at zero slip in which load, camber, pressure set point and speed ramp to the
next values (no pause: the wheel keeps rolling under load).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import tyre as ty
from .sim import DT


@dataclass
class Programme:
    t: np.ndarray  # sample times [s] (the slip stamps, before dropouts)
    Fz: np.ndarray  # [N]
    kappa: np.ndarray  # [-]
    alpha: np.ndarray  # [rad]
    gamma: np.ndarray  # [rad]
    V: np.ndarray  # [m/s]
    pset: np.ndarray  # inflation pressure set point, gauge [Pa]
    reset: np.ndarray  # True where the pressure is (re)set to the set point
    kind: np.ndarray  # 0 transition, 1 warm-up, 2 cornering, 3 drive/brake
    units: list = field(default_factory=list)
    text: str = ""


def _tri(A: float, rate: float, direction: int) -> np.ndarray:
    """0 -> direction*A -> -direction*A -> 0 at constant rate (a TTC sweep)."""
    T1 = A / rate
    n = int(round(4 * T1 / DT))
    s = np.arange(n) * DT
    y = np.interp(s, [0, T1, 3 * T1, 4 * T1], [0.0, A, -A, 0.0])
    return direction * y


@dataclass
class Unit:
    kind: str  # "warmup", "sweep", "drivebrake", "hold"
    Fz: float
    p: float
    gamma: float
    V: float
    alpha: np.ndarray
    kappa: np.ndarray
    note: str = ""


def build(rng: np.random.Generator, variant: ty.Variant, T: np.ndarray, minutes: float,
          single_pressure: bool = False, speeds: tuple | None = None,
          other_speed_block: bool = False, sidewall: bool = False,
          delta_max: float = 1.35, t0: float = 1_700_000_000.0) -> Programme:  # fmt: skip
    """A randomised TTC-like programme of ``minutes`` at 100 Hz.

    single_pressure : one set point (NOMPRES) for the whole session.
    speeds : cornering and drive/brake blocks repeated at each of these speeds [m/s].
    other_speed_block : a few reference sweeps at another speed.
    sidewall : add the low-pressure / high-load corner (sweeps to 13-14 deg).
    delta_max : otherwise, (load, pressure) pairs whose deflection exceeds delta_max times
        the nominal one are left out (the sidewall corner is not visited).
    """
    Fz0, p0, V0 = T[ty.FZ0], T[ty.P0], T[ty.VREF]
    N = int(round(minutes * 60.0 / DT))
    d0 = ty.deflection(T, Fz0, p0)
    A = math.radians(rng.uniform(11.0, 13.0))  # sweep amplitude
    rate = math.radians(rng.uniform(3.5, 4.5))  # sweep rate
    km = rng.uniform(0.15, 0.2)  # drive/brake slip-ratio amplitude
    krate = rng.uniform(0.06, 0.09)  # slip-ratio rate [1/s]

    def sweep(Fz, p, g, V, note="", amp=A):
        d = 1 if rng.random() < 0.7 else -1
        return Unit("sweep", Fz, p, g, V, _tri(amp, rate * rng.uniform(0.85, 1.15), d),
                    None, note)  # fmt: skip

    def drivebrake(Fz, p, g, V, a, note=""):
        d = 1 if rng.random() < 0.6 else -1
        k = _tri(km, krate * rng.uniform(0.95, 1.05), d)
        return Unit("drivebrake", Fz, p, g, V, np.full(len(k), a), k, note)

    def ok(Fz, p):
        return sidewall or ty.deflection(T, Fz, p) <= delta_max * d0 + 1e-12

    loads_all = [f * Fz0 for f in variant.loads]
    press_all = [f * p0 for f in variant.pressures]
    cambers = [0.0, math.radians(2.0), math.radians(4.0)]
    if rng.random() < 0.3:
        cambers = [cambers[i] for i in rng.permutation(3)]
    sweep_s = 4 * A / rate
    db_s = 4 * km / krate
    budget = minutes * 60.0
    units: list[Unit] = []
    # warm-up: gentle sinusoidal steer at a medium-high load
    wu_s = rng.uniform(18.0, 30.0)
    nwu = int(round(wu_s / DT))
    Fz_wu = min(loads_all, key=lambda x: abs(x - 0.8 * Fz0))
    aw = math.radians(rng.uniform(3.0, 5.0)) * np.sin(2 * math.pi * rng.uniform(0.2, 0.3)
                                                      * np.arange(nwu) * DT)  # fmt: skip
    units.append(Unit("warmup", Fz_wu, p0, 0.0, V0, aw, None, "warm-up"))
    # ---- cornering and drive/brake sets
    spd = list(speeds) if speeds else [V0]
    if single_pressure:
        P = [p0]
    else:
        nP = int(rng.choice([2, 3])) if len(press_all) <= 3 else int(rng.choice([2, 3, 4]))
        others = [x for x in press_all if abs(x - p0) > 1]
        P = [p0] + list(rng.choice(others, size=min(nP - 1, len(others)), replace=False))
        P = sorted(P, key=lambda x: -x if rng.random() < 0.5 else x)
    frac_corner = 0.68 if not speeds else 0.62
    n_sweeps = max(3, int(frac_corner * (budget - wu_s) / (sweep_s + 1.5) / len(spd)))
    G = cambers if not speeds else cambers[:2]
    nL = int(np.clip(round(n_sweeps / (len(P) * len(G))), 2, len(loads_all)))
    if len(P) * len(G) * nL > 1.25 * n_sweeps and len(P) > 1:
        P = P[:-1]
    # loads: spread over the variant's range, always including the one nearest FZ0
    idx = np.linspace(0, len(loads_all) - 1, nL).round().astype(int)
    L = sorted(set(loads_all[i] for i in idx) | {min(loads_all, key=lambda x: abs(x - Fz0))})
    while len(P) > 2 and len(P) * len(G) * len(L) > 1.1 * n_sweeps:
        P = P[:-1]
    corner: list[Unit] = []
    for V in spd:
        for p in P:
            for g in G:
                order = list(L) if rng.random() < 0.5 else list(L)[::-1]
                if rng.random() < 0.3:
                    order = [order[i] for i in rng.permutation(len(order))]
                for Fz in order:
                    if ok(Fz, p):
                        corner.append(sweep(Fz, p, g, V))
    db: list[Unit] = []
    n_db = max(2, int(0.24 * (budget - wu_s) / (db_s + 1.5) / len(spd)))
    adb = [0.0, math.radians(-3.0), math.radians(-6.0)]
    nLd = int(np.clip(round(n_db / 3), 1, 4))
    Ld = sorted(set(L[i] for i in np.linspace(0, len(L) - 1, nLd).round().astype(int)))
    Ld = [x for x in Ld if x >= 0.3 * Fz0] or [min(L, key=lambda x: abs(x - Fz0))]
    for V in spd:
        for a in adb:
            for Fz in Ld:
                db.append(drivebrake(Fz, p0, 0.0, V, a))

    # both runs must fit: trim the cornering matrix (whole load orders at its end) if needed
    def dur(us):
        return sum(len(u.alpha) * DT + 1.5 for u in us)

    extra_s = (5 * (sweep_s + 1.5) if sidewall else 0.0) + (
        3 * (sweep_s + 1.5) if other_speed_block else 0.0
    )
    while corner and wu_s + dur(corner) + dur(db) + extra_s > budget - 2.0:
        corner.pop()
    blocks = [corner, db] if rng.random() < 0.7 else [db, corner]
    for b in blocks:
        units += b
    # sidewall corner: low pressure, loads up to the top, sweeps a little wider
    if sidewall:
        plow = 0.6 * p0
        hi = [f * Fz0 for f in ((0.6, 1.0, 1.2, 1.4) if variant.kind == "fsae"
                                else (0.75, 1.25, 1.5, 1.75))]  # fmt: skip
        amp = max(A, math.radians(rng.uniform(13.0, 14.0)))
        sw = [sweep(Fz, plow, 0.0, V0, "sidewall corner", amp) for Fz in hi]
        sw += [sweep(hi[-1], p0, 0.0, V0, "high load, nominal pressure", amp)]
        pos = int(rng.integers(1, len(units)))
        units[pos:pos] = sw
    # another speed: a few reference sweeps
    if other_speed_block and not speeds:
        V2 = rng.choice([25.0, 60.0]) / 3.6
        Fr = min(L, key=lambda x: abs(x - Fz0))
        extra = [sweep(Fr, p0, 0.0, V2, "other speed") for _ in range(2)]
        extra.append(drivebrake(Fr, p0, 0.0, V2, math.radians(-3.0), "other speed"))
        pos = int(rng.integers(len(units) // 2, len(units)))
        units[pos:pos] = extra
    # fill: repeated reference sweeps (nominal load, NOMPRES, no camber) and drive/brake
    Fr = min(L, key=lambda x: abs(x - Fz0))
    k = 0
    while True:
        prog = _assemble(units, N, T, t0)
        if prog is not None:
            return prog
        for _ in range(4):
            if k % 3 == 2:
                units.append(drivebrake(Fr, p0, 0.0, V0, math.radians(-3.0), "reference"))
            else:
                Fk = Fr if k % 2 == 0 else L[max(0, len(L) // 2 - 1)]
                units.append(sweep(Fk, p0, 0.0, V0, "reference"))
            k += 1


def _ramp(a, b, n):
    return np.linspace(a, b, n + 1)[1:] if n > 0 else np.zeros(0)


def _assemble(units, N, T, t0) -> Programme | None:
    """The sample arrays of ``units``, cut to N samples; None if they are shorter."""
    cols = {k: [] for k in ("Fz", "kappa", "alpha", "gamma", "V", "pset", "reset", "kind")}
    kinds = {"warmup": 1, "sweep": 2, "drivebrake": 3}
    prev = None
    text = []
    n_tot = 0
    for u in units:
        if prev is not None:
            changes = []
            if abs(u.Fz - prev.Fz) > 1e-6:
                changes.append(1.0 + abs(u.Fz - prev.Fz) / (2.0 * T[ty.FZ0]))
            if abs(u.gamma - prev.gamma) > 1e-9:
                changes.append(1.2)
            if abs(u.p - prev.p) > 1e-6:
                changes.append(2.5)
            if abs(u.V - prev.V) > 1e-6:
                changes.append(abs(u.V - prev.V) / 2.0 + 0.5)
            a_end = float(prev.alpha[-1])
            a_start = float(u.alpha[0])
            if abs(a_end - a_start) > 1e-9:
                changes.append(1.0)
            if changes:
                n = int(round(max(changes) / DT))
                cols["Fz"].append(_ramp(prev.Fz, u.Fz, n))
                cols["gamma"].append(_ramp(prev.gamma, u.gamma, n))
                cols["V"].append(_ramp(prev.V, u.V, n))
                cols["pset"].append(np.full(n, u.p))
                r = np.zeros(n, bool)
                if abs(u.p - prev.p) > 1e-6:
                    r[0] = True
                cols["reset"].append(r)
                # slip angle: back to zero, then to the next unit's start
                h = n // 2
                cols["alpha"].append(np.concatenate([_ramp(a_end, 0.0, h),
                                                     _ramp(0.0, a_start, n - h)]))  # fmt: skip
                cols["kappa"].append(np.zeros(n))
                cols["kind"].append(np.zeros(n, np.int8))
                n_tot += n
        m = len(u.alpha)
        cols["Fz"].append(np.full(m, u.Fz))
        cols["gamma"].append(np.full(m, u.gamma))
        cols["V"].append(np.full(m, u.V))
        cols["pset"].append(np.full(m, u.p))
        r = np.zeros(m, bool)
        if prev is None:
            r[0] = True
        cols["reset"].append(r)
        cols["alpha"].append(u.alpha)
        cols["kappa"].append(u.kappa if u.kappa is not None else np.zeros(m))
        cols["kind"].append(np.full(m, kinds[u.kind], np.int8))
        if n_tot < N:
            what = {"warmup": "warm-up steer", "sweep": "lateral sweep",
                    "drivebrake": "drive/brake sweep"}[u.kind]  # fmt: skip
            extra = (f" at alpha {math.degrees(float(u.alpha[0])):.0f} deg"
                     if u.kind == "drivebrake" else "")  # fmt: skip
            text.append(f"{n_tot * DT:6.1f} s {what}{extra}: Fz {u.Fz:.0f} N, p "
                        f"{u.p / 1000:.0f} kPa, gamma {math.degrees(u.gamma):.0f} deg, "
                        f"V {u.V * 3.6:.0f} km/h {u.note}".rstrip())  # fmt: skip
        n_tot += m
        prev = u
    if n_tot < N:
        return None
    arr = {k: np.concatenate(v)[:N] for k, v in cols.items()}
    t = t0 + np.arange(N) * DT
    return Programme(t=t, Fz=arr["Fz"].astype(float), kappa=arr["kappa"].astype(float),
                     alpha=arr["alpha"].astype(float), gamma=arr["gamma"].astype(float),
                     V=arr["V"].astype(float), pset=arr["pset"].astype(float),
                     reset=arr["reset"].astype(np.bool_), kind=arr["kind"], units=units,
                     text="\n".join(text))  # fmt: skip
