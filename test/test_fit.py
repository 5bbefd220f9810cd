"""Refitting Magic Formula coefficients from recordings (``fit`` package, ``tire-model fit``).

The round trip: the virtual rig records a flat-trac session of a tyre whose friction,
stiffness, pressure and temperature coefficients differ from the reference file by 5-10 %;
the fit starts from the reference file and must recover the forces to noise level on held-out
sweeps, and the coefficients (as peak friction and stiffness at several loads, pressures and
temperatures) within a few percent.
"""

from __future__ import annotations

import json
import math
import os
import subprocess

import numpy as np
import pytest
from conftest import MF61_TIR, TOOL

from tire_model_ros.fit import FitOptions, fit_coefficients, fit_recording, split_sweeps
from tire_model_ros.fit.report import write_fit_report
from tire_model_ros.fit.stages import past_peak, physical_checks, sample_mask, usable_mask
from tire_model_ros.fit.sweeps import split_segments
from tire_model_ros.model import TireModel, read_tir, write_tir
from tire_model_ros.recording.series import WheelSeries

DEG = math.pi / 180.0


def perturbed(model: TireModel) -> TireModel:
    """The 'real' tyre: friction and stiffness 5-8 % off, other pressure and temperature terms."""
    P = model.params
    return model.with_params(
        {
            "PDX1": P["PDX1"] * 0.94,
            "PKX1": P["PKX1"] * 1.07,
            "PDY1": P["PDY1"] * 1.08,
            "PKY1": P["PKY1"] * 0.93,
            "PPX1": P["PPX1"] + 0.1,
            "PPX3": P["PPX3"] - 0.1,
            "PPY1": P["PPY1"] + 0.1,
            "PPY3": P["PPY3"] + 0.1,
            "TTX1": -0.1,
            "TTX3": -0.08,
            "TTY1": -0.1,
            "TTY3": -0.06,
        }
    )


@pytest.fixture(scope="module")
def session(model):
    """A flat-trac session of the perturbed tyre: its TTX/TTY act on the tread temperature."""
    from tire_model_ros.rig import simulate_session

    truth = perturbed(model)
    wheels, info = simulate_session(truth, "flat_trac", effects=["model_temperature"], seed=5)
    return truth, wheels, info


@pytest.fixture(scope="module")
def fitted(model, session):
    _, wheels, _ = session
    return fit_recording(wheels, model, FitOptions(progress=False))


# --- sweeps ----------------------------------------------------------------------------------


def _programme(dt: float = 0.01, noise: bool = True, seed: int = 0) -> tuple[WheelSeries, list]:
    """Known segments: (start s, end s, label) and the series with sensor noise."""
    parts, t0 = [], 0.0
    kappa, alpha = [], []

    def add(k0, k1, a0, a1, dur, label):
        nonlocal t0
        n = round(dur / dt)
        kappa.append(np.linspace(k0, k1, n, endpoint=False))
        alpha.append(np.linspace(a0, a1, n, endpoint=False))
        parts.append((t0, t0 + dur, label))
        t0 += dur

    add(0, 0, 0, 0, 2.0, "pause")
    add(0, 0, 0, 10 * DEG, 10 / 3, "ramp alpha+")
    add(0, 0, 10 * DEG, -10 * DEG, 20 / 3, "ramp alpha-")
    add(0, 0, -10 * DEG, 0, 10 / 3, "ramp alpha+")
    add(0, 0, 0, 0, 1.5, "pause")
    add(0, 0.2, 0, 0, 2.0, "ramp kappa+")
    add(0.2, -0.2, 0, 0, 4.0, "ramp kappa-")
    add(-0.2, 0, 0, 0, 2.0, "ramp kappa+")
    add(0, 0, 0, 4 * DEG, 1.0, "ramp alpha+")
    add(0, 0.1, 4 * DEG, 4 * DEG, 2.0, "ramp kappa+")
    add(0.1, 0.1, 4 * DEG, 4 * DEG, 3.0, "steady")
    k, a = np.concatenate(kappa), np.concatenate(alpha)
    n = len(k)
    rng = np.random.default_rng(seed)
    s = 1.0 if noise else 0.0
    series = WheelSeries(
        "/test/wheel",
        np.arange(n) * dt,
        k + s * rng.normal(0, 1e-3, n),
        a + s * rng.normal(0, 0.05 * DEG, n),
        np.zeros(n),
        4000 + s * rng.normal(0, 30, n),
    )
    return series, parts


