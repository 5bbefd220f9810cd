"""Recording decode rate: ``read_recording`` on a ~100k-message MCAP bag (median of 3).

Target: >= 300k messages/s. The MCAP read includes the CRC checks (data section CRC, else each
chunk's; message indexes against their records). Also prints the write rate, the sqlite3
figure, the salvage scan of an unclosed copy (a killed recorder's file: read record by
record) and, for reference, rosbags' own per-message deserialiser on the same messages.

    .venv/bin/python bench/bench_recording.py [--messages 100000]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from tire_model_ros.recording import cdr, read_raw, read_recording, write_recording
from tire_model_ros.recording.series import WheelSeries

TOPICS_PER_SAMPLE = 6  # slip, load, pressure, temperature, velocity, measured_forces


def make_wheel(n: int) -> WheelSeries:
    rng = np.random.default_rng(0)
    t = 1_700_000_000 + np.arange(n) * 1e-3
    c = lambda: rng.normal(size=n)  # noqa: E731
    return WheelSeries(
        "/rig/wheel",
        t,
        c(),
        c(),
        c(),
        4000 + c(),
        p=2e5 + c(),
        T=30 + c(),
        Vx=10 + c(),
        Fx=c(),
        Fy=c(),
        Fz_meas=c(),
        Mx=c(),
        My=c(),
        Mz=c(),
    )


def timed(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=100_000)
    args = parser.parse_args()
    n = args.messages // TOPICS_PER_SAMPLE
    messages = n * TOPICS_PER_SAMPLE
    w = make_wheel(n)
    with tempfile.TemporaryDirectory() as tmp:
        for storage in ("mcap", "sqlite3"):
            bag = Path(tmp) / storage
            t_write = timed(
                lambda b=bag, s=storage: write_recording(b, [w], storage=s, overwrite=True)
            )
            t_read = timed(lambda b=bag: read_recording(b))
            got = read_recording(bag)["/rig/wheel"]
            assert len(got) == n and np.array_equal(got.Fx, w.Fx)
            print(
                f"{storage:8s} {messages} messages: read_recording {t_read * 1e3:7.1f} ms "
                f"= {messages / t_read / 1e3:7.0f} k messages/s (median of 3); "
                f"write_recording {messages / t_write / 1e3:5.0f} k messages/s"
            )
        data = (Path(tmp) / "mcap" / "mcap.mcap").read_bytes()
        (Path(tmp) / "cut.mcap").write_bytes(data[: len(data) * 9 // 10])  # no footer
        t_scan = timed(lambda: read_raw(Path(tmp) / "cut.mcap", salvage=True))
        found = read_raw(Path(tmp) / "cut.mcap", salvage=True).messages_read
        print(
            f"salvage of an unclosed copy (90 % of the file): {found} messages in "
            f"{t_scan * 1e3:.0f} ms = {found / t_scan / 1e3:.0f} k messages/s (median of 3)"
        )
        raw = read_raw(Path(tmp) / "mcap")
        topic = raw.topics["/rig/wheel/load"]
        k = min(len(topic), 5000)

        def reference() -> None:
            for i in range(k):
                cdr.decode_reference(topic.msgtype, topic.message(i))

        t_ref = timed(reference, 1)
        print(
            f"reference rosbags deserialize_cdr: {k / t_ref / 1e3:.0f} k messages/s "
            f"(WrenchStamped, {k} messages)"
        )


if __name__ == "__main__":
    main()
