"""The temperature range of a .tir, the fitted envelope it carries, eval's warning about rows
outside it, and the virtual rig's two programmes of the seed paper (issue 15)."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
from conftest import DEFAULT_TIR, TOOL

from tire_model_ros.model import TireModel, write_tir
from tire_model_ros.model.envelope import RIG, SIMULATION, Envelope
from tire_model_ros.model.tir import TirError, read_tir
from tire_model_ros.rig import simulate_session

FNOMIN = 6752.0  # config/default.tir
STEPS = (0.1 * FNOMIN, 20e3, 5.0)


@pytest.fixture(scope="module")
def tyre() -> TireModel:
    return TireModel.from_file(DEFAULT_TIR)


# ------------------------------------------------------------------ [TEMPERATURE_RANGE]
def test_temperature_range_saturates_and_round_trips(tyre, tmp_path):
    ranged = tyre.with_params({"TEMPMIN": -10.0, "TEMPMAX": 80.0})
    T = np.array([-40.0, -10.0, 25.0, 80.0, 120.0])
    n = len(T)
    o = ranged.evaluate(np.full(n, 6000.0), np.full(n, 0.1), np.full(n, 0.05), 0.0, 16.6, 2.6e5, T)
    assert o.Fx[0] == o.Fx[1] and o.Fx[3] == o.Fx[4]  # saturated to the range's ends
    assert len(set(np.round(o.Fx[1:4], 6))) == 3  # and not inside it
    plain = ranged.evaluate(
        np.full(n, 6000.0), np.full(n, 0.1), np.full(n, 0.05), 0.0, 16.6, 2.6e5, T, limits=False
    )
    assert plain.Fx[0] != plain.Fx[1] and plain.Fx[3] != plain.Fx[4]
    path = tmp_path / "ranged.tir"
    write_tir(ranged.tir, path)
    text = path.read_text()
    assert "[TEMPERATURE_RANGE]" in text
    back = read_tir(path)
    assert (back.params["TEMPMIN"], back.params["TEMPMAX"]) == (-10.0, 80.0)
    write_tir(tyre.tir, tmp_path / "plain.tir")  # a file without one stays without one
    assert "TEMPERATURE_RANGE" not in (tmp_path / "plain.tir").read_text()
    half = tmp_path / "half.tir"  # all or nothing, like the other optional sections
    half.write_text(text.replace("TEMPMAX", "$TEMPMAX"))
    with pytest.raises(TirError, match="TEMPMAX"):
        read_tir(half)


# ------------------------------------------------------------------ the envelope
def _envelope() -> Envelope:
    rng = np.random.default_rng(3)
    n = 4000
    rig = Envelope.from_samples(
        rng.uniform(0.4, 1.0, n) * FNOMIN,
        rng.choice([2.2e5, 2.6e5], n),
        rng.uniform(25.0, 45.0, n),
        RIG,
        STEPS,
        20,
    )
    sim = Envelope.from_samples(
        np.repeat([1.2 * FNOMIN, 1.6 * FNOMIN], 500), np.full(1000, 60e3), np.full(1000, 25.0),
        SIMULATION, STEPS, 20,
    )  # fmt: skip
    return rig.union(sim).filled()


def test_envelope_covers_what_was_fitted_and_fills_between(tyre, tmp_path):
    env = _envelope()
    assert env.contains_one(0.7 * FNOMIN, 2.6e5, 35.0)
    assert env.contains_one(1.4 * FNOMIN, 60e3, 25.0)  # between two simulated loads: filled
    assert not env.contains_one(2.0 * FNOMIN, 60e3, 25.0)  # beyond the highest load
    assert not env.contains_one(0.7 * FNOMIN, 2.6e5, 80.0)  # hotter than any data
    assert not env.contains_one(1.4 * FNOMIN, 140e3, 25.0)  # no data at 140 kPa that load
    assert not env.contains_one(float("nan"), 2.6e5, 25.0)
    got = env.contains(
        np.array([0.7, 1.4, 2.0]) * FNOMIN, np.array([2.6e5, 60e3, 60e3]), np.full(3, 30.0)
    )
    assert got.tolist() == [True, False, False]  # 30 degC at 60 kPa: not simulated
    assert env.cells[(14, 3, 5)] == SIMULATION and env.cells[(7, 13, 7)] == RIG

    path = tmp_path / "enveloped.tir"
    write_tir(env.into(tyre.tir), path)
    back = Envelope.from_tir(read_tir(path))  # strict reading keeps the section verbatim
    assert back is not None and back.cells == env.cells
    assert Envelope.from_tir(tyre.tir) is None
    bad = tmp_path / "bad.tir"
    bad.write_text(path.read_text().replace(" 60000 25 2", " 60000 25 x", 1))
    with pytest.raises(ValueError, match=r"bad\.tir: \[FIT_ENVELOPE\] row at line \d+"):
        Envelope.from_tir(read_tir(bad))


def test_filled_cells_take_what_informed_both_sides():
    cells = {(12, 11, 8): RIG | SIMULATION, (12, 11, 16): SIMULATION}  # 40 and 80 degC
    cells |= {(5, 13, 7): RIG, (5, 13, 9): SIMULATION}
    env = Envelope(*STEPS, cells).filled()
    assert {env.cells[(12, 11, k)] for k in range(9, 16)} == {SIMULATION}  # the rig never hot
    assert env.cells[(5, 13, 8)] == RIG | SIMULATION  # nothing shared: either side's


def test_eval_warns_about_rows_outside_the_envelope(tyre, tmp_path):
    path = tmp_path / "enveloped.tir"
    write_tir(_envelope().into(tyre.tir), path)
    src, dst = tmp_path / "in.csv", tmp_path / "out.csv"
    src.write_text(
        "Fz,kappa,alpha,gamma,Vx,p,T\n"
        f"{0.7 * FNOMIN},0.05,0.02,0,16,260000,30\n"  # inside
        f"{2.0 * FNOMIN},0.05,0.02,0,16,260000,30\n"  # too much load
        f"{0.7 * FNOMIN},0.05,0.02,0,16,260000,80\n"  # too hot
    )
    res = subprocess.run(
        [*TOOL, "eval", "--tir", str(path), str(src), "-o", str(dst)],
        capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "2 of 3 rows outside the envelope" in res.stderr and "line(s) 3, 4;" in res.stderr
    assert "2 outside the fitted envelope" in res.stdout
    assert len(dst.read_text().splitlines()) == 4  # evaluated all the same
    res = subprocess.run(
        [*TOOL, "eval", "--tir", str(DEFAULT_TIR), str(src), "-o", str(dst), "--force"],
        capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    assert res.returncode == 0 and "no fitted envelope" in res.stdout
    assert "outside the envelope" not in res.stderr


# ------------------------------------------------------------------ the rig's two parts
def test_safe_envelope_heats_without_a_temperature_channel(tyre):
    wheels, truth = simulate_session(tyre, "safe_envelope", rate_hz=10)
    w = wheels[0]
    assert w.T is None and truth["omitted"] == ["temperature"] and "heating" in truth["effects"]
    assert truth["concealed"] == ["heating"] and not truth["isothermal"]
    assert w.Fz.min() > 0.39 * FNOMIN and w.Fz.max() < 1.21 * FNOMIN
    assert w.p.min() > 0.84 * 2.6e5 and w.p.max() < 1.16 * 2.6e5
    hidden = truth["wheels"]["/rig/wheel"]["hidden_summary"]
    assert hidden["T_surface_peak_C"] > 40.0 and hidden["mu_factor_min"] < 0.95


def test_special_conditions_isothermal_with_sidewall_contact(tyre):
    on, truth = simulate_session(tyre, "special_conditions", rate_hz=10, effects={"noise": False})
    off, _ = simulate_session(
        tyre, "special_conditions", rate_hz=10, effects={"noise": False, "sidewall": False}
    )
    w, flat = on[0], off[0]
    assert truth["isothermal"] and "sidewall" in truth["effects"]
    swept = np.abs(w.kappa) + np.abs(w.alpha) > 0
    assert set(np.unique(w.T[swept])) == {-10.0, 25.0, 40.0, 80.0}  # the set temperatures
    levels = np.unique(w.p[swept])
    assert {60e3, 140e3, 220e3} <= set(levels)
    assert w.Fz.max() == pytest.approx(1.6 * FNOMIN)
    lost = 1.0 - np.abs(w.Fy) / np.maximum(np.abs(flat.Fy), 1e-9)
    corner = (w.p == 60e3) & (w.Fz > 1.3 * FNOMIN) & (np.abs(w.alpha) > np.radians(12.0))
    assert lost[corner].min() > 0.05  # the sidewall takes Fy at low pressure, high load ...
    assert np.all(lost[w.p > 100e3] == 0.0)  # ... and nowhere else
    assert np.all(lost[np.abs(w.alpha) < np.radians(6.0)] == 0.0)
    np.testing.assert_array_equal(w.Fx, flat.Fx)
    hot, cold = (np.abs(w.Fy[(w.T == T) & (np.abs(w.kappa) == 0)]).max() for T in (80.0, 40.0))
    assert hot < 0.9 * cold  # the temperature law acts at the set temperature
