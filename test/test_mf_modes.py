"""The useMode variants of the evaluator: turn slip (``turn_slip``) and alpha* (``alpha_star``).

The oracle comparison is in test_mf_oracle.py; here: the switches leave the plain path alone,
the limit the evaluator takes where MFeval's Mz is 0/0, the complex branch of zeta7, .tir
reading of the turn-slip coefficients, broadcasting and NaN isolation.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
import pytest
from conftest import MF61_TIR, requires_reference

from tire_model_ros.model import TireModel
from tire_model_ros.model.turnslip import residual_cos

pytestmark = requires_reference
FORCES = ("Fx", "Fy", "Mx", "My", "Mz", "Mzr", "t", "Kya", "muy")


def _grid():
    rng = np.random.default_rng(3)
    n = 700  # more than one block of the kernels
    return dict(
        Fz=rng.uniform(500.0, 12000.0, n), kappa=rng.uniform(-0.3, 0.3, n),
        alpha=rng.uniform(-0.3, 0.3, n), gamma=rng.uniform(-0.1, 0.1, n),
        Vx=rng.uniform(-5.0, 35.0, n), p=rng.uniform(1.8e5, 3.2e5, n),
        phit=rng.uniform(-0.3, 0.3, n),
    )  # fmt: skip


def _eval(model, g, **kw):
    return model.evaluate(g["Fz"], g["kappa"], g["alpha"], g["gamma"], g["Vx"], g["p"],
                          phit=g["phit"], **kw)  # fmt: skip


def test_phit_is_ignored_without_turn_slip(model) -> None:
    g = _grid()
    for limits in (True, False):
        a = _eval(model, g, limits=limits)
        b = _eval(model, dict(g, phit=np.zeros_like(g["phit"])), limits=limits)
        c = _eval(model, g, limits=limits, turn_slip=False, alpha_star=False)
        for name in ("Fx", "Fy", "Mz", "Mx", "My", "Re", "omega", "Rl", "sigmay"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
            np.testing.assert_array_equal(getattr(a, name), getattr(c, name), err_msg=name)


@pytest.mark.parametrize("limits", [True, False])
def test_turn_slip_changes_the_forces_and_is_smooth_through_phit_zero(model, limits) -> None:
    """Mz is finite at phit = 0 (the limit phit -> 0, where MFeval has 0/0) and continuous."""
    args = (6752.0, 0.05, np.array([-0.1, 0.0, 0.05, 0.17]), 0.07, 16.6, 2.6e5)
    zero = model.evaluate(*args, phit=0.0, limits=limits, turn_slip=True)
    for name in FORCES:
        assert np.all(np.isfinite(getattr(zero, name))), name
    for h in (1e-9, -1e-9):
        near = model.evaluate(*args, phit=h, limits=limits, turn_slip=True)
        for name in ("Fx", "Fy", "Mz", "Mzr"):
            np.testing.assert_allclose(getattr(near, name), getattr(zero, name), rtol=1e-6,
                                       atol=1e-4, err_msg=name)  # fmt: skip
    turning = model.evaluate(*args, phit=0.1, limits=limits, turn_slip=True)
    plain = model.evaluate(*args, phit=0.1, limits=limits)
    assert np.all(np.abs(turning.Fy - plain.Fy) > 10.0)  # phit 0.1 1/m: a clear effect
    assert np.all(np.abs(turning.Mz - plain.Mz) > 1.0)


def test_turn_slip_without_spin_keeps_the_forces(model) -> None:
    """phit = 0 and gamma = 0 give phi = 0: every zeta is 1 (zeta4 too), Fx, Fy as without
    turn slip; only Mzr keeps zeta7 < 1 (its limit at phit -> 0) and zeta0 = 0."""
    g = _grid()
    g = dict(g, gamma=np.zeros_like(g["gamma"]), phit=np.zeros_like(g["phit"]),
             Vx=np.abs(g["Vx"]) + 5.0)  # fmt: skip
    a = _eval(model, g, limits=False, turn_slip=True)
    b = _eval(model, g, limits=False)
    for name in ("Fx", "Fy", "Mx", "Kya", "muy", "t"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-12, atol=1e-9,
                                   err_msg=name)  # fmt: skip


def test_residual_cos_is_the_real_part_of_the_complex_form() -> None:
    """cos(zeta7 atan x) with zeta7 = (2/pi) acos(ratio): MFeval's complex acos above 1."""
    for ratio in (-3.0, -1.5, -1.0, -0.4, 0.0, 0.004, 0.7, 1.0, 1.3, 4.0):
        for x in (-20.0, -1.0, -0.1, 0.0, 0.3, 2.0, 50.0):
            zeta7 = 2.0 / math.pi * cmath.acos(ratio)
            want = cmath.cos(zeta7 * math.atan(x)).real
            assert residual_cos(ratio, x) == pytest.approx(want, rel=1e-12, abs=1e-14)
    assert math.isnan(residual_cos(math.nan, 1.0))


