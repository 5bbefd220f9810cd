"""The hidden states of an improved model run forward (``model.states``): the node's form of
the diagnosis' effects. Real .tir file; no ROS."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import DEFAULT_TIR

from tire_model_ros.diagnosis.dynamics import first_order, thermal_state_K
from tire_model_ros.model import TireModel
from tire_model_ros.model.states import (
    Carcass,
    Effects,
    EffectsError,
    EffectState,
    Node,
    Sidewall,
    WheelEffects,
    contact_alpha,
    deflection_pressure_weight,
    relative_deflection,
    sidewall_factor,
)

FULL = WheelEffects(
    T_amb_C=20.0,
    thermal=Node(3.0, 2e-3),
    thermal_slow=Node(120.0, 1e-3),
    thermal_slow_start_K=6.0,
    stiffness_per_K=-0.01,
    gas=Node(60.0, 1e-3),
    gas_start_K=3.0,
    offsets={"Fy": (12.0, 150.0), "Mz": (-1.5, 0.0)},
    alpha_shift_rad=0.002,
    T_lag_s=30.0,
    T_surface_weight=0.5,
    T_carcass=Carcass(200.0, 4.0, -0.002, 45.0),
    grip_table=((20.0, 40.0, 60.0), (1.05, 1.0, 0.9)),
    speed_table=((-2.0, 0.0, 1.0), (0.8, 1.0, 0.9)),
    sidewall=Sidewall(1.5, 0.1, 2.0, 0.4, 0.03, 0.05),
)


def test_nodes_step_as_the_diagnosis_integrates_them():
    """Driven by the power of its outputs, each node follows the diagnosis' exact-step
    integration (thermal_state_K) sample for sample, on uneven stamps with a pause."""
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.005, 0.03, 400))
    t[200:] += 5.0  # a pause
    P = rng.uniform(0.0, 4000.0, 400)
    fx = WheelEffects(
        thermal=Node(2.5, 3e-3),
        thermal_slow=Node(90.0, 2e-3),
        thermal_slow_start_K=4.0,
        gas=Node(40.0, 5e-4),
        gas_start_K=7.0,  # pre-warmed
    )
    st = EffectState(fx)
    got = {k: [] for k in ("thermal", "thermal_slow", "gas")}
    for ti, Pi in zip(t, P, strict=True):
        st.inputs(float(ti), 0.1, 0.0, 10.0, 30.0, 2.5e5, 2.6e5, 25.0)
        for k in got:
            got[k].append(st.y[k])
        st.outputs((Pi, 0.0, 5000.0, 0.0, 0.0, 0.0), 1.0, 5000.0, 0.1, 0.0, 10.0, 5000.0)
    for k in got:  # |Fx V kappa| = P with V kappa = 1
        node = getattr(fx, k)
        y0 = {"thermal_slow": fx.thermal_slow_start_K, "gas": fx.gas_start_K}.get(k, 0.0)
        want = first_order(node.gain_per_W * P, t, node.tau_s, y0)
        np.testing.assert_allclose(got[k], want, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(  # the diagnosis' node from rest is the same integration
        thermal_state_K(P, t, 2.5, 3e-3), first_order(3e-3 * P, t, 2.5), rtol=0, atol=0
    )


def test_inputs_and_outputs_follow_the_effects():
    """Measured channels pass; missing ones take the hidden nodes (tread plus carcass); the
    ply-steer shift adds to alpha; friction scales by the similarity method; Fy takes the
    sidewall factor of the sample's deflection; offsets add, their load part in proportion
    to Fz / FNOMIN."""
    model = TireModel.from_file(DEFAULT_TIR)
    st = EffectState(FULL)
    st.y.update(thermal=15.0, thermal_slow=5.0, gas=8.0)
    st.t_last = 1.0
    kappa, alpha, Vx, Fz = 0.04, math.radians(9.0), 12.0, 5000.0
    st.P_last = 0.0  # no heating over the next step: the states only decay
    k, a, T, p, s = st.inputs(1.0, kappa, alpha, Vx, None, None, 2.6e5, 25.0, Fz / 3000.0)
    assert T == 20.0 + 15.0 + 5.0
    assert p == pytest.approx((2.6e5 + 101325.0) * (293.15 + 8.0) / 293.15 - 101325.0)
    a_in = alpha + 0.002
    stiff = 1.0 - 0.01 * 5.0  # the carcass' stiffness loss on the slips
    k_in, tan_in = kappa * stiff, math.tan(a_in) * stiff
    Vs = Vx * math.hypot(k_in, tan_in)
    s_want = float(np.interp(math.log(Vs), [-2.0, 0.0, 1.0], [0.8, 1.0, 0.9]))
    assert s == pytest.approx(s_want, rel=1e-12)
    assert (k, math.tan(a)) == pytest.approx((k_in / s, tan_in / s), rel=1e-12)
    assert st.inputs(1.0, kappa, alpha, Vx, 42.0, 2.2e5, 2.6e5, 25.0)[2:4] == (42.0, 2.2e5)
    k, a, T, p, s = st.inputs(1.0, kappa, alpha, Vx, None, 1.0e5, 2.6e5, 25.0, Fz / 3000.0)
    raw = model.evaluate_one(Fz, k, a, 0.0, Vx, p, T)
    out = st.outputs(raw, s, Fz, kappa, alpha, Vx, 3000.0)
    rho = (Fz / 3000.0) / ((1.0e5 + 101325.0) / (2.6e5 + 101325.0))
    side = sidewall_factor(rho, a_in, FULL.sidewall)
    assert side < 0.95  # deflected past the threshold, beyond alpha_c: the drop acts
    assert out[0] == pytest.approx(raw[0] * s)
    assert out[1] == pytest.approx(raw[1] * s * side + 12.0 + 150.0 * Fz / 3000.0)
    assert out[5] == pytest.approx(raw[5] * s - 1.5)
    assert out[2:5] == raw[2:5]
    assert st.P_last == pytest.approx(abs(out[0] * Vx * kappa) + abs(out[1] * Vx * math.tan(alpha)))
    st.outputs((math.nan,) * 6, 1.0, Fz, kappa, alpha, Vx, 3000.0)
    assert math.isfinite(st.P_last)  # a bad sample does not poison the states
    st.idle(2.0)  # off the ground: the last power is held over this step, then none
    y0 = st.y["thermal"]
    assert st.P_last == 0.0
    st.idle(5.0)
    assert st.y["thermal"] == pytest.approx(y0 * math.exp(-3.0 / 3.0), rel=1e-12)


def test_one_absurd_sample_leaves_no_trace_and_the_states_stay_bounded():
    """kappa = -1e6 once (what drove the tread to 2e213 degC): marked as not driving, it steps
    the nodes with the power held from before, so the states after it are those of a run
    without it; driving, its power is bounded and the nodes stay within their bound."""
    from tire_model_ros.model.states import MAX_POWER_W, MAX_RISE_K

    model = TireModel.from_file(DEFAULT_TIR)
    fx = WheelEffects(thermal=Node(4.0, 5e-3), thermal_slow=Node(60.0, 2e-5))
    t = np.arange(200) * 0.01
    slips = 0.1 * np.sin(t * 3.0)

    def run(absurd: bool, drive: bool) -> tuple[list[tuple[float, ...]], EffectState]:
        st, rows = EffectState(fx), []
        for i, (ti, k) in enumerate(zip(t, slips, strict=True)):
            if i == 100 and absurd:  # between samples 99 and 100
                out = st.evaluate(model, ti - 0.005, 5000.0, -1e6, 0.05, 0.0, 15.0,
                                  None, None, 2.6e5, 25.0, 6752.0, drive=drive)  # fmt: skip
                assert all(math.isfinite(v) for v in out)
            rows.append(st.evaluate(model, float(ti), 5000.0, float(k), 0.05, 0.0, 15.0,
                                    None, None, 2.6e5, 25.0, 6752.0))  # fmt: skip
        return rows, st

    clean, st_clean = run(False, True)
    skipped, st_skipped = run(True, False)
    np.testing.assert_allclose(skipped, clean, rtol=1e-12, atol=1e-9)
    assert st_skipped.y == pytest.approx(st_clean.y, rel=1e-12)
    driven, st_driven = run(True, True)
    assert np.all(np.isfinite(driven)) and all(abs(y) <= MAX_RISE_K for y in st_driven.y.values())
    assert st_driven.temperature_C < 25.0 + 2 * MAX_RISE_K
    lag = EffectState(WheelEffects(T_lag_s=2.0))  # a measured temperature through its lag
    ref = EffectState(WheelEffects(T_lag_s=2.0))
    for i in range(30):
        if i == 15:  # 500 degC once, between two samples, not driving: no trace in the lag
            lag.inputs(i - 0.5, 0.1, 0.0, 10.0, 500.0, None, 2.6e5, 25.0, drive=False)
        T = lag.inputs(float(i), 0.1, 0.0, 10.0, 30.0 + i, None, 2.6e5, 25.0)[2]
        T_ref = ref.inputs(float(i), 0.1, 0.0, 10.0, 30.0 + i, None, 2.6e5, 25.0)[2]
        assert abs(T - T_ref) <= 1e-12 * abs(T_ref)
    st = EffectState(fx)  # a power of 1e300 W: bounded drive, bounded states
    for i in range(50):
        st.inputs(float(i), 0.1, 0.0, 10.0, None, None, 2.6e5, 25.0)
        st.outputs((1e300, 0.0, 5000.0, 0.0, 0.0, 0.0), 1.0, 5000.0, 0.1, 0.0, 10.0, 5000.0)
        assert st.P_last <= MAX_POWER_W and abs(st.y["thermal"]) <= MAX_RISE_K


def test_a_speed_table_relative_to_the_reference_speed_leaves_the_file_there():
    """A table relative to the file's reference speed V0 scales friction by mu(V |s|) /
    mu(V0 |s|): 1 at V0 whatever the slip, the table's ratio elsewhere."""
    table = ((-2.0, 0.0, 1.0), (1.1, 1.0, 0.8))
    fx = WheelEffects(speed_table=table, speed_reference_mps=11.0)
    kappa, alpha = 0.05, math.radians(4.0)
    slip = math.hypot(kappa, math.tan(alpha))
    for V in (11.0, 20.0, 5.0):
        st = EffectState(fx)
        s = st.inputs(0.0, kappa, alpha, V, 60.0, 2.0e5, 2.0e5, 25.0)[4]
        g = [float(np.interp(math.log(v * slip), table[0], table[1])) for v in (V, 11.0)]
        assert s == pytest.approx(g[0] / g[1], rel=1e-12)
    assert s > 1.0  # slower: slides slower, on the rising side of this table
    doc = Effects({"/w": fx}).to_json()
    assert Effects.from_dict(json.loads(doc)).wheels["/w"].speed_reference_mps == 11.0