@pytest.mark.parametrize("noise", [False, True])
def test_split_sweeps_finds_the_programme(noise):
    series, parts = _programme(noise=noise)
    segs = split_segments(series)
    assert [g.label for g in segs] == [p[2] for p in parts]
    for g, (t0, t1, _) in zip(segs, parts, strict=True):
        assert abs(series.t[g.index[0]] - t0) < 0.3
        assert abs(series.t[g.index[-1]] - t1) < 0.3
    idx = split_sweeps(series)
    assert np.array_equal(np.concatenate(idx), np.arange(len(series)))  # partition, time order


def test_split_sweeps_breaks_at_gaps_and_survives_nan():
    series, _ = _programme()
    t = series.t.copy()
    t[1500:] += 30.0  # a 30 s hole in the recording, inside the alpha- ramp
    kappa = series.kappa.copy()
    kappa[200:260] = np.nan
    gapped = WheelSeries(series.prefix, t, kappa, series.alpha, series.gamma, series.Fz)
    idx = split_sweeps(gapped)
    assert np.array_equal(np.concatenate(idx), np.arange(len(t)))
    assert any(i[0] == 1500 for i in idx)
    nan_all = WheelSeries(
        "/w", series.t, np.full(len(t), np.nan), series.alpha, series.gamma, np.full(len(t), np.nan)
    )
    assert np.array_equal(np.concatenate(split_sweeps(nan_all)), np.arange(len(t)))
    assert split_sweeps(WheelSeries("/w", t[:0], t[:0], t[:0], t[:0], t[:0])) == []


