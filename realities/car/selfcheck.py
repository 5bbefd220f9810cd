"""Self-check of the 'car' generator: generate a few cases in a temp dir, read them back with
``rosbags`` (not with the project's reader) and print signs, ranges, noise and effect sizes.

    .venv/bin/python -m realities.car.selfcheck [--minutes 2] [--cases a,b,...] [--seed 1]
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader

DEFAULT_CASES = ("relaxation", "offset", "heat_recorded", "pressure_recorded", "null_6")


def read_bag(path):
    """{topic: (stamps_ns, values)} with values per message type as arrays."""
    out = {}
    with AnyReader([Path(path)]) as r:
        for conn, _t, raw in r.messages():
            msg = r.deserialize(raw, conn.msgtype)
            ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            tp = conn.msgtype
            if tp.endswith("Vector3Stamped"):
                v = (msg.vector.x, msg.vector.y, msg.vector.z)
            elif tp.endswith("WrenchStamped"):
                f, m = msg.wrench.force, msg.wrench.torque
                v = (f.x, f.y, f.z, m.x, m.y, m.z)
            elif tp.endswith("FluidPressure"):
                v = (msg.fluid_pressure,)
            elif tp.endswith("Temperature"):
                v = (msg.temperature,)
            elif tp.endswith("TwistStamped"):
                v = (msg.twist.linear.x,)
            else:
                continue
            out.setdefault(conn.topic, ([], []))
            out[conn.topic][0].append(ns)
            out[conn.topic][1].append(v)
    return {k: (np.array(a, np.int64), np.array(b, float)) for k, (a, b) in out.items()}


def check_case(case, seed, minutes, tmp):
    from .generate import generate

    out = Path(tmp) / f"{case}_{seed}"
    t0 = time.time()
    generate(case, seed, out, minutes=minutes, verbose=False)
    dt = time.time() - t0
    truth = json.loads((out / "truth.json").read_text())
    rec = read_bag(out / "recording")
    twin = read_bag(out / "twin")
    problems = []
    print(f"== {case} seed {seed} ({minutes:g} min, {dt:.1f} s): tyre {truth['tyre']}")
    nv = truth["noise"]["force_noise_variance_N2"]
    for e in truth["effects"]:
        note = "  (below the noise variance: a short session)" if e["ms_N2"] < nv else ""
        print(
            f"   effect {e['name']:<16s} concealed={e['concealed']!s:<5s} ms_N2 "
            f"{e['ms_N2']:9.0f} = {e['ms_N2'] / nv:6.1f} x noise variance {nv:.0f} N^2{note}"
        )
    if truth["null"]:
        print("   null; imperfections:", ", ".join(i["kind"] for i in truth["imperfections"]))
    for w in truth["wheels"]:
        need = ("slip", "load", "measured_forces")
        for ch in need:
            if f"{w}/{ch}" not in rec:
                problems.append(f"{w}/{ch} missing in recording")
        for ch in need + ("velocity", "temperature", "pressure"):
            if f"{w}/{ch}" not in twin:
                problems.append(f"{w}/{ch} missing in twin")
        ts, slip = rec[f"{w}/slip"]
        tw, slip_t = twin[f"{w}/slip"]
        if not np.array_equal(ts, tw):
            problems.append(f"{w}: twin slip stamps differ from the recording's")
        if np.any(np.diff(ts) <= 0):
            problems.append(f"{w}: slip stamps not increasing")
        tf, F = twin[f"{w}/measured_forces"]
        # align twin forces to the slip stamps (same stamps)
        idx = np.searchsorted(tf, tw)
        ok = (idx < tf.size) & (tf[np.minimum(idx, tf.size - 1)] == tw)
        Fa = F[np.minimum(idx, tf.size - 1)][ok]
        k, a, g = slip_t[ok, 0], slip_t[ok, 1], slip_t[ok, 2]
        # signs: small-slip slopes (ISO-W: dFx/dkappa > 0, dFy/dalpha < 0)
        sa = (np.abs(a) < math.radians(2)) & (np.abs(k) < 0.02)
        sk = (np.abs(k) < 0.03) & (np.abs(a) < math.radians(1))
        cy = np.polyfit(a[sa], Fa[sa, 1], 1)[0] if sa.sum() > 50 else float("nan")
        cx = np.polyfit(k[sk], Fa[sk, 0], 1)[0] if sk.sum() > 50 else float("nan")
        if not cy < 0:
            problems.append(f"{w}: dFy/dalpha = {cy:.0f} not negative")
        if not cx > 0:
            problems.append(f"{w}: dFx/dkappa = {cx:.0f} not positive")
        # noise: recording - twin on common stamps
        trf, Fr = rec[f"{w}/measured_forces"]
        common, i1, i2 = np.intersect1d(trf, tf, return_indices=True)
        d = Fr[i1] - F[i2]
        sd = np.median(np.abs(d - np.median(d, 0)), 0) * 1.4826
        _, V = twin[f"{w}/velocity"]
        _, Tt = twin[f"{w}/temperature"]
        _, pp = twin[f"{w}/pressure"]
        print(
            f"   {w}: n={ts.size} alpha {math.degrees(a.min()):6.1f}..{math.degrees(a.max()):5.1f}"
            f" deg, kappa {k.min():6.3f}..{k.max():5.3f}, gamma {math.degrees(g.min()):5.1f}.."
            f"{math.degrees(g.max()):4.1f} deg, Fz {Fa[:, 2].min():5.0f}..{Fa[:, 2].max():5.0f} N,"
            f" V {V.min():4.1f}..{V.max():4.1f} m/s, Ttread {Tt.min():5.1f}..{Tt.max():5.1f} C, "
            f"p {pp.min() / 1e3:5.1f}..{pp.max() / 1e3:5.1f} kPa"
        )
        print(
            f"      Cx {cx:9.0f} N, Cy {cy:9.0f} N/rad, noise (robust sd rec-twin) Fx {sd[0]:5.1f}"
            f" Fy {sd[1]:5.1f} Fz {sd[2]:5.1f} N (truth sigma {truth['noise']['Fx_Fy_N']:.1f}"
            f"/{truth['noise']['Fz_N']:.1f})"
        )
        if f"{w}/temperature" in rec:
            print(f"      temperature recorded: {rec[f'{w}/temperature'][0].size} samples")
        if f"{w}/pressure" in rec:
            print(f"      pressure recorded: {rec[f'{w}/pressure'][0].size} samples")
    for p in problems:
        print("   PROBLEM:", p)
    return problems


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=2.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--cases", default=",".join(DEFAULT_CASES))
    a = ap.parse_args(argv)
    allp = []
    with tempfile.TemporaryDirectory(prefix="car_selfcheck_") as tmp:
        for case in a.cases.split(","):
            allp += check_case(case, a.seed, a.minutes, tmp)
    print("selfcheck:", "OK" if not allp else f"{len(allp)} problem(s)")
    return 1 if allp else 0


if __name__ == "__main__":
    raise SystemExit(main())