def test_effects_file_round_trip(tmp_path):
    fx = Effects({"/rig/wheel": FULL}, "improved.tir", ("drift: friction step at a fitted time",))
    path = tmp_path / "improved.effects.json"
    path.write_text(fx.to_json())
    back = Effects.read(path)
    assert back == fx
    assert back.for_wheel("/car/fl") == FULL  # a one-wheel (rig) file serves every wheel
    two = Effects({"/a": FULL, "/b": WheelEffects()})
    assert two.for_wheel("/c") is None
    doc = json.loads(fx.to_json())  # version 3: the gas node started at ambient
    del doc["wheels"]["/rig/wheel"]["gas"]["start_K"]
    doc["version"] = 3
    assert Effects.from_dict(doc).wheels["/rig/wheel"].gas_start_K == 0.0


def test_sidewall_loss_saturates_at_its_depth_and_older_files_read_as_fitted(tmp_path):
    """The drop grows at drop_per_rad beyond alpha_c and levels off at depth (a share of Fy),
    gated by the deflection over a fitted width; a file written before depth and the width
    were fitted reads as the unbounded linear loss behind a 5 % gate it was fitted as."""
    alpha = np.radians(np.array([4.0, 6.0, 8.0, 20.0, 60.0]))
    rho = np.full(alpha.shape, 3.0)  # far past the threshold: the gate is open
    f = sidewall_factor(rho, alpha, Sidewall(1.5, np.radians(6.0), 2.0, 0.3))
    assert f[:2] == pytest.approx([1.0, 1.0])  # not beyond alpha_c
    u = np.radians(2.0)
    assert 1.0 - f[2] == pytest.approx(0.3 * (1.0 - math.exp(-2.0 * u / 0.3)))
    assert 1.0 - f[2] == pytest.approx(2.0 * u, rel=0.15)  # at first: about drop per rad
    assert np.all(np.diff(f[2:]) < 0.0) and f[-1] == pytest.approx(0.7, abs=1e-3)
    linear = sidewall_factor(rho, alpha, Sidewall(1.5, np.radians(6.0), 2.0))
    assert linear[2] == pytest.approx(1.0 - 2.0 * u) and linear[-1] == 0.0
    near = np.array([1.4, 1.45, 1.55, 1.6])  # the gate's width decides how far it leaks
    soft, sharp = (
        sidewall_factor(near, alpha[-1], Sidewall(1.5, np.radians(6.0), 2.0, 0.3, w))
        for w in (0.05, 0.005)
    )
    assert (
        1.0 - soft[0] > 0.05 and 1.0 - sharp[0] < 1e-4 and sharp[-1] == pytest.approx(0.7, abs=1e-3)
    )
    doc = json.loads(Effects({"/w": FULL}).to_json())
    assert doc["wheels"]["/w"]["sidewall"]["depth"] == 0.4
    for key in ("depth", "gate_width", "alpha_c_per_rho"):
        del doc["wheels"]["/w"]["sidewall"][key]
    doc["version"] = 2  # as the diagnosis wrote it before
    path = tmp_path / "old.effects.json"
    path.write_text(json.dumps(doc))
    side = Effects.read(path).wheels["/w"].sidewall
    assert side == (1.5, 0.1, 2.0, math.inf, 0.05, 0.0, None)
    again = json.loads(Effects({"/w": WheelEffects(sidewall=side)}).to_json())
    assert "depth" not in again["wheels"]["/w"]["sidewall"]  # JSON has no inf: left out


