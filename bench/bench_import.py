"""Import rate: a TTC-style cornering session of the virtual rig written in each measurement
format (TTC .mat and .dat, TYDEX, CSV), read back by ``import_file`` (parse, units, axes, NaN
rows, sign checks) and written as an MCAP bag; best of 3 per format.

Target: a TTC run file (about 10^5 rows) in a few seconds.

    .venv/bin/python bench/bench_import.py [--rate 100]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

from tire_model_ros.importers import FORMATS, import_file
from tire_model_ros.recording import write_recording
from tire_model_ros.rig import simulate_session
from tire_model_ros.wheel.params import default_tir_path

SUFFIX = {"ttc": (".mat", ".dat"), "tydex": (".tdx",), "csv": (".csv",)}


def best_of(n: int, fn: Callable[[], object]) -> float:
    """Shortest wall time [s] of ``n`` calls of ``fn``."""
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=100.0, help="sample rate [Hz]")
    args = parser.parse_args()
    wheels, _ = simulate_session(default_tir_path(), "ttc_cornering", rate_hz=args.rate, seed=1)
    series = wheels[0]
    n = len(series)
    print(f"TTC-style cornering session: {n} rows, {series.t[-1] - series.t[0]:.0f} s")
    print(f"{'file':<10} {'MB':>6} {'read [s]':>9} {'rows/s':>10} {'bag [s]':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        for fmt in FORMATS:
            for suffix in SUFFIX[fmt.name]:
                path = Path(tmp) / f"run{suffix}"
                fmt.write(series, path)
                read = best_of(3, partial(import_file, path))
                got = import_file(path).series
                bag = Path(tmp) / f"bag{suffix.strip('.')}"
                t_bag = best_of(1, partial(write_recording, bag, [got]))
                mb = path.stat().st_size / 1e6
                print(f"{path.name:<10} {mb:6.1f} {read:9.2f} {n / read:10.3g} {t_bag:8.2f}")


if __name__ == "__main__":
    main()
