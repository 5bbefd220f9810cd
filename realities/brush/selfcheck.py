"""Self-check: generate a few cases in a temp dir, read them back with rosbags, print sizes.

    .venv/bin/python -m realities.brush.selfcheck [--cases c1,c2,...] [--minutes M] [--seed N]

Reads the bags with ``rosbags`` (not the project's reader), then checks: the topics and
stamps (twin slip stamps == recording slip stamps), ISO-W signs (positive kappa -> positive
Fx, positive alpha -> negative Fy, positive gamma -> negative Fy at alpha = 0), the force and
load ranges, the noise (recording - twin), truth.json's fields and each effect's ms_N2
against the force noise variance; model.tir is read back with read_tir. No diagnosis.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from tire_model_ros.model import TireModel

from . import cases

DEFAULT = ["null_1", "heat_above", "relaxation", "offset", "combined", "multi2_a"]


def read_bag(path: Path) -> dict:
    ts = get_typestore(Stores.ROS2_JAZZY)
    out: dict = {}
    with Reader(path) as r:
        for conn, _t, raw in r.messages():
            msg = ts.deserialize_cdr(raw, conn.msgtype)
            st = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            ch = conn.topic.rsplit("/", 1)[1]
            if ch == "slip":
                v = (msg.vector.x, msg.vector.y, msg.vector.z)
            elif ch in ("load",):
                v = (msg.wrench.force.z,)
            elif ch == "measured_forces":
                w = msg.wrench
                v = (w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z)
            elif ch == "pressure":
                v = (msg.fluid_pressure,)
            elif ch == "temperature":
                v = (msg.temperature,)
            elif ch == "velocity":
                v = (msg.twist.linear.x,)
            else:
                continue
            out.setdefault(conn.topic, ([], []))
            out[conn.topic][0].append(st)
            out[conn.topic][1].append(v)
    return {k: (np.array(t), np.array(v)) for k, (t, v) in out.items()}


def align(ts, t, v):
    """Latest value at or before each stamp of ts."""
    i = np.searchsorted(t, ts + 1e-7, side="right") - 1
    return v[np.clip(i, 0, len(v) - 1)]


def check(outdir: Path) -> bool:
    ok = True
    truth = json.loads((outdir / "truth.json").read_text())
    rec = read_bag(outdir / "recording")
    twin = read_bag(outdir / "twin")
    P = truth["wheels"][0]
    tm = TireModel.from_file(outdir / "model.tir")
    print(f"== {truth['case']} (seed {truth['seed']}), tyre {truth['tyre'].split(':')[0]}")
    print("   recording topics:", {k.rsplit("/", 1)[1]: len(v[0]) for k, v in rec.items()})
    print("   twin topics:     ", {k.rsplit("/", 1)[1]: len(v[0]) for k, v in twin.items()})
    for need in ("slip", "load", "measured_forces"):
        if f"{P}/{need}" not in rec:
            print(f"   FAIL: recording lacks {need}")
            ok = False
    for need in ("slip", "load", "measured_forces", "pressure", "temperature", "velocity"):
        if f"{P}/{need}" not in twin:
            print(f"   FAIL: twin lacks {need}")
            ok = False
    ts_r = rec[f"{P}/slip"][0]
    ts_t, slip = twin[f"{P}/slip"]
    if len(ts_r) != len(ts_t) or np.max(np.abs(ts_r - ts_t)) > 1e-9:
        print("   FAIL: twin slip stamps differ from the recording's")
        ok = False
    tf, F = twin[f"{P}/measured_forces"]
    F = align(ts_t, tf, F)
    Fz = align(ts_t, *twin[f"{P}/load"])[:, 0]
    k, a, g = slip[:, 0], slip[:, 1], slip[:, 2]
    # signs (ISO-W): drive/brake at alpha = 0, sweeps at small slip, camber at alpha = 0
    m = (np.abs(a) < 1e-4) & (np.abs(k) > 0.02) & (np.abs(k) < 0.08)
    if m.sum() > 10:
        c = np.corrcoef(k[m], F[m, 0])[0, 1]
        print(f"   sign kappa->Fx: corr {c:+.3f}", "ok" if c > 0.9 else "FAIL")
        ok &= c > 0.9
    m = (np.abs(k) < 1e-6) & (np.abs(a) > math.radians(0.5)) & (np.abs(a) < math.radians(2))
    m &= np.abs(g) < 1e-3
    if m.sum() > 10:
        c = np.corrcoef(a[m], F[m, 1] / Fz[m])[0, 1]
        print(f"   sign alpha->Fy: corr {c:+.3f}", "ok" if c < -0.9 else "FAIL")
        ok &= c < -0.9
    Mzs = np.sign(a[m]) * F[m, 5] if m.sum() > 10 else np.array([0.0])
    print(
        f"   aligning moment at small alpha: mean sign(alpha) Mz = {Mzs.mean():+.1f} N m "
        "(positive: aligning)"
    )
    m0 = (np.abs(k) < 1e-6) & (np.abs(a) < math.radians(0.05))
    for gdeg in (0, 2, 4):
        mm = m0 & (np.abs(g - math.radians(gdeg)) < 1e-4)
        if mm.sum() > 5:
            print(
                f"   Fy at alpha~0, gamma {gdeg} deg: {np.mean(F[mm, 1]):+7.1f} N "
                f"({100 * np.mean(F[mm, 1] / Fz[mm]):+.2f} % Fz)"
            )
    print(
        f"   ranges: Fz {Fz.min():.0f}..{Fz.max():.0f} N, Fx {F[:, 0].min():.0f}.."
        f"{F[:, 0].max():.0f}, Fy {F[:, 1].min():.0f}..{F[:, 1].max():.0f}, Mz "
        f"{F[:, 5].min():.1f}..{F[:, 5].max():.1f} N m, alpha {np.degrees(a.min()):.1f}.."
        f"{np.degrees(a.max()):.1f} deg, kappa {k.min():.3f}..{k.max():.3f}"
    )
    mu = np.max(np.abs(F[:, 1]) / np.maximum(Fz, 1.0))
    print(f"   peak |Fy|/Fz {mu:.2f}")
    # noise: recording - twin at the recording's force stamps
    trf, Fr = rec[f"{P}/measured_forces"]
    Ft = align(trf, tf, twin[f"{P}/measured_forces"][1])
    res = Fr - Ft
    nvar = truth["noise"]["force_noise_variance_N2"]
    est = np.var(res[:, 0]) + np.var(res[:, 1])
    print(
        f"   force noise variance: truth {nvar:.0f} N2, recording - twin {est:.0f} N2"
        " (includes the imperfections)"
    )
    # model.tir against the twin (steady state; large where the case's physics is missing)
    p = align(ts_t, *twin[f"{P}/pressure"])[:, 0]
    V = align(ts_t, *twin[f"{P}/velocity"])[:, 0]
    o = tm.evaluate(Fz, k, a, g, V, p, full=False)
    r2 = np.mean((o.Fx - F[:, 0]) ** 2 + (o.Fy - F[:, 1]) ** 2)
    print(f"   model.tir vs twin: mean (dFx^2 + dFy^2) = {r2:.0f} N2 = {r2 / nvar:.1f} x noise")
    for e in truth["effects"]:
        print(
            f"   effect {e['name']:<16} concealed {e['concealed']!s:<5} ms {e['ms_N2']:9.0f} N2"
            f" = {e['ms_N2'] / nvar:6.1f} x noise"
        )
        if e["ms_N2"] < 0.8 * nvar:
            print("   WARNING: effect below the noise variance")
    if truth["effects"]:
        ms = [e["ms_N2"] for e in truth["effects"]]
        if truth["case"].startswith("multi") and ms[0] < 2.0 * ms[1]:
            print("   FAIL: first effect is not twice the second")
            ok = False
    for key in (
        "generator",
        "case",
        "seed",
        "minutes",
        "wheels",
        "null",
        "effects",
        "imperfections",
        "tyre",
        "noise",
        "programme",
        "description",
    ):
        if key not in truth:
            print(f"   FAIL: truth.json lacks {key}")
            ok = False
    print(
        "   imperfections:",
        [i["kind"] for i in truth["imperfections"]] or "none",
        "| topics recorded:",
        sorted(k.rsplit("/", 1)[1] for k in rec),
    )
    return ok


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", default=",".join(DEFAULT))
    ap.add_argument("--minutes", type=float, default=3.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep", help="write the cases here instead of a temp dir")
    a = ap.parse_args(argv)
    base = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="brush_selfcheck_"))
    ok = True
    for case in a.cases.split(","):
        t0 = time.time()
        out = base / case
        cases.generate(case, a.seed, str(out), a.minutes, quiet=True)
        dt = time.time() - t0
        ok &= check(out)
        print(f"   generated in {dt:.1f} s")
    print("selfcheck", "passed" if ok else "FAILED", f"({base})")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
