"""Benchmark of the Magic Formula evaluator against the targets of the Foundation issue.

- batch: combined-slip Fx, Fy, Mz (with Mx, My) for 1e6 samples on one core, median of runs,
  target >= 5 million evaluations per second;
- single sample: ``TireModel.evaluate_one`` as the node calls it, median, target <= 20 us.

Run: ``NUMBA_NUM_THREADS=1 .venv/bin/python bench/bench_model.py [--tir FILE] [--runs N]
[--stages]``. Both wall-clock and process CPU time are printed: on a shared machine the CPU time
is the fairer figure for one core. ``--stages`` also times each stage loop of the batch kernel
on its own (CPU ns per sample, over 100 blocks of the same inputs): where the time goes.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

DEFAULT_TIR = (
    Path(__file__).resolve().parents[1]
    / ".."
    / "shared"
    / "reference"
    / "tir"
    / "MagicFormula61_Parameters.tir"
).resolve()


def _median_time(fn, runs: int) -> tuple[float, float]:
    wall, cpu = [], []
    for _ in range(runs):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    return float(np.median(wall)), float(np.median(cpu))


def _stage_times(model, inputs, runs: int) -> None:
    """Print each stage loop's CPU time per sample (limits on), called block by block."""
    from tire_model_ros.model import kernel as k

    P, B = model.coefficient_vector, k.BLOCK
    nb = 100
    Fz, kappa, alpha, gamma, Vx, p, T = (a[: nb * B].copy() for a in inputs)
    phit = np.zeros(nb * B)
    mf52 = k.is_mf52(P)
    stages = {
        "conditions": lambda i0, s: k._conditions_stage(
            P, Fz, kappa, alpha, gamma, Vx, p, T, phit, True, i0, B
        ),
        "longitudinal": lambda i0, s: k._longitudinal_stage(P, Vx, True, i0, B, s),
        "lateral": lambda i0, s: k._lateral_stage(P, True, mf52, B, s),
        "lateral_zero_camber": lambda i0, s: k._lateral_zero_camber_stage(P, True, mf52, B, s),
        "combined": lambda i0, s: k._combined_stage(P, True, B, s),
        "aligning": lambda i0, s: k._aligning_stage(P, Vx, True, mf52, i0, B, s),
        "moments": lambda i0, s: k._moments_stage(P, kappa, Vx, mf52, i0, B, s),
    }
    rows = (k.COND_ROWS, k.LONG_ROWS, k.LAT_ROWS, k.LAT_G0_ROWS, k.COMB_ROWS, k.MZ_ROWS,
            k.MOM_ROWS)  # fmt: skip
    scratch = []  # each block's scratch after all stages: the inputs every stage reads
    for b in range(nb):
        s = np.empty((k.N_SCRATCH, B))
        for f, r in zip(stages.values(), rows, strict=True):
            k._keep(s, r, f(b * B, s), B)
        scratch.append(s)
    total = 0.0
    for name, f in stages.items():
        _, cpu = _median_time(lambda f=f: [f(b * B, scratch[b]) for b in range(nb)], runs)
        total += cpu / (nb * B) * 1e9
        print(f"  stage {name}: {cpu / (nb * B) * 1e9:.1f} ns/sample CPU")
    print(
        f"  stages together: {total:.1f} ns/sample ({1e3 / total:.2f} M/s; with a Python call per "
        f"block, without the copies between blocks)"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tir", default=str(DEFAULT_TIR))
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("-n", type=int, default=1_000_000)
    ap.add_argument("--stages", action="store_true", help="also time each stage loop")
    ap.add_argument(
        "--variants",
        action="store_true",
        help="also time the turn-slip and alpha* loops (compiled on first use)",
    )
    args = ap.parse_args()

    t0 = time.perf_counter()
    from tire_model_ros.model import TireModel

    model = TireModel.from_file(args.tir)
    t1 = time.perf_counter()
    model.evaluate(4000.0, 0.0, 0.0)
    model.evaluate(4000.0, 0.0, 0.0, full=False)
    model.evaluate_one(4000.0, 0.0, 0.0, 0.0, 16.0, 2.5e5, 25.0)
    t2 = time.perf_counter()
    print(f"import + read_tir: {t1 - t0:.2f} s; first calls (compile or cache): {t2 - t1:.2f} s")

    rng = np.random.default_rng(0)
    n = args.n
    P = model.params
    Fz = rng.uniform(0.3, 1.8, n) * P["FNOMIN"]
    kappa = rng.uniform(-0.3, 0.3, n)
    alpha = rng.uniform(-0.25, 0.25, n)
    gamma = rng.uniform(-0.06, 0.06, n)
    Vx = rng.uniform(5.0, 40.0, n)
    p = rng.uniform(0.8, 1.2, n) * P["NOMPRES"]
    T = rng.uniform(10.0, 90.0, n)

    for label, kw in (
        ("forces+moments (full=False)", {"full": False}),
        ("forces alone (full=False, moments=False)", {"full": False, "moments": False}),
        ("all outputs (full=True)", {"full": True}),
    ):
        wall, cpu = _median_time(
            lambda kw=kw: model.evaluate(Fz, kappa, alpha, gamma, Vx, p, T, **kw), args.runs
        )
        target = " (target >= 5 M/s)" if kw == {"full": False} else ""  # on the forces+moments
        print(f"batch {label}: {n / wall / 1e6:.2f} M/s wall, {n / cpu / 1e6:.2f} M/s CPU{target}")

    if args.stages:
        _stage_times(model, (Fz, kappa, alpha, gamma, Vx, p, T), args.runs)
    if args.variants:
        phit = rng.uniform(-0.3, 0.3, n)
        for label, kw in (
            ("plain", {}),
            ("turn_slip", {"turn_slip": True}),
            ("alpha_star", {"alpha_star": True}),
        ):
            model.evaluate(4000.0, 0.0, 0.0, full=False, **kw)  # compile or load first
            wall, cpu = _median_time(
                lambda kw=kw: model.evaluate(
                    Fz, kappa, alpha, gamma, Vx, p, T, phit=phit, full=False, **kw
                ),
                args.runs,
            )
            print(f"batch forces+moments, {label}: {n / cpu / 1e6:.2f} M/s CPU")

    m = 20000
    idx = rng.integers(0, n, m)
    one = model.evaluate_one
    samples = [(Fz[i], kappa[i], alpha[i], gamma[i], Vx[i], p[i], T[i]) for i in idx]
    times = []
    for s in samples:
        c0 = time.perf_counter()
        one(*s)
        times.append(time.perf_counter() - c0)
    print(
        f"evaluate_one: median {np.median(times) * 1e6:.2f} us, "
        f"99th percentile {np.percentile(times, 99) * 1e6:.2f} us (target <= 20 us)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
