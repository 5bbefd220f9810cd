"""Self-check of the flattrac generator (no diagnosis involved).

Generates a few cases in a temporary directory, reads the bags back with ``rosbags`` (not with
the project's reader) and prints: topics and counts, ISO-W signs (dFx/dkappa > 0, dFy/dalpha < 0
at small slip), ranges, the noise (recording - twin) against truth.json, the effect sizes, and
how well model.tir (evaluated with ``tire_model_ros.model``) explains the twin: on a null the
twin must be reproduced to a fraction of a newton, elsewhere the residual is the effects.

    .venv/bin/python -m realities.flattrac.selfcheck [--cases a,b,...] [--minutes M] [--seed N]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

DEFAULT_CASES = ("null_6", "heat_cross", "delay", "camber", "sidewall", "multi3")


def read_bag(path) -> dict:
    """{channel: (stamps [int ns], values)} of the /rig/wheel topics, read with rosbags."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    data: dict = {}
    with Reader(Path(path)) as r:
        for conn, _, raw in r.messages():
            msg = ts.deserialize_cdr(raw, conn.msgtype)
            ch = conn.topic.rsplit("/", 1)[1]
            t = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec  # exact ns
            if ch == "slip":
                v = (msg.vector.x, msg.vector.y, msg.vector.z)
            elif ch in ("load",):
                v = msg.wrench.force.z
            elif ch == "measured_forces":
                f, m = msg.wrench.force, msg.wrench.torque
                v = (f.x, f.y, f.z, m.x, m.y, m.z)
            elif ch == "pressure":
                v = msg.fluid_pressure
            elif ch == "temperature":
                v = msg.temperature
            elif ch == "velocity":
                v = msg.twist.linear.x
            else:
                continue
            data.setdefault(ch, ([], []))
            data[ch][0].append(t)
            data[ch][1].append(v)
    return {k: (np.array(t, np.int64), np.array(v, float)) for k, (t, v) in data.items()}


def latest(t_ref, t, v):
    """Latest value at or before each reference stamp (first value before the start)."""
    i = np.searchsorted(t, t_ref, side="right") - 1  # integer ns stamps: exact
    return v[np.clip(i, 0, len(t) - 1)]


