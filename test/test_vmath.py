"""The vectorisable maths of the evaluator against libm (numpy) over the double range."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from tire_model_ros.model import vmath as vm

SPECIAL = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, -5e-324, 1e-310,
                    2.2250738585072014e-308, 1.0, -1.0, 0.5, 709.78, 709.79, -708.5, -745.1,
                    -745.2, 1.7976931348623157e308])  # fmt: skip


def _loop(f):
    @njit
    def run(x, y):
        for i in range(x.shape[0]):
            y[i] = f(x[i])

    return run


def _ulp_error(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    same = (got == want) | (np.isnan(got) & np.isnan(want))
    with np.errstate(invalid="ignore", over="ignore"):
        err = np.abs(got - want) / np.spacing(np.abs(want))
    return np.where(same, 0.0, err)


def _samples(name: str) -> np.ndarray:
    rng = np.random.default_rng(7)
    wide = rng.standard_normal(100_000) * 10.0 ** rng.uniform(-300, 300, 100_000)
    small = rng.uniform(-7.0, 7.0, 100_000)
    special = SPECIAL
    if name in ("sin", "cos", "tan"):  # the accurate range of the Cody-Waite reduction
        wide = wide[np.abs(wide) < 1e8]
        special = special[~(np.abs(special) > 1e8)]
    if name == "exp":
        wide = rng.uniform(-750.0, 712.0, 100_000)
    if name == "log":
        wide, small = np.abs(wide), np.abs(small)
    return np.concatenate([small, wide, special])


@pytest.mark.parametrize(
    ("name", "max_ulp"),
    [("atan", 2), ("sin", 2), ("cos", 2), ("tan", 4), ("exp", 1), ("log", 2)],
)
def test_matches_libm_within_a_few_ulp(name: str, max_ulp: float) -> None:
    x = _samples(name)
    got = np.empty_like(x)
    _loop(getattr(vm, name))(x, got)
    with np.errstate(all="ignore"):
        want = getattr(np, "arctan" if name == "atan" else name)(x)
    err = _ulp_error(got, want)
    assert err.max() <= max_ulp, (name, x[err.argmax()], got[err.argmax()], want[err.argmax()])


def test_sin_cos_stay_bounded_beyond_the_reduction_range() -> None:
    x = np.array([1e9, -3e15, 1e300, 1.7976931348623157e308])
    s, c = np.empty_like(x), np.empty_like(x)
    _loop(vm.sin)(x, s)
    _loop(vm.cos)(x, c)
    assert np.all(np.abs(s) <= 1.0) and np.all(np.abs(c) <= 1.0)


@njit
def _pow_loop(x, y, out):
    for i in range(x.shape[0]):
        out[i] = vm.pow(x[i], y[i])


def test_pow_matches_libm_and_its_special_cases() -> None:
    rng = np.random.default_rng(3)
    x_special = [0.0, 0.0, -2.0, -2.0, -2.0, 1.0, np.nan, np.nan, np.inf, -np.inf, 2.0]
    y_special = [0.0, -1.0, 3.0, 2.0, 0.5, np.nan, 0.0, 1.0, -1.0, 2.0, np.inf]
    x = np.concatenate([rng.uniform(0.0, 3.0, 50_000), x_special])
    y = np.concatenate([rng.uniform(-3.0, 3.0, 50_000), y_special])
    got = np.empty_like(x)
    _pow_loop(x, y, got)
    with np.errstate(all="ignore"):
        want = np.power(x, y)
    # exp(y log x): the rounding of y log x (|y log x| < 4 here) costs up to ~20 ulp
    assert _ulp_error(got, want).max() <= 32


@njit
def _fma(a, b, c):
    return vm.fma(a, b, c)


def test_fma_rounds_once() -> None:
    # (1 + 2^-30)^2 - (1 + 2^-29) = 2^-60 exactly; a multiply then an add rounds it to 0
    a = 1.0 + 2.0**-30
    assert _fma(a, a, -(1.0 + 2.0**-29)) == 2.0**-60
    assert a * a - (1.0 + 2.0**-29) == 0.0
