"""Synthetic WheelSeries for the recording tests: every channel filled, exact ns stamps."""

from __future__ import annotations

import numpy as np

from tire_model_ros.recording import WheelSeries
from tire_model_ros.vocabulary import NS_PER_S as NS
from tire_model_ros.vocabulary import SERIES_CHANNELS

T0 = 1_700_000_000 * NS  # a realistic epoch: float seconds cannot hold these to the ns


def random_wheel(prefix="/rig/wheel", n=200, *, p=True, T=True, Vx=True, seed=0, t0_ns=T0,
                 dt_ns=1_000_000) -> WheelSeries:  # fmt: skip
    """``n`` samples of random values; stamps every ``dt_ns`` with sub-us jitter."""
    rng = np.random.default_rng(seed)
    t_ns = t0_ns + np.arange(n, dtype=np.int64) * dt_ns + rng.integers(0, 999, n)
    col = lambda: rng.normal(size=n)  # noqa: E731
    return WheelSeries(
        prefix, t_ns / NS, col(), col(), col(), 4000 + col(),
        p=2e5 + col() if p else None, T=30 + col() if T else None,
        Vx=10 + col() if Vx else None,
        Fx=col(), Fy=col(), Fz_meas=4000 + col(), Mx=col(), My=col(), Mz=col(),
        meta={"t_ns": t_ns},
    )  # fmt: skip


def assert_same(a: WheelSeries, b: WheelSeries) -> None:
    """Same prefix, identical ns stamps, and every channel bit-identical (or both absent)."""
    assert a.prefix == b.prefix
    np.testing.assert_array_equal(a.meta["t_ns"], b.meta["t_ns"])
    for name in SERIES_CHANNELS:
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=name)