def check_case(case, seed, minutes, root) -> bool:
    from tire_model_ros.model import TireModel

    from .make import generate

    out = Path(root) / f"{case}_{seed}"
    t0 = time.time()
    generate(case, seed, out, minutes=minutes, quiet=True)
    dt_gen = time.time() - t0
    truth = json.loads((out / "truth.json").read_text())
    rec = read_bag(out / "recording")
    twin = read_bag(out / "twin")
    ok = True
    print(f"\n== {case} seed {seed}: {truth['tyre']}  ({dt_gen:.1f} s)")
    print("   recording topics: " + ", ".join(f"{k} {len(v[0])}" for k, v in sorted(rec.items())))
    print("   twin topics:      " + ", ".join(f"{k} {len(v[0])}" for k, v in sorted(twin.items())))
    same = np.array_equal(rec["slip"][0], twin["slip"][0])
    print(f"   slip stamps identical in recording and twin: {same}")
    ok &= same
    ts, slip = twin["slip"]
    F = latest(ts, *twin["measured_forces"])
    k, a, g = slip.T
    Fx, Fy = F[:, 0], F[:, 1]
    # ISO-W signs from the twin near pure slip: slopes at small slip
    m = (np.abs(a) < 1.5 * np.pi / 180) & (np.abs(k) < 0.002) & (np.abs(g) < 1e-6)
    sy = np.polyfit(a[m], Fy[m], 1)[0] if m.sum() > 50 and np.ptp(a[m]) > 0.005 else np.nan
    m2 = (np.abs(k) < 0.02) & (np.abs(a) < 1e-6)
    sx = np.polyfit(k[m2], Fx[m2], 1)[0] if m2.sum() > 50 and np.ptp(k[m2]) > 0.005 else np.nan
    sign_ok = (np.isnan(sy) or sy < 0) and (np.isnan(sx) or sx > 0)
    print(f"   signs: dFy/dalpha = {sy:.0f} N/rad (<0), dFx/dkappa = {sx:.0f} N (>0): "
          f"{'ok' if sign_ok else 'WRONG'}")  # fmt: skip
    ok &= bool(sign_ok)
    Fz = twin["load"][1]
    print(f"   ranges: kappa {k.min():+.3f}..{k.max():+.3f}, alpha {np.degrees(a.min()):+.1f}.."
          f"{np.degrees(a.max()):+.1f} deg, gamma {np.degrees(g.min()):.1f}..{np.degrees(g.max()):.1f}"
          f" deg, Fz {Fz.min():.0f}..{Fz.max():.0f} N, Fx {Fx.min():.0f}..{Fx.max():.0f} N, "
          f"Fy {Fy.min():.0f}..{Fy.max():.0f} N")  # fmt: skip
    V = latest(ts, *twin["velocity"])
    p = latest(ts, *twin["pressure"])
    T = latest(ts, *twin["temperature"])
    print(f"   V {V.min():.1f}..{V.max():.1f} m/s, p {p.min() / 1e3:.1f}..{p.max() / 1e3:.1f} kPa, "
          f"tread {T.min():.1f}..{T.max():.1f} C")  # fmt: skip
    # noise: recording minus twin at the same stamps (robust sigma, spikes excluded)
    tr, Fr = rec["measured_forces"]
    Ft = latest(tr, *twin["measured_forces"])
    d = Fr - Ft
    mad = 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    nz = truth["noise"]
    print(f"   noise Fx {mad[0]:.1f} N (truth {nz['Fx_N']:.1f}), Fy {mad[1]:.1f} N (truth "
          f"{nz['Fy_N']:.1f}), Mz {mad[5]:.2f} N m; noise var Fx+Fy {nz['var_FxFy_N2']:.0f} N^2")  # fmt: skip
    # model.tir against the twin (true inputs): the residual is the effects
    mt = TireModel.from_file(out / "model.tir")
    o = mt.evaluate(Fz, k, a, g, V, p if "pressure" in rec or truth["pressure_mode"] in
                    ("regulated", "setpoints") else None, full=False)  # fmt: skip
    r2 = (Fx - o.Fx) ** 2 + (Fy - o.Fy) ** 2
    print(f"   model.tir vs twin: mean (dFx^2 + dFy^2) = {r2.mean():.2f} N^2")
    for e in truth["effects"]:
        print(f"   effect {e['name']:<17} concealed={e['concealed']!s:<5} ms={e['ms_N2']:9.1f} "
              f"N^2 = {e['ms_N2'] / nz['var_FxFy_N2']:.1f}x noise var")  # fmt: skip
    if truth["null"]:
        good = r2.mean() < 0.05 * nz["var_FxFy_N2"]
        print(f"   null: model.tir reproduces the twin: {'ok' if good else 'NO'}; "
              f"imperfections {[i['kind'] for i in truth['imperfections']]}")  # fmt: skip
        ok &= bool(good)
    else:
        eff = truth["effects"]
        vis = all(e["ms_N2"] >= 1.0 * nz["var_FxFy_N2"] for e in eff)
        ratio = len(eff) < 2 or eff[0]["ms_N2"] >= 2.0 * eff[1]["ms_N2"]
        print(f"   every effect >= 1x noise var: {vis}; first >= 2x second: {ratio}")
        ok &= vis and ratio
        if len(eff) == 1:  # a single effect: model.tir's residual on the twin is that effect
            match = abs(r2.mean() - eff[0]["ms_N2"]) <= 0.05 * eff[0]["ms_N2"]
            print(f"   residual of model.tir on the twin equals ms_N2 (5 %): {match}")
            ok &= bool(match)
    return ok


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", default=",".join(DEFAULT_CASES))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--minutes", type=float, default=8.0)
    a = ap.parse_args(argv)
    cases = [c for c in a.cases.split(",") if c]
    with tempfile.TemporaryDirectory(prefix="flattrac_selfcheck_") as root:
        results = {c: check_case(c, a.seed, a.minutes, root) for c in cases}
    print("\nselfcheck: " + ", ".join(f"{c} {'ok' if v else 'FAIL'}" for c, v in results.items()))
    return 0 if all(results.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
