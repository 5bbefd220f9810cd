"""The temperature extension of INTERFACE.md on the MF 6.1 example tyre.

dT = (T - NOMTEMP)/NOMTEMP; Kxk *= 1+TTX1 dT+TTX2 dT^2; mux *= 1+TTX3 dT+TTX4 dT^2;
Kya: PKY1 term *(1+TTY1 dT), PKY2 term *(1+TTY2 dT); muy *= 1+TTY3 dT+TTY4 dT^2.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import requires_reference

from tire_model_ros.model import TireModel

pytestmark = requires_reference

TT = {"TTX1": 0.3, "TTX2": -0.2, "TTX3": -0.15, "TTX4": 0.05,
      "TTY1": 0.25, "TTY2": -0.4, "TTY3": -0.12, "TTY4": 0.07}  # fmt: skip
QUANTITIES = ("Fx", "Fy", "Mx", "My", "Mz", "Kxk", "Kya", "mux", "muy", "t", "Mzr", "Re",
              "sigmax", "sigmay")  # fmt: skip


def _grid():
    """Combined-slip grid over load, slips, camber and pressure (flattened)."""
    Fz, kappa, alpha, gamma, p = np.meshgrid(
        [2000.0, 6752.0, 11000.0], [-0.2, -0.03, 0.0, 0.05, 0.4], [-0.2, -0.02, 0.0, 0.1],
        [-0.05, 0.0, 0.08], [2.0e5, 2.6e5, 3.4e5], indexing="ij",
    )  # fmt: skip
    return Fz.ravel(), kappa.ravel(), alpha.ravel(), gamma.ravel(), p.ravel()


def _same(a, b) -> None:
    for name in QUANTITIES:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_file_without_temperature_section_has_no_temperature_effect(model) -> None:
    assert model.params["NOMTEMP"] == 25.0
    assert all(model.params[k] == 0.0 for k in TT)
    Fz, kappa, alpha, gamma, p = _grid()
    nominal = model.evaluate(Fz, kappa, alpha, gamma, 16.6, p)
    for T in (-20.0, 25.0, 90.0):
        _same(model.evaluate(Fz, kappa, alpha, gamma, 16.6, p, T), nominal)


@pytest.mark.parametrize("limits", [True, False])
def test_nominal_temperature_changes_nothing(model, limits) -> None:
    warm = model.with_params(TT)
    Fz, kappa, alpha, gamma, p = _grid()
    _same(
        warm.evaluate(Fz, kappa, alpha, gamma, 16.6, p, 25.0, limits=limits),
        model.evaluate(Fz, kappa, alpha, gamma, 16.6, p, limits=limits),
    )
    # and T=None means NOMTEMP, also for another NOMTEMP
    hot_ref = warm.with_params({"NOMTEMP": 60.0})
    _same(
        hot_ref.evaluate(Fz, kappa, alpha, gamma, 16.6, p, 60.0, limits=limits),
        hot_ref.evaluate(Fz, kappa, alpha, gamma, 16.6, p, limits=limits),
    )


def _quad(a1: float, a2: float, dT: float) -> float:
    return 1.0 + a1 * dT + a2 * dT * dT


@pytest.mark.parametrize("T", [-10.0, 5.0, 60.0, 110.0])
def test_factors_follow_the_interface(model, T) -> None:
    warm = model.with_params(TT)
    P = warm.params
    dT = (T - P["NOMTEMP"]) / P["NOMTEMP"]
    Fz, kappa, alpha, gamma, p = _grid()
    hot = warm.evaluate(Fz, kappa, alpha, gamma, 16.6, p, T)
    ref = model.evaluate(Fz, kappa, alpha, gamma, 16.6, p)
    np.testing.assert_allclose(hot.Kxk, ref.Kxk * _quad(TT["TTX1"], TT["TTX2"], dT), rtol=1e-13)
    np.testing.assert_allclose(hot.mux, ref.mux * _quad(TT["TTX3"], TT["TTX4"], dT), rtol=1e-13)
    np.testing.assert_allclose(hot.muy, ref.muy * _quad(TT["TTY3"], TT["TTY4"], dT), rtol=1e-13)

    # Kya written out from INTERFACE.md, independent of the model code
    Fz0p = P["LFZO"] * P["FNOMIN"]
    g = np.clip(gamma, P["CAMMIN"], P["CAMMAX"])
    dpi = (np.clip(p, P["PRESMIN"], P["PRESMAX"]) - P["NOMPRES"]) / P["NOMPRES"]
    Kya = (
        P["PKY1"] * Fz0p * (1 + P["PPY1"] * dpi) * (1 + TT["TTY1"] * dT) * (1 - P["PKY3"] * abs(g))
        * np.sin(P["PKY4"] * np.arctan((Fz / Fz0p) / (
            (P["PKY2"] + P["PKY5"] * g**2) * (1 + P["PPY2"] * dpi) * (1 + TT["TTY2"] * dT))))
        * P["LKY"]
    )  # fmt: skip
    np.testing.assert_allclose(hot.Kya, Kya, rtol=1e-12)
    # the changed stiffness and friction reach the forces
    assert np.max(np.abs(hot.Fx - ref.Fx)) > 1.0
    assert np.max(np.abs(hot.Fy - ref.Fy)) > 1.0


def _plain_curves(model: TireModel) -> TireModel:
    """No shifts, so that the peak is D and the slope at zero slip is BCD = stiffness."""
    zero = ("PHX1", "PHX2", "PVX1", "PVX2", "PHY1", "PHY2", "PVY1", "PVY2", "PVY3", "PVY4",
            "PKY6", "PKY7", "RHX1", "RHY1", "RHY2", "RVY1", "RVY2", "RVY3")  # fmt: skip
    return model.with_params(dict.fromkeys(zero, 0.0))


@pytest.mark.parametrize("T", [0.0, 70.0])
def test_temperature_scales_peak_force_and_slip_stiffness(model, T) -> None:
    plain = _plain_curves(model)
    warm = plain.with_params(TT)
    dT = (T - 25.0) / 25.0
    kappa = np.linspace(0.0, 0.6, 60001)
    Fx_hot = warm.evaluate(4000.0, kappa, 0.0, T=T, limits=False, full=False).Fx
    Fx_ref = plain.evaluate(4000.0, kappa, 0.0, limits=False, full=False).Fx
    assert Fx_hot.max() / Fx_ref.max() == pytest.approx(_quad(TT["TTX3"], TT["TTX4"], dT), 1e-7)
    h = 1e-7
    slope_hot = warm.evaluate(4000.0, h, 0.0, T=T, limits=False, full=False).Fx / h
    slope_ref = plain.evaluate(4000.0, h, 0.0, limits=False, full=False).Fx / h
    assert slope_hot / slope_ref == pytest.approx(_quad(TT["TTX1"], TT["TTX2"], dT), 1e-5)

    alpha = np.linspace(-0.6, 0.0, 60001)
    Fy_hot = warm.evaluate(4000.0, 0.0, alpha, T=T, limits=False, full=False).Fy
    Fy_ref = plain.evaluate(4000.0, 0.0, alpha, limits=False, full=False).Fy
    assert Fy_hot.max() / Fy_ref.max() == pytest.approx(_quad(TT["TTY3"], TT["TTY4"], dT), 1e-7)
    assert math.isfinite(Fy_hot.max())