def test_variants_short_and_full_outputs_agree(model) -> None:
    g = _grid()
    for kw in (dict(turn_slip=True), dict(alpha_star=True), dict(turn_slip=True, alpha_star=True)):
        full = _eval(model, g, limits=True, **kw)
        short = _eval(model, g, limits=True, full=False, **kw)
        for name in FORCES:
            np.testing.assert_array_equal(getattr(full, name), getattr(short, name))


def test_alpha_star_matches_alpha_at_small_angles(model) -> None:
    """tan(alpha) ~ alpha, sin(gamma) ~ gamma: the variant is a small change there."""
    alpha = np.linspace(-1e-3, 1e-3, 9)
    a = model.evaluate(5000.0, 0.0, alpha, 1e-3, 20.0, 2.6e5, limits=False, alpha_star=True)
    b = model.evaluate(5000.0, 0.0, alpha, 1e-3, 20.0, 2.6e5, limits=False)
    np.testing.assert_allclose(a.Fy, b.Fy, rtol=1e-5, atol=1e-3)
    big = model.evaluate(5000.0, 0.0, 0.3, 0.0, 20.0, 2.6e5, limits=False, alpha_star=True)
    assert abs(float(big.Fy) - float(model.evaluate(5000.0, 0.0, 0.3, limits=False).Fy)) > 1.0
    # driving backwards: Fy0 reverses with alpha* (MFeval), so Fy changes sign
    fwd = model.evaluate(5000.0, 0.0, 0.05, 0.0, 10.0, 2.6e5, limits=False, alpha_star=True)
    bwd = model.evaluate(5000.0, 0.0, 0.05, 0.0, -10.0, 2.6e5, limits=False, alpha_star=True)
    assert np.sign(float(fwd.Fy)) == np.sign(float(bwd.Fy))  # alpha* = tan(alpha) sgn(Vx)


def test_turn_slip_broadcasts_and_isolates_nan(model) -> None:
    g = _grid()
    ref = _eval(model, g, limits=True, turn_slip=True)
    bad = dict(g, phit=g["phit"].copy())
    bad["phit"][5] = math.nan
    out = _eval(model, bad, limits=True, turn_slip=True)
    assert math.isnan(out.Fy[5]) and math.isnan(out.Mz[5])
    keep = np.arange(g["Fz"].size) != 5
    for name in FORCES:
        np.testing.assert_array_equal(getattr(out, name)[keep], getattr(ref, name)[keep])
    grid = model.evaluate(np.array([[3000.0], [7000.0]]), 0.02, 0.05, 0.03,
                          phit=np.array([0.0, 0.05, -0.2]), turn_slip=True)  # fmt: skip
    assert grid.Mz.shape == (2, 3)
    one = model.evaluate(7000.0, 0.02, 0.05, 0.03, phit=-0.2, turn_slip=True)
    assert grid.Mz[1, 2] == one.Mz and grid.Fy[1, 2] == one.Fy


@pytest.mark.parametrize("turn_slip,alpha_star", [(True, False), (False, True), (True, True)])
def test_unloaded_wheel_gives_zero_in_every_mode(model, turn_slip, alpha_star) -> None:
    """Fz <= 0 gives zero forces and moments, as without the variants (turn slip's zeta7 is
    0/0 there)."""
    Fz, kappa, alpha = np.array([0.0, -5.0]), np.array([0.0, 0.1]), np.array([0.1, 0.0])
    plain = model.evaluate(Fz, kappa, alpha, 0.02, phit=0.2)
    out = model.evaluate(Fz, kappa, alpha, 0.02, phit=0.2, turn_slip=turn_slip,
                         alpha_star=alpha_star)  # fmt: skip
    for name in FORCES:
        np.testing.assert_array_equal(getattr(out, name), getattr(plain, name))
        assert np.all(np.isfinite(getattr(out, name)))


def test_turn_slip_coefficients_come_from_the_tir_file(model, tmp_path) -> None:
    text = MF61_TIR.read_text()
    assert "PDYP1                    =    0.4" in text
    changed = tmp_path / "spin.tir"
    changed.write_text(text.replace("PDYP1                    =    0.4",
                                    "PDYP1                    =    0.9"))  # fmt: skip
    other = TireModel.from_file(changed)
    assert other.params["PDYP1"] == 0.9 and model.params["PDYP1"] == 0.4
    args = (6752.0, 0.0, 0.05, 0.0, 16.6, 2.6e5)
    a = model.evaluate(*args, phit=0.2, limits=False, turn_slip=True)
    b = other.evaluate(*args, phit=0.2, limits=False, turn_slip=True)
    assert abs(float(a.Fy) - float(b.Fy)) > 1.0  # zeta2 (4.77) reads PDYP1
    plain_a = model.evaluate(*args, phit=0.2, limits=False)
    plain_b = other.evaluate(*args, phit=0.2, limits=False)
    assert plain_a.Fy == plain_b.Fy