def test_sidewall_deflection_follows_the_files_vertical_stiffness_law():
    """The deflection is the load over the MF 6.1 vertical stiffness Cz0 (1 + PFZ1 dpi): the
    file's PFZ1 is carried in the effects file (version 5) and the node's state uses it; a
    file without PFZ1, or an effects file before version 5, weighs the pressure by the air's
    share (a stiffness proportional to the absolute pressure), as it was fitted with."""
    p_nom, atm = 260e3, 101325.0
    assert deflection_pressure_weight({"PFZ1": 0.88}) == 0.88
    assert (
        deflection_pressure_weight({"PFZ1": 0.0}) is None and deflection_pressure_weight({}) is None
    )
    rho = relative_deflection(1.2, 1.0, 140e3, p_nom, 0.88)
    assert rho == pytest.approx(1.2 / (1.0 + 0.88 * (140e3 - p_nom) / p_nom))
    air = relative_deflection(1.2, 1.0, 140e3, p_nom, None)
    assert air == pytest.approx(1.2 / ((140e3 + atm) / (p_nom + atm)))  # the law before 5
    sw = Sidewall(1.9, 0.05, 3.0, 0.3, 0.01, 0.0, 0.88)
    doc = json.loads(Effects({"/w": WheelEffects(sidewall=sw)}).to_json())
    assert doc["wheels"]["/w"]["sidewall"]["deflection_pressure_weight"] == 0.88
    assert Effects.from_dict(doc).wheels["/w"].sidewall == sw
    old = json.loads(json.dumps(doc))
    del old["wheels"]["/w"]["sidewall"]["deflection_pressure_weight"]
    old["version"] = 4
    # Between the two laws' deflections at 140 kPa, 120 % load (2.02 and 1.80): the gate
    # opens with the file's law, stays shut with the air's share.
    for fx, opened in ((Effects.from_dict(doc), True), (Effects.from_dict(old), False)):
        state = EffectState(fx.wheels["/w"])
        state.inputs(0.0, 0.0, 0.2, 10.0, 25.0, 140e3, p_nom, 25.0, 1.2)
        assert (state._rho > sw.threshold) == opened, state._rho