def test_split_sweeps_on_the_rig_matches_its_sweeps(session):
    _, wheels, _info = session
    s = wheels[0]
    segs = split_segments(s)
    ramps = [
        g for g in segs if g.kind == "ramp" and ("alpha" in g.direction or "kappa" in g.direction)
    ]
    # flat_trac: dozens of sweeps, each cut into its monotone legs
    assert len(ramps) > 40
    for g in ramps:  # each leg is monotone in its slip: the smoothed slip never turns back
        for ch, sign in g.direction.items():
            if ch not in ("alpha", "kappa"):
                continue
            x = getattr(s, ch)[g.index]
            w = max(1, len(x) // 10)
            xs = np.convolve(x, np.ones(w) / w, mode="valid")
            span = abs(xs[-1] - xs[0])
            assert sign * (xs[-1] - xs[0]) > 0
            assert np.all(sign * np.diff(xs) > -0.1 * span), (ch, g.label)


# --- fit_coefficients ------------------------------------------------------------------------


def test_fit_coefficients_recovers_two_coefficients(model, session):
    truth, wheels, _ = session
    lat = [s.select(sample_mask(s, "pure_lat")) for s in wheels]
    # Start from the true tyre with the two coefficients reset to the reference file's values
    # (8 % and 7 % off); the other coefficients are right, so both must come back to 1 %.
    start = truth.with_params({k: model.params[k] for k in ("PDY1", "PKY1")})
    got, info = fit_coefficients(start, lat, ["PDY1", "PKY1"], channels=("Fy",))
    for k in ("PDY1", "PKY1"):
        assert abs(got.params[k] / truth.params[k] - 1) < 0.01, k
        assert 0 < info["stderr"][k] < abs(truth.params[k])
    assert info["rmse_after"]["Fy"] < 0.5 * info["rmse_before"]["Fy"]
    assert info["nfev"] > 1 and info["success"]
    # 2 % of the samples hit by 8 kN spikes (a glitching load cell): the robust loss keeps the
    # estimate where it was, a plain least-squares fit is dragged away.
    spiky = []
    for s in lat:
        Fy = s.Fy.copy()
        rng = np.random.default_rng(7)
        hit = rng.random(len(Fy)) < 0.02
        Fy[hit] += 8000.0 * np.sign(Fy[hit])  # outward: would inflate the peak
        spiky.append(
            WheelSeries(s.prefix, s.t, s.kappa, s.alpha, s.gamma, s.Fz, s.p, s.T, s.Vx, Fy=Fy)
        )
    robust, _ = fit_coefficients(start, spiky, ["PDY1", "PKY1"], channels=("Fy",))
    plain, _ = fit_coefficients(start, spiky, ["PDY1", "PKY1"], channels=("Fy",), loss="linear")
    for k in ("PDY1", "PKY1"):
        assert abs(robust.params[k] / truth.params[k] - 1) < 0.01, k
    assert abs(plain.params["PDY1"] / truth.params["PDY1"] - 1) > abs(
        robust.params["PDY1"] / truth.params["PDY1"] - 1
    )


def test_fit_coefficients_rejects_bad_input(model, session):
    _, wheels, _ = session
    with pytest.raises(ValueError, match="PDY99"):
        fit_coefficients(model, wheels, ["PDY99"], channels=("Fy",))
    with pytest.raises(ValueError, match="too few samples"):
        fit_coefficients(model, [wheels[0].select(np.arange(10))], ["PDY1"], channels=("Fy",))
    with pytest.raises(ValueError, match="channel"):
        fit_coefficients(model, wheels, ["PDY1"], channels=("Fq",))
    s = wheels[0]
    nan = WheelSeries(s.prefix, s.t, s.kappa, s.alpha, s.gamma, s.Fz, Fy=np.full(len(s), np.nan))
    with pytest.raises(ValueError, match="too few samples"):
        fit_coefficients(model, [nan], ["PDY1"], channels=("Fy",))


# --- the staged fit --------------------------------------------------------------------------


def _heldout_rmse(model, wheels, masks, channel):
    d = []
    for s, m in zip(wheels, masks, strict=True):
        out = model.evaluate(s.Fz[m], s.kappa[m], s.alpha[m], s.gamma[m], s.Vx[m], s.p[m], s.T[m])
        d.append(getattr(out, channel) - getattr(s, channel)[m])
    d = np.concatenate(d)
    return float(np.sqrt(np.mean(d * d)))


def test_round_trip_forces_to_noise_on_heldout_sweeps(session, fitted):
    truth, wheels, _ = session
    res = fitted
    assert res.report["n_heldout"] > 0.1 * res.report["n_samples"]
    for c in ("Fx", "Fy", "Mz"):
        noise = _heldout_rmse(truth, wheels, res.heldout_masks, c)
        got = _heldout_rmse(res.model, wheels, res.heldout_masks, c)
        start = _heldout_rmse(res.start_model, wheels, res.heldout_masks, c)
        assert got < 1.15 * noise, (c, got, noise)
        assert got < 0.5 * start or c == "Mz", (c, got, start)
    # the report's figures are the same held-out numbers
    rep = res.report["metrics"]["overall"]["heldout"]
    assert rep["after"]["Fy"]["rmse"] == pytest.approx(
        _heldout_rmse(res.model, wheels, res.heldout_masks, "Fy"), rel=1e-9
    )
    assert rep["after"]["Fy"]["r2"] > 0.99


def _peaks(model, Fz, p, T):
    out = model.evaluate(Fz, 0.0, 0.0, 0.0, None, p, T, full=True)
    return {k: float(np.asarray(getattr(out, k))) for k in ("mux", "muy", "Kxk", "Kya")}


# flat_trac sweeps three loads at NOMPRES and two pressures at FNOMIN: check where it measured.
@pytest.mark.parametrize(("load", "p_ratio"), [(0.5, 1), (1, 1), (1.5, 1), (1, 0.8), (1, 1.2)])
@pytest.mark.parametrize("dT", [0.0, 20.0])
def test_round_trip_friction_and_stiffness(session, fitted, load, p_ratio, dT):
    truth, _, _ = session
    P = truth.params
    args = (load * P["FNOMIN"], p_ratio * P["NOMPRES"], P["NOMTEMP"] + dT)
    want, got = _peaks(truth, *args), _peaks(fitted.model, *args)
    for k in want:
        assert got[k] == pytest.approx(want[k], rel=0.03), (k, args)


def test_round_trip_main_coefficients(session, fitted):
    truth, _, _ = session
    for k in ("PDX1", "PKX1", "PDY1", "PKY1"):
        assert fitted.model.params[k] == pytest.approx(truth.params[k], rel=0.02), k
    # Pressure terms multiply dpi (+-0.2 here): 10 % of PPX3 = 0.01 is 0.2 % of friction.
    for k in ("PPX1", "PPX3", "PPY3"):
        assert fitted.model.params[k] == pytest.approx(truth.params[k], rel=0.1), k
    # temperature effect on friction over +20 degC, relative to nominal, within 1 % of truth
    T0 = truth.params["NOMTEMP"]
    for a, b in (("TTX3", "TTX4"), ("TTY3", "TTY4")):

        def factor(m):
            dT = 20.0 / T0
            return 1 + m.params[a] * dT + m.params[b] * dT * dT  # noqa: B023

        assert factor(fitted.model) == pytest.approx(factor(truth), abs=0.01), a


def test_stages_report_and_checks(fitted):
    stages = {st["stage"]: st for st in fitted.report["stages"]}
    assert list(stages) == ["Fx0", "Fy0", "Mz0", "combined", "pressure", "temperature"]
    for name in ("Fx0", "Fy0"):
        assert stages[name]["status"] == "fitted", stages[name]
    # Fx0/Fy0 already take the linear pressure and temperature terms along; the dedicated
    # stages then refine them, or keep them when the refinement does not beat the noise.
    for name in ("pressure", "temperature"):
        assert stages[name]["status"] in ("fitted", "not significant"), stages[name]
        sig = stages[name]["significance"]
        assert (sig["delta_chi2_eff"] >= sig["needed"]) == (stages[name]["status"] == "fitted")
    assert {"PPX1", "PPY1", "TTX1", "TTY3"} <= set(stages["Fx0"]["names"] + stages["Fy0"]["names"])
    assert "TTX3" in stages["temperature"]["names"] and "PPY1" in stages["pressure"]["names"]
    assert "PDY2" in stages["Fy0"]["names"]  # flat_trac has three loads
    m = fitted.model.params
    assert m["PCX1"] > 0 and m["PCY1"] > 0 and m["PDX1"] > 0 and m["PEX1"] <= 1 and m["PEY1"] <= 1


def test_skipped_stages_say_why(model, session):
    _, wheels, _ = session
    s = wheels[0]
    # no pressure, no temperature, lateral samples only
    lat = s.select(sample_mask(s, "pure_lat") & (np.abs(s.kappa) < 1e-3))
    lat.p = None
    lat.T = None
    res = fit_recording(
        [lat],
        model,
        FitOptions(
            progress=False, max_samples=3000, stages=["Fy0", "pressure", "temperature", "Fx0"]
        ),
    )
    st = {x["stage"]: x for x in res.report["stages"]}
    assert st["Fy0"]["status"] == "fitted"
    assert "no pressure channel" in st["pressure"]["reason"]
    assert "no temperature channel" in st["temperature"]["reason"]
    assert st["Mz0"]["reason"] == "not requested"
    assert st["Fx0"]["status"] == "skipped" and "no slip-ratio sweep" in st["Fx0"]["reason"]
    with pytest.raises(ValueError, match="no finite measured force"):
        nan = WheelSeries(
            s.prefix, s.t, s.kappa, s.alpha, s.gamma, s.Fz, Fx=np.full(len(s), np.nan)
        )
        fit_recording([nan], model, FitOptions(progress=False))


def test_physical_checks_and_warmup(model, session):
    _, wheels, _ = session
    s = wheels[0]
    assert physical_checks("Fy0", model, [s]) == {}
    bad = physical_checks("Fy0", model.with_params({"PEY1": 3.0}), [s])
    assert set(bad) == {"Ey <= 1 (4.E24)"} and 0 < bad["Ey <= 1 (4.E24)"] <= 1.0
    bad = physical_checks("combined", model.with_params({"REX1": 2.0}), [s])
    assert set(bad) == {"Exa <= 1 (4.E56)"} and bad["Exa <= 1 (4.E56)"] == 1.0
    assert past_peak(model, [s]) == {"long": True, "lat": True}
    small = s.select((np.abs(s.alpha) < 2 * DEG) & (np.abs(s.kappa) < 0.02))
    assert past_peak(model, [small]) == {"long": False, "lat": False}
    keep = usable_mask(s, FitOptions(warmup_s=30.0))
    assert not keep[s.t < s.t[0] + 29.9].any() and keep[s.t > s.t[0] + 30.1].all()
    if s.T is not None:
        cold = usable_mask(s, FitOptions(min_temperature=30.0))
        assert np.array_equal(cold, s.T >= 30.0)


def test_fit_that_does_not_beat_noise_keeps_start_values(model):
    from tire_model_ros.rig import simulate_session

    # The rig's tyre is the start model itself (only sensor noise added): nothing to gain, so
    # the stages must keep the start values instead of fitting the noise.
    wheels, _ = simulate_session(model, "lateral_sweeps", seed=2, omit=["temperature"])
    res = fit_recording(wheels, model, FitOptions(progress=False, stages=["Fy0"]))
    st = res.report["stages"][1]
    assert st["stage"] == "Fy0" and st["status"] == "not significant", st
    assert "start values kept" in st["reason"]
    assert res.report["changed"] == {}


def test_written_tir_loads_and_is_not_overwritten(fitted, tmp_path):
    out = tmp_path / "fitted.tir"
    write_tir(fitted.model.tir, out)
    again = TireModel(read_tir(out))
    for k in ("PDY1", "PKY1", "TTX3", "TTY3", "PPX3", "NOMTEMP"):
        assert again.params[k] == pytest.approx(fitted.model.params[k], rel=1e-12), k
    assert "[TEMPERATURE_COEFFICIENTS]" in out.read_text()
    before = out.read_bytes()
    with pytest.raises(FileExistsError):
        write_tir(fitted.model.tir, out)
    assert out.read_bytes() == before


def test_report_files(fitted, tmp_path):
    md = write_fit_report(fitted, tmp_path / "rep")
    text = md.read_text()
    assert "held" in text and "| Fy |" in text
    data = json.loads((tmp_path / "rep" / "fit_report.json").read_text())
    ho = data["metrics"]["overall"]["heldout"]
    assert set(ho) == {"before", "after"} and ho["after"]["Fx"]["nrmse"] < 0.02
    loads = data["metrics"]["by_condition"]["load"]
    assert len(loads) >= 3 and all("heldout" in row for row in loads)
    assert "pressure" in data["metrics"]["by_condition"]
    for png in ("fit_Fx.png", "fit_Fy.png", "fit_sweeps.png", "fit_residual_time.png"):
        assert (tmp_path / "rep" / png).read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(FileExistsError):
        write_fit_report(fitted, tmp_path / "rep")


# --- the command -----------------------------------------------------------------------------


def _cli(*args, cwd):
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    return subprocess.run(
        [*TOOL, "fit", *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=240
    )


def test_cli_end_to_end(model, tmp_path):
    from tire_model_ros.rig import simulate_session, write_session

    truth = perturbed(model)
    wheels, info = simulate_session(truth, "lateral_sweeps", seed=2, omit=["temperature"])
    bag = tmp_path / "lat.mcap"
    write_session(bag, wheels, info)
    wheels2, info2 = simulate_session(truth, "longitudinal_sweeps", seed=3, omit=["temperature"])
    bag2 = tmp_path / "long.mcap"
    write_session(bag2, wheels2, info2)
    out = tmp_path / "out.tir"
    stages = "Fx0,Fy0,temperature"
    r = _cli(str(bag), str(bag2), "--tir", str(MF61_TIR), "-o", str(out), "--stages", stages,
             cwd=tmp_path)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "fit Fy0" in r.stderr and "no temperature channel" in r.stderr, r.stderr
    got = TireModel.from_file(out)
    assert got.params["PDY1"] == pytest.approx(truth.params["PDY1"], rel=0.03)
    assert got.params["PDX1"] == pytest.approx(truth.params["PDX1"], rel=0.03)  # 2nd bag
    rep = tmp_path / "out_fit_report"
    assert (rep / "fit_report.md").exists() and (rep / "fit_Fy.png").exists()
    data = json.loads((rep / "fit_report.json").read_text())
    assert (
        data["metrics"]["overall"]["heldout"]["after"]["Fy"]["rmse"]
        < data["metrics"]["overall"]["heldout"]["before"]["Fy"]["rmse"]
    )
    stamp = out.read_bytes()
    r2 = _cli(str(bag), "--tir", str(MF61_TIR), "-o", str(out), cwd=tmp_path)
    assert r2.returncode == 1 and "exists" in r2.stderr and "Traceback" not in r2.stderr
    assert out.read_bytes() == stamp
    r3 = _cli(
        str(bag),
        "--tir",
        str(MF61_TIR),
        "-o",
        str(tmp_path / "x.tir"),
        "--stages",
        "pressure",
        cwd=tmp_path,
    )
    assert r3.returncode == 1 and "pressure does not vary" in r3.stderr
    assert "nothing written" in r3.stderr
    assert not (tmp_path / "x.tir").exists() and not (tmp_path / "x_fit_report").exists()
    r4 = _cli(
        str(tmp_path / "missing.mcap"),
        "--tir",
        str(MF61_TIR),
        "-o",
        str(tmp_path / "y.tir"),
        cwd=tmp_path,
    )
    assert r4.returncode == 1 and "missing.mcap" in r4.stderr and "Traceback" not in r4.stderr
