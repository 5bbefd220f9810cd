"""The virtual rig: reproducibility, each effect's signature, sizes, bags and the CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import MF61_TIR, ROOT, TIR_DIR

from tire_model_ros.cli import main as cli_main
from tire_model_ros.model import TireModel
from tire_model_ros.rig import simulate_session, truth_path
from tire_model_ros.rig.effects import resolve_effects
from tire_model_ros.rig.thermal import gas_law_pressure

DEG = math.pi / 180
QUIET = {"noise": False}


def _sim(model, programme, effects=None, rate=50.0, **kw):
    eff = {**QUIET, **(effects or {})}
    wheels, truth = simulate_session(model, programme, effects=eff, rate_hz=rate, **kw)
    return wheels, truth


def _segments(truth, kind, prefix="/rig/wheel"):
    return [s for s in truth["wheels"][prefix]["segments"] if s["kind"] == kind]


def _idx(seg, rate):
    return slice(round(seg["t0_s"] * rate), round(seg["t1_s"] * rate))


def _base(model, w):
    return model.evaluate(w.Fz, w.kappa, w.alpha, w.gamma, w.Vx, w.p)


def _first_peak(alpha):
    """Index of the first turning point (the +A of 0 -> +A -> -A -> 0)."""
    return int(np.argmax(np.abs(alpha) >= 0.999 * np.max(np.abs(alpha))))


def _legs(alpha):
    """Out (0 -> peak) and back (peak -> 0) legs of a 0 -> +A -> -A -> 0 sweep, |alpha|>A/2."""
    k = _first_peak(alpha)
    A = abs(alpha[k])
    out = np.arange(0, k)
    back = np.arange(k, 2 * k)
    return out[np.abs(alpha[out]) > A / 2], back[np.abs(alpha[back]) > A / 2]


def _loop_width(alpha, Fy, lo=0.1, hi=0.9):
    """Mean |Fy| difference between the two legs at the same alpha on 0 -> +A -> 0."""
    k = _first_peak(alpha)
    a_out, f_out = alpha[:k], Fy[:k]
    a_back, f_back = alpha[k : 2 * k][::-1], Fy[k : 2 * k][::-1]
    grid = np.linspace(lo, hi, 30) * abs(alpha[k]) * np.sign(alpha[k])
    order_o, order_b = np.argsort(a_out), np.argsort(a_back)
    fo = np.interp(grid, a_out[order_o], f_out[order_o])
    fb = np.interp(grid, a_back[order_b], f_back[order_b])
    return float(np.mean(np.abs(fo - fb)))


# ------------------------------------------------------------------ reproducibility


def test_same_seed_same_series_and_other_seed_differs(model):
    a, ta = simulate_session(model, "camber", seed=7, rate_hz=50, effects={"heating": True})
    b, tb = simulate_session(model, "camber", seed=7, rate_hz=50, effects={"heating": True})
    c, _ = simulate_session(model, "camber", seed=8, rate_hz=50, effects={"heating": True})
    for name in ("kappa", "alpha", "Fz", "p", "T", "Fx", "Fy", "Mz"):
        assert np.array_equal(getattr(a[0], name), getattr(b[0], name)), name
    assert json.dumps(ta, sort_keys=True) == json.dumps(tb, sort_keys=True)
    assert not np.array_equal(a[0].Fy, c[0].Fy)
    # the noise is realistic: forces scatter about 0.3 % FNOMIN around the noiseless ones
    q, _ = simulate_session(
        model, "camber", seed=7, rate_hz=50, effects={"heating": True, "noise": False}
    )
    sd = np.std(a[0].Fy - q[0].Fy)
    assert 0.002 * 6752 < sd < 0.006 * 6752


def test_unknown_effect_programme_or_parameter_is_a_clear_error(model):
    with pytest.raises(ValueError, match="unknown effect 'heatin'"):
        simulate_session(model, "camber", effects={"heatin": True})
    with pytest.raises(ValueError, match="heating: unknown parameter"):
        resolve_effects({"heating": {"tau": 1}})
    with pytest.raises(ValueError, match="relaxation: parameter sigma_alpha_m must be > 0"):
        resolve_effects({"relaxation": {"sigma_alpha_m": 0}})
    with pytest.raises(ValueError, match="delay: parameter tau_s must be >= 0"):
        resolve_effects({"delay": {"tau_s": -0.01}})
    with pytest.raises(ValueError, match="unknown programme"):
        simulate_session(model, "flat_track")
    with pytest.raises(ValueError, match="cannot omit"):
        simulate_session(model, "camber", omit=["forces"])


# ------------------------------------------------------------------ nominal rig = the model


def test_without_effects_the_forces_are_the_model(model):
    w, truth = _sim(model, "combined")
    o = _base(model, w[0])
    assert np.max(np.abs(w[0].Fy - o.Fy)) < 1e-6
    assert np.max(np.abs(w[0].Fx - o.Fx)) < 1e-6
    assert truth["effects"] == {}


# ------------------------------------------------------------------ heating


def test_heating_way_back_weaker_and_surface_rise_plausible(model):
    w, truth = _sim(model, "lateral_sweeps", {"heating": True}, rate=100.0)
    s = w[0]
    o = _base(model, s)
    ref = _segments(truth, "lateral_sweep")[0]  # first reference sweep: FNOMIN, 3 deg/s
    assert ref["rate_deg_s"] == 3.0 and ref["amplitude_deg"] == 10.0
    sl = _idx(ref, 100.0)
    out, back = _legs(s.alpha[sl])
    ratio = np.abs(s.Fy[sl]) / np.abs(o.Fy[sl])
    loss = 1 - ratio[back].mean() / ratio[out].mean()
    assert 0.02 < loss < 0.12  # PHYSICS.md: |mu| about 6-7 % lower on the way back
    dT = ref["hidden"]["dT_surface_K"]
    assert 4.0 <= dT <= 22.0  # PHYSICS.md: +4...22 degC in 12.5 s
    # the temperature sensor sees the surface node (lagged, 10 Hz) and follows it
    Ts_trace = np.array(truth["wheels"]["/rig/wheel"]["hidden_trace"]["T_surface"])
    assert abs(s.T.max() - Ts_trace.max()) < 2.0
    # the surface recovers after the cooling pause (the carcass keeps a little)
    pause = next(x for x in _segments(truth, "pause") if "cooling" in x["label"])
    ps = _idx(pause, 100.0)
    assert s.T[ps][-1] < s.T[ps][0] - 3.0
    # heating off: no way-back loss
    w0, _ = _sim(model, "lateral_sweeps", {}, rate=100.0)
    r0 = np.abs(w0[0].Fy[sl]) / np.abs(o.Fy[sl])
    assert abs(1 - r0[back].mean() / r0[out].mean()) < 1e-6


def test_heating_concealed_when_temperature_omitted(model):
    w, truth = _sim(model, "camber", {"heating": True}, omit=["temperature"])
    assert w[0].T is None
    assert truth["concealed"] == ["heating"] and truth["omitted"] == ["temperature"]
    assert truth["diagnosis_words"] == ["temperature"]


# ------------------------------------------------------------------ gas pressure


def test_gas_law_numbers_of_physics_md():
    run = np.zeros(2, dtype=int)
    for p0, rise in ((220e3, 0.05), (83e3, 0.076)):
        p = gas_law_pressure(np.full(2, p0), np.array([25.0, 35.0]), run)
        assert p[0] == pytest.approx(p0)
        assert p[1] / p0 - 1 == pytest.approx(rise, abs=0.003)


def test_gas_pressure_follows_gas_temperature_and_reaches_the_model(model):
    w, truth = _sim(model, "lateral_sweeps", {"gas_pressure": True})
    wt = truth["wheels"]["/rig/wheel"]
    summ = wt["hidden_summary"]
    assert summ["T_gas_peak_C"] > 28.0
    assert summ["p_true_max_Pa"] > 1.01 * model.params["NOMPRES"]
    # the recorded (gauge) pressure channel carries it, and the forces follow the model at it
    assert w[0].p.max() == pytest.approx(summ["p_true_max_Pa"])
    o = _base(model, w[0])
    assert np.max(np.abs(w[0].Fy - o.Fy)) < 1e-6
    nominal = model.evaluate(w[0].Fz, w[0].kappa, w[0].alpha, w[0].gamma, w[0].Vx, None)
    assert np.max(np.abs(w[0].Fy - nominal.Fy)) > 20.0
    w2, t2 = _sim(model, "lateral_sweeps", {"gas_pressure": True}, omit=["pressure"])
    assert w2[0].p is None and t2["concealed"] == ["gas_pressure"]


# ------------------------------------------------------------------ relaxation, delay


def test_relaxation_loop_grows_with_sweep_rate_and_with_lower_speed(model):
    w, truth = _sim(model, "lateral_sweeps", {"relaxation": True})
    s = w[0]
    sweeps = {x["label"]: _idx(x, 50.0) for x in _segments(truth, "lateral_sweep")}
    width = {k: _loop_width(s.alpha[v], s.Fy[v]) for k, v in sweeps.items()}
    slow, fast = width["lateral rate=1.5deg/s"], width["lateral rate=6deg/s"]
    ref, low_v = width["lateral Fz=1FNOMIN"], width["lateral V=0.5V0"]
    assert fast > 2.5 * slow and low_v > 1.5 * ref
    # the order of size of PHYSICS.md: half-width ~ Kya * alpha_dot * sigma / V
    sl = sweeps["lateral Fz=1FNOMIN"]
    Kya = abs(_base(model, s).Kya[sl][0])
    expect = Kya * 3 * DEG * 0.5 / model.params["LONGVL"]
    half_width_near_0 = _loop_width(s.alpha[sl], s.Fy[sl], 0.02, 0.1) / 2
    assert 0.6 * expect < half_width_near_0 < 1.2 * expect
    w0, _ = _sim(model, "lateral_sweeps", {})
    s0 = w0[0]
    assert (
        _loop_width(s0.alpha[sweeps["lateral rate=6deg/s"]], s0.Fy[sweeps["lateral rate=6deg/s"]])
        < 1e-6
    )


def test_delay_cross_correlation_lag_equals_tau(model):
    tau = 0.05
    w, _ = _sim(model, "lateral_sweeps", {"delay": {"tau_s": tau}}, rate=100.0)
    s = w[0]
    o = _base(model, s)
    x = np.diff(o.Fy)
    y = np.diff(s.Fy)
    lags = np.arange(-20, 21)
    cc = [
        np.dot(x[max(0, -k) : len(x) - max(0, k)], y[max(0, k) : len(y) - max(0, -k)]) for k in lags
    ]
    assert lags[int(np.argmax(cc))] == round(tau * 100)


# ------------------------------------------------------------------ offsets, camber, combined


def test_offset_gives_fy_at_zero_slip(model):
    w, _ = _sim(model, "lateral_sweeps", {"offset": {"fy_per_Fz": 0.03, "fx_N": 25.0}})
    s = w[0]
    o = _base(model, s)
    zero = (np.abs(s.alpha) < 1e-9) & (np.abs(s.kappa) < 1e-9)
    assert zero.sum() > 100
    assert np.allclose((s.Fy - o.Fy)[zero], 0.03 * s.Fz[zero], atol=1e-6)
    assert np.allclose((s.Fx - o.Fx)[zero], 25.0, atol=1e-6)


def test_camber_thrust_grows_with_gamma(model):
    w, truth = _sim(model, "camber", {"camber": True})
    s = w[0]
    r = s.Fy - _base(model, s).Fy
    pauses = _segments(truth, "pause")
    per_deg = []
    for p in pauses:
        sl = _idx(p, 50.0)
        g = np.degrees(s.gamma[sl][0])
        if abs(g) > 0.5:
            per_deg.append(np.mean(r[sl]) / np.mean(s.Fz[sl]) / g)
    assert len(per_deg) >= 3
    assert np.allclose(per_deg, -0.026, rtol=0.15)  # saturating: a little less at 4 deg


def test_combined_changes_only_combined_slip(model):
    w, truth = _sim(model, "combined", {"combined": True})
    s = w[0]
    o = _base(model, s)
    pure = _idx(_segments(truth, "lateral_sweep")[0], 50.0)
    assert np.max(np.abs(s.Fy[pure] - o.Fy[pure])) < 1.0
    comb = _idx(_segments(truth, "combined_sweep")[1], 50.0)  # alpha = -4 deg
    assert np.max(np.abs(s.Fy[comb] - o.Fy[comb])) > 0.03 * model.params["FNOMIN"]


# ------------------------------------------------------------------ friction laws


def test_speed_friction_depends_on_speed_at_fixed_alpha(model):
    w, truth = _sim(model, "lateral_sweeps", {"speed_friction": True})
    s = w[0]
    ratio = s.Fy / _base(model, s).Fy
    segs = {x["label"]: _idx(x, 50.0) for x in _segments(truth, "lateral_sweep")}

    def at_8deg(sl):
        a = s.alpha[sl]
        return np.mean(ratio[sl][np.abs(np.abs(a) - 8 * DEG) < 0.5 * DEG])

    assert at_8deg(segs["lateral V=0.5V0"]) > at_8deg(segs["lateral Fz=1FNOMIN"]) + 0.02
    small = np.abs(s.alpha) < 0.3 * DEG  # adhesion: stiffness kept, friction law irrelevant
    dF = np.abs(s.Fy - _base(model, s).Fy)
    assert np.max(dF[small]) < 0.02 * model.params["FNOMIN"]


def test_wear_never_recovers(model):
    w, truth = _sim(model, "lateral_sweeps", {"wear": {"loss_per_km": 0.3}})
    mu = np.array(truth["wheels"]["/rig/wheel"]["hidden_trace"]["mu_factor"])
    assert np.all(np.diff(mu) <= 1e-12) and mu[-1] < 0.97
    s = w[0]
    o = _base(model, s)
    refs = [x for x in _segments(truth, "lateral_sweep") if x["label"].startswith("reference")]
    first, last = (_idx(x, 50.0) for x in (refs[0], refs[-1]))
    assert "after pause" in refs[-1]["label"]
    r1 = np.max(np.abs(s.Fy[first])) / np.max(np.abs(o.Fy[first]))
    r2 = np.max(np.abs(s.Fy[last])) / np.max(np.abs(o.Fy[last]))
    assert r2 < r1 - 0.01


def test_belt_stop_halts_the_belt_and_carries_the_friction_step(model):
    w, truth = _sim(
        model, "lateral_sweeps", {"mu_step": {"ratio": 0.9}}, programme_options={"stop_s": 20.0}
    )
    segs = truth["wheels"][w[0].prefix]["segments"]
    stop = next(g for g in segs if g["label"] == "belt stop")
    assert stop["t1_s"] - stop["t0_s"] == pytest.approx(20.0, abs=0.02)
    t = w[0].t - w[0].t[0]
    inside = (t > stop["t0_s"] + 0.1) & (t < stop["t1_s"] - 0.1)
    assert np.all(np.abs(w[0].Vx[inside]) < 0.2)  # belt-speed noise only
    at = truth["wheels"][w[0].prefix]["hidden_summary"]["mu_step_at_s"]
    assert at == pytest.approx(0.5 * (stop["t0_s"] + stop["t1_s"]), abs=0.01)


def test_mu_step_between_runs(model):
    w, _ = _sim(model, "camber", {"mu_step": {"ratio": 0.9, "at_s": 40.0}})
    s = w[0]
    big = np.abs(s.alpha) > 6 * DEG
    ratio = s.Fy / _base(model, s).Fy
    t = s.t - s.t[0]
    assert np.allclose(ratio[big & (t < 39)], 1.0, atol=1e-9)
    after = ratio[big & (t > 41)]
    assert 0.88 < after.mean() < 0.95


# ------------------------------------------------------------------ track


def test_track_four_wheels_with_load_transfer(model):
    w, truth = _sim(model, "track", {"heating": True}, rate=25.0)
    assert [x.prefix for x in w] == ["/car/fl", "/car/fr", "/car/rl", "/car/rr"]
    fl, fr = w[0], w[1]
    total = sum(x.Fz for x in w)
    assert np.allclose(total, total[0], rtol=0.01)  # load transfer conserves the weight
    left_turn = np.array([x["kind"] == "track" for x in truth["wheels"]["/car/fl"]["segments"]])
    assert left_turn.all()
    # in a left turn (Fy > 0 on the front axle) the right wheel carries more load
    turning = (fl.Fy + fr.Fy) > 0.3 * model.params["FNOMIN"]
    assert turning.sum() > 50 and np.all(fr.Fz[turning] > fl.Fz[turning])
    braking = fl.kappa < -0.01
    assert braking.sum() > 50 and np.all(fl.Fx[braking] < 0)


# ------------------------------------------------------------------ the CLI and the bag


def test_cli_writes_bag_and_truth_beside_it(tmp_path):
    from tire_model_ros.recording import read_recording

    bag = tmp_path / "run"
    args = [
        "simulate",
        "--tir",
        str(MF61_TIR),
        "--programme",
        "camber:rate_scale=2",
        "-o",
        str(bag),
        "--effect",
        "heating:T_opt_C=40",
        "--effect",
        "offset",
        "--omit",
        "temperature,velocity",
        "--seed",
        "3",
        "--rate",
        "20",
    ]
    assert cli_main(args) == 0
    tpath = truth_path(bag)
    assert tpath == tmp_path / "run.truth.json" and tpath.is_file()
    assert not any(p.name.endswith(".json") for p in bag.iterdir())
    truth = json.loads(tpath.read_text())
    assert truth["effects"]["heating"]["T_opt_C"] == 40.0
    assert truth["omitted"] == ["temperature", "velocity"] and truth["seed"] == 3
    assert truth["programme_options"]["rate_scale"] == 2.0
    rec = read_recording(bag)
    s = rec["/rig/wheel"]
    assert s.T is None and s.Vx is None and s.p is not None and len(s) > 500
    # the bag holds what simulate_session returns (same seed -> same content)
    wheels, _ = simulate_session(
        MF61_TIR,
        "camber",
        effects={"heating": {"T_opt_C": 40}, "offset": True},
        omit=["temperature", "velocity"],
        seed=3,
        rate_hz=20,
        programme_options={"rate_scale": 2},
    )
    assert np.allclose(s.Fy, wheels[0].Fy) and np.allclose(s.alpha, wheels[0].alpha)
    # refuses to overwrite without --force, overwrites with it
    assert cli_main(args) == 1
    assert cli_main([*args, "--force"]) == 0
    assert (
        cli_main(
            [
                "simulate",
                "--tir",
                str(MF61_TIR),
                "--programme",
                "camber",
                "-o",
                str(tmp_path / "x"),
                "--effect",
                "heating:bogus=1",
            ]
        )
        == 1
    )
    assert not (tmp_path / "x").exists()


def test_load_ripple_recorded_or_not(model):
    w, truth = _sim(model, "camber", {"load_ripple": {"amplitude": 0.03}})
    s = w[0]
    hs = truth["wheels"]["/rig/wheel"]["hidden_summary"]
    assert hs["Fz_true_max_N"] == pytest.approx(1.03 * model.params["FNOMIN"], rel=0.002)
    assert np.max(np.abs(s.Fy - _base(model, s).Fy)) < 1e-6  # recorded: the model explains it
    w2, _ = _sim(model, "camber", {"load_ripple": {"amplitude": 0.03, "recorded": 0}})
    s2 = w2[0]
    assert np.ptp(s2.Fz[:200]) == 0.0  # the load channel shows the set load only
    assert np.max(np.abs(s2.Fy - _base(model, s2).Fy)) > 0.005 * model.params["FNOMIN"]


def test_model_temperature_lets_the_files_terms_act(model):
    hot = model.with_params({"TTY3": -0.4, "NOMTEMP": 25.0})
    w, _ = _sim(hot, "camber", {"model_temperature": True})
    s = w[0]
    at_nominal = _base(hot, s).Fy
    at_sensor = hot.evaluate(s.Fz, s.kappa, s.alpha, s.gamma, s.Vx, s.p, s.T).Fy
    big = np.abs(s.alpha) > 5 * DEG
    err_nom = np.sqrt(np.mean((s.Fy - at_nominal)[big] ** 2))
    err_sensor = np.sqrt(np.mean((s.Fy - at_sensor)[big] ** 2))
    assert err_nom > 50.0 and err_sensor < 0.3 * err_nom  # the sensor lags the surface a bit


@pytest.mark.parametrize("name", ["flat_trac_nominal", "flat_trac_heating_hidden", "track_4wheels"])
def test_sample_bags_read_with_truth_beside(name):
    from tire_model_ros.recording import read_recording

    bag = ROOT / "bags" / name
    truth = json.loads(truth_path(bag).read_text())
    rec = read_recording(bag)
    assert sorted(rec) == sorted(truth["wheels"])
    for prefix, s in rec.items():
        assert (s.T is None) == ("temperature" in truth["omitted"]), prefix
        assert len(s) == round(truth["duration_s"] * truth["rate_hz"])
        assert np.all(np.isfinite(s.Fy)) and np.all(s.Fz > 0)


def test_effects_as_a_list_of_names_and_truth_words(model):
    _, truth = simulate_session(model, "camber", effects=["heating", "delay"], rate_hz=20)
    assert set(truth["effects"]) == {"noise", "heating", "delay"}
    assert truth["effect_words"] == {"noise": None, "heating": "temperature", "delay": "time_delay"}
    assert truth["effects"]["delay"] == {"tau_s": 0.02}


def test_transient_phase_lag_relaxation_vs_delay(model):
    """Relaxation: lag angle atan(w sigma / V) grows with frequency and at lower speed;
    delay: the same time lag at every frequency and speed."""

    def lag_s(s, o, sl, f):
        t = np.arange(sl.stop - sl.start) / 100.0
        basis = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])
        cm = np.linalg.lstsq(basis, o.Fy[sl] - o.Fy[sl].mean(), rcond=None)[0]
        cs = np.linalg.lstsq(basis, s.Fy[sl] - s.Fy[sl].mean(), rcond=None)[0]
        dphi = np.angle(cm[0] + 1j * cm[1]) - np.angle(cs[0] + 1j * cs[1])
        return ((dphi + np.pi) % (2 * np.pi) - np.pi) / (2 * np.pi * f)

    out = {}
    for eff in ({"relaxation": True}, {"delay": {"tau_s": 0.03}}):
        w, truth = _sim(model, "transient", eff, rate=100.0)
        s = w[0]
        o = _base(model, s)
        name = next(iter(eff))
        out[name] = {
            x["label"]: lag_s(s, o, _idx(x, 100.0), x["freq_hz"])
            for x in _segments(truth, "steer_sine")
        }
    d = out["delay"]
    assert all(abs(v - 0.03) < 0.003 for v in d.values())
    r = out["relaxation"]
    V = model.params["LONGVL"]
    sig = 0.5
    for f in (0.5, 2.0):
        expect = math.atan(2 * np.pi * f * sig / V) / (2 * np.pi * f)
        assert r[f"steer sine {f:g} Hz V=1V0"] == pytest.approx(expect, rel=0.2)
    assert r["steer sine 1 Hz V=0.5V0"] > 1.6 * r["steer sine 1 Hz V=1V0"]


@pytest.mark.parametrize("tir", ["FSAE_Defaults.tir", "citybus_tire_CityBus_Pac02Tire.tir"])
def test_every_programme_with_every_effect_stays_finite(tir):
    from tire_model_ros.rig import EFFECTS, PROGRAMMES

    m = TireModel.from_file(TIR_DIR / tir)
    for prog in PROGRAMMES:
        wheels, truth = simulate_session(
            m, prog, effects=list(EFFECTS), rate_hz=10, programme_options={"laps": 1}, omit=[]
        )
        for w in wheels:
            for ch in ("kappa", "alpha", "Fz", "p", "T", "Vx", "Fx", "Fy", "Mz"):
                assert np.all(np.isfinite(getattr(w, ch))), (tir, prog, w.prefix, ch)
        assert json.loads(json.dumps(truth))["programme"] == prog