def test_sidewall_meets_the_road_at_a_smaller_slip_angle_the_more_the_tyre_is_deflected():
    """alpha_c holds at the threshold deflection and falls by alpha_c_per_rho per unit of
    deflection past it (never below 0); a version 3 file (alpha_c fixed) reads with 0."""
    sw = Sidewall(1.5, 0.15, 3.0, 0.2, 0.01, 0.1)
    rho = np.array([1.5, 1.7, 2.0, 4.0])
    assert contact_alpha(rho, sw) == pytest.approx([0.15, 0.13, 0.10, 0.0])
    alpha = np.full(rho.shape, 0.14)  # beyond the contact angle only once deflected past 1.6
    f = sidewall_factor(rho, alpha, sw)
    assert f[0] == pytest.approx(1.0, abs=1e-6) and np.all(np.diff(f) < 0.0)
    fixed = sidewall_factor(rho, alpha, sw._replace(alpha_c_per_rho=0.0))
    assert np.all(fixed > 1.0 - 1e-6)  # alpha_c fixed: 0.14 rad never reaches it
    doc = json.loads(Effects({"/w": WheelEffects(sidewall=sw)}).to_json())
    assert doc["version"] == 8 and doc["wheels"]["/w"]["sidewall"]["alpha_c_per_rho"] == 0.1
    del doc["wheels"]["/w"]["sidewall"]["alpha_c_per_rho"]
    doc["version"] = 3
    assert Effects.from_dict(doc).wheels["/w"].sidewall == sw._replace(alpha_c_per_rho=0.0)


@pytest.mark.parametrize(
    ("mangle", "words"),
    [
        (lambda d: d.update(format="x"), ["format"]),
        (lambda d: d.update(version=9), ["version"]),
        (lambda d: d["wheels"]["/w"]["T_carcass"].pop("start_K"), ["T_carcass.start_K"]),
        (lambda d: d["wheels"]["/w"]["T_carcass"].update(tau_s=-1), ["T_carcass.tau_s"]),
        (lambda d: d.update(wheels={}), ["wheels"]),
        (lambda d: d["wheels"]["/w"]["thermal"].update(tau_s=-1.0), ["wheels./w.thermal.tau_s"]),
        (lambda d: d["wheels"]["/w"]["thermal_slow"].pop("start_K"), ["thermal_slow.start_K"]),
        (lambda d: d["wheels"]["/w"].update(bulk={"tau_s": 1}), ["wheels./w.bulk"]),
        (lambda d: d["wheels"]["/w"]["sidewall"].pop("drop_per_rad"), ["sidewall.drop_per_rad"]),
        (lambda d: d["wheels"]["/w"]["sidewall"].update(depth=1.5), ["sidewall.depth"]),
        (lambda d: d["wheels"]["/w"]["sidewall"].update(gate_width=0), ["sidewall.gate_width"]),
        (
            lambda d: d["wheels"]["/w"]["sidewall"].update(deflection_threshold=0),
            ["sidewall.deflection_threshold"],
        ),
        (
            lambda d: d["wheels"]["/w"]["sidewall"].update(deflection_pressure_weight=-0.5),
            ["sidewall.deflection_pressure_weight"],
        ),
        (lambda d: d["wheels"]["/w"].update(alpha_shift_rad="x"), ["alpha_shift_rad"]),
        (lambda d: d["wheels"]["/w"].update(T_surface_weight=-0.1), ["T_surface_weight"]),
        (lambda d: d["wheels"]["/w"]["grip_table"].update(T_C=[1, 0, 2]), ["grip_table", "T_C"]),
        (lambda d: d["wheels"]["/w"]["grip_table"].update(mu=[1, 0, 1]), ["grip_table"]),
        (lambda d: d["wheels"]["/w"]["offsets"].update(Fq={"N": 1}), ["offsets.Fq"]),
        (lambda d: d["wheels"]["/w"]["speed_table"].update(ln_Vs=[1, 0, 2]), ["speed_table"]),
        (lambda d: d["wheels"]["/w"]["speed_table"].update(mu=[1, -1, 1]), ["speed_table"]),
        (
            lambda d: d["wheels"]["/w"]["speed_table"].update(reference_V_mps=-1.0),
            ["speed_table.reference_V_mps"],
        ),
        (lambda d: d["wheels"]["/w"].update(T_amb_C="hot"), ["T_amb_C"]),
        (lambda d: d["wheels"]["/w"].update(offsets=[1, 2]), ["wheels./w.offsets"]),
        (lambda d: d.update(not_carried=5), ["not_carried"]),
        (lambda d: d["wheels"]["/w"]["gas"].update(gain_per_W=float("nan")), ["gas.gain_per_W"]),
    ],
)
def test_malformed_effects_file_names_file_and_key(tmp_path, mangle, words):
    doc = json.loads(Effects({"/w": FULL}).to_json())
    mangle(doc)
    path = tmp_path / "bad.effects.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(EffectsError) as err:
        Effects.read(path)
    assert str(path) in str(err.value)
    for w in words:
        assert w in str(err.value)


def test_unreadable_effects_file(tmp_path):
    for path, text in ((tmp_path / "garbage.json", "{not json"), (tmp_path / "none.json", None)):
        if text is not None:
            path.write_text(text)
        with pytest.raises(EffectsError, match=path.name):
            Effects.read(path)


def test_a_measured_temperature_is_lagged_as_the_diagnosis_lags_it():
    """T_lag_s: the node feeds the model the measured temperature through the first-order lag
    the diagnosis fitted (diagnosis.dynamics.first_order from the first sample), sample for
    sample on uneven stamps."""
    rng = np.random.default_rng(2)
    t = np.cumsum(rng.uniform(0.005, 0.03, 300))
    T = 40.0 + np.cumsum(rng.normal(0.0, 0.5, 300))
    st = EffectState(WheelEffects(T_lag_s=20.0))
    got = [
        st.inputs(float(ti), 0.0, 0.0, 10.0, float(Ti), None, 2.6e5, 25.0)[2]
        for ti, Ti in zip(t, T, strict=True)
    ]
    np.testing.assert_allclose(got, first_order(T, t, 20.0, float(T[0])), rtol=1e-12)
    assert np.std(got) < 0.5 * np.std(T)  # lagged, not passed through


def test_the_stiffness_falls_with_a_measured_temperatures_carcass_and_round_trips():
    """T_carcass: the slips the model sees are scaled by 1 + c (carcass - reference), the
    carcass the measured temperature through its own lag from a start above the first sample
    (a tyre brought warm), as the diagnosis integrates it; the grip's temperature is apart
    (here the surface itself); the file keeps it (version 8); a version 7 file reads without
    it."""
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.005, 0.03, 300))
    T = 40.0 + np.cumsum(rng.normal(0.0, 0.5, 300))
    fx = WheelEffects(T_carcass=Carcass(20.0, 6.0, -0.004, 40.0))
    st = EffectState(fx)
    got = np.array([
        st.inputs(float(ti), 0.05, 0.1, 10.0, float(Ti), None, 2.6e5, 25.0)[:3]
        for ti, Ti in zip(t, T, strict=True)
    ])  # fmt: skip
    k = 1.0 - 0.004 * (first_order(T, t, 20.0, float(T[0]) + 6.0) - 40.0)
    np.testing.assert_allclose(got[:, 0], 0.05 * k, rtol=1e-12)
    np.testing.assert_allclose(np.tan(got[:, 1]), np.tan(0.1) * k, rtol=1e-12)
    np.testing.assert_allclose(got[:, 2], T, rtol=1e-12)  # the grip feels the surface
    assert np.ptp(k) > 0.005
    doc = json.loads(Effects({"/w": fx}).to_json())
    assert doc["version"] == 8 and doc["wheels"]["/w"]["T_carcass"]["start_K"] == 6.0
    assert Effects.from_dict(doc).wheels["/w"] == fx
    del doc["wheels"]["/w"]["T_carcass"]
    doc["version"] = 7
    assert Effects.from_dict(doc).wheels["/w"] == WheelEffects()


def test_a_measured_surface_temperature_is_blended_with_its_lag_and_the_weight_round_trips():
    """T_surface_weight w: the grip feels w of the measured (surface) temperature at once and
    the rest through the lag, and its friction follows that temperature through the grip
    table; the file keeps both (since version 7) and refuses a w outside [0, 1]; a version 6 file
    (the lag alone) reads with w = 0 and no table."""
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.005, 0.03, 300))
    T = 40.0 + np.cumsum(rng.normal(0.0, 0.5, 300))
    table = ((38.0, 40.0, 42.0), (1.1, 1.0, 0.8))
    fx = WheelEffects(T_lag_s=20.0, T_surface_weight=0.4, grip_table=table)
    st = EffectState(fx)
    got = np.array([
        st.inputs(float(ti), 0.0, 0.0, 10.0, float(Ti), None, 2.6e5, 25.0)[2:5:2]
        for ti, Ti in zip(t, T, strict=True)
    ])  # fmt: skip
    want = 0.4 * T + 0.6 * first_order(T, t, 20.0, float(T[0]))
    np.testing.assert_allclose(got[:, 0], want, rtol=1e-12)
    np.testing.assert_allclose(got[:, 1], np.interp(want, *table), rtol=1e-12)
    assert np.ptp(got[:, 1]) > 0.1
    doc = json.loads(Effects({"/w": fx}).to_json())
    assert doc["version"] == 8 and doc["wheels"]["/w"]["T_surface_weight"] == 0.4
    assert doc["wheels"]["/w"]["grip_table"] == {"T_C": [38.0, 40.0, 42.0], "mu": [1.1, 1.0, 0.8]}
    assert Effects.from_dict(doc).wheels["/w"] == fx
    doc["wheels"]["/w"]["T_surface_weight"] = 1.5
    with pytest.raises(EffectsError, match="T_surface_weight"):
        Effects.from_dict(doc)
    del doc["wheels"]["/w"]["T_surface_weight"], doc["wheels"]["/w"]["grip_table"]
    doc["version"] = 6
    assert Effects.from_dict(doc).wheels["/w"] == WheelEffects(T_lag_s=20.0)
