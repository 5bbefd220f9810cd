"""Mismatch diagnosis on virtual-rig recordings: names the physics the model leaves out.

Real parts only: the rig (its own two-node thermal physics, relaxation, noise), real .tir files,
a real bag written and read back, and the CLI in a subprocess.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess

import numpy as np
import pytest
from conftest import MF61_TIR, ROOT, TOOL

from tire_model_ros.diagnosis import Diagnosis, diagnose
from tire_model_ros.diagnosis.dynamics import relaxed_slip, thermal_state_K
from tire_model_ros.diagnosis.evidence import (
    agree_doing,
    beats_control,
    compare,
    region_gains,
    rms,
    supported,
)
from tire_model_ros.diagnosis.fitting import Score, merge
from tire_model_ros.diagnosis.folds import SPLIT, rare_folds
from tire_model_ros.diagnosis.result import MZ_COEFS
from tire_model_ros.model import TireModel
from tire_model_ros.model.states import Effects
from tire_model_ros.rig import simulate_session
from tire_model_ros.vocabulary import EFFECT_WORDS, TOLD_APART_BY


def _session(model, effects, omit=(), seed=3):
    wheels, truth = simulate_session(
        model, "lateral_sweeps", effects=effects, omit=list(omit), seed=seed
    )
    return wheels, truth


def _check_json(doc: dict) -> None:
    """The INTERFACE.md diagnosis object, field by field."""
    assert set(doc) >= {"effects", "fit"}
    assert doc["effects"], "effects is never empty ('none' when nothing is found)"
    for e in doc["effects"]:
        assert e["name"] in EFFECT_WORDS
        assert isinstance(e["concealed"], bool)
        assert e["channel"] in ("Fx", "Fy", "Mz")
        assert isinstance(e["where"], str) and e["where"]
        assert isinstance(e["evidence"], str) and e["evidence"]
        assert all(isinstance(k, str) and isinstance(v, float) for k, v in e["parameters"].items())
    names = [e["name"] for e in doc["effects"]]
    assert ("none" not in names) or names == ["none"]
    fit = doc["fit"]
    assert set(fit) == {"baseline", "improved", "heldout_baseline", "heldout_improved"}
    for block in ("baseline", "improved"):
        for ch in ("Fx", "Fy"):
            assert fit[block][ch]["rmse"] >= 0.0 and 0.0 <= fit[block][ch]["nrmse"] < 1.0
    for block in ("heldout_baseline", "heldout_improved"):
        for ch in ("Fx", "Fy"):
            assert fit[block][ch]["rmse"] >= 0.0
    json.dumps(doc, allow_nan=False)  # strict JSON: no NaN/inf


def test_hidden_states_are_first_order_and_recover():
    """The diagnosis' own states: a thermal node cools back, a lag vanishes at sigma -> 0."""
    t = np.arange(0.0, 100.0, 0.01)
    P = np.where(t < 20.0, 1000.0, 0.0)
    T = thermal_state_K(P, t, 5.0, 0.01)
    assert T[1999] == pytest.approx(10.0 * (1 - np.exp(-20.0 / 5.0)), rel=1e-3)
    assert T[-1] < 1e-3 * T[1999]  # recovers after the pause (wear would not)
    a = np.sin(t)
    lag = relaxed_slip(a, t, np.full_like(t, 10.0), 0.5)
    # First order in distance: phase lag atan(omega sigma / V) at omega = 1 rad/s.
    assert np.argmax(lag[:700]) - np.argmax(a[:700]) == pytest.approx(5, abs=1)
    assert np.allclose(relaxed_slip(a, t, np.full_like(t, 10.0), 0.0), a)


@pytest.fixture(scope="module")
def heated(model):
    """A heating tyre with no temperature channel, and its diagnosis (two tests read it)."""
    wheels, _truth = _session(model, {"heating": True}, omit=["temperature"])
    return wheels, diagnose(wheels, model, seed=0)


def test_concealed_temperature_is_named_first_and_halves_heldout_error(model, heated):
    wheels, diag = heated
    assert all(w.T is None for w in wheels)
    assert isinstance(diag, Diagnosis)
    first = diag.effects[0]
    assert first.name == "temperature", diag.details["log"]
    assert first.concealed is True
    assert first.parameters["tau_fast_s"] > 0 and np.isfinite(first.uncertainty["tau_fast_s"])
    fit = diag.fit
    assert fit["heldout_improved"]["Fy"]["rmse"] <= 0.5 * fit["heldout_baseline"]["Fy"]["rmse"]
    # Mz, refitted on each model's forces (Q*Z only), follows the better forces (without the
    # refit the heated model's held-out Mz was 6.8 N m against the baseline's 4.6; the carcass'
    # stiffness loss acts as a slip scaling, which the trail feels too: 15 % better, not 20)
    assert fit["heldout_improved"]["Mz"]["rmse"] < 0.9 * fit["heldout_baseline"]["Mz"]["rmse"]
    qz = {k: model.params[k] for k in MZ_COEFS}
    assert any(diag.improved_model.params[k] != v for k, v in qz.items())
    grid = dict(Fz=np.full(50, 4000.0), kappa=np.linspace(-0.2, 0.2, 50), alpha=np.linspace(
        -0.2, 0.2, 50), gamma=0.0, Vx=16.7)  # fmt: skip
    a = diag.improved_model.evaluate(**grid)
    b = diag.improved_model.with_params(qz).evaluate(**grid)
    np.testing.assert_array_equal(a.Fy, b.Fy)  # the forces stay as selected
    np.testing.assert_array_equal(a.Fx, b.Fx)
    assert not np.allclose(a.Mz, b.Mz)
    # The inferred temperature rises with the energy put in and is reported per wheel.
    prefix = wheels[0].prefix
    T = diag.inferred[prefix]["T"]
    assert T.shape == wheels[0].t.shape and np.ptp(T) > 1.0
    assert diag.heldout_mask[prefix].any() and diag.train_mask[prefix].any()
    assert not (diag.heldout_mask[prefix] & diag.train_mask[prefix]).any()
    assert set(diag.predictions[prefix]) >= {"baseline_Fy", "improved_Fy"}
    _check_json(diag.to_json())
    # The effects file carries the grip against the temperature (a table; the .tir's
    # quadratic stays the file's) and the hidden tread node (the node runs them when no
    # temperature topic is fresh).
    assert diag.improved_model.params["TTY3"] == model.params["TTY3"]
    fx = diag.node_effects().for_wheel(prefix)
    assert fx.grip_table is not None and len(fx.grip_table[0]) == 6  # ambient and 5 percentiles
    assert min(fx.grip_table[1]) < 1.0 or max(fx.grip_table[1]) > 1.0
    assert fx.thermal.tau_s == pytest.approx(first.parameters["tau_fast_s"])
    assert fx.thermal.gain_per_W == first.parameters["gain_K_per_W"] > 0
    assert fx.thermal_slow.tau_s == pytest.approx(first.parameters["tau_slow_s"])


def test_a_twin_scores_the_models_on_the_channels_the_recording_has(model, heated):
    """A virtual rig's twin carries the true temperature and pressure, which a recording may
    conceal. Replayed on the twin, the models must see only what the diagnosis saw: given
    the twin's true pressure, the file's pressure terms would run on a concealed leak and
    what they make of it would count as model error (brush pressure_leak s36: the floor
    39 N, above the baseline's 24 N held-out RMSE; without the hidden channels 16 N)."""
    from tire_model_ros.diagnosis.result import reference_context

    wheels, diag = heated
    twin, _ = _session(model, {"heating": True, "noise": False})
    assert twin[0].T is not None and twin[0].p is not None
    wd = diag.wheels[wheels[0].prefix]
    ref = reference_context(wd, twin[0])
    assert ref.wheel.inputs["T"] is None  # concealed in the recording
    np.testing.assert_allclose(ref.wheel.inputs["p"], twin[0].p)  # recorded: the twin's
    concealed = dataclasses.replace(wd, ctx=dataclasses.replace(
        wd.ctx, wheel=dataclasses.replace(wd.ctx.wheel, inputs={**wd.ctx.wheel.inputs, "p": None})
    ))  # fmt: skip
    assert reference_context(concealed, twin[0]).wheel.inputs["p"] is None


def test_relaxation_is_named(model):
    wheels, _ = _session(model, {"relaxation": True})
    diag = diagnose(wheels, model, seed=0)
    names = [e.name for e in diag.effects]
    assert names[0] == "relaxation", diag.details["log"]
    assert 0.1 < diag.effects[0].parameters["sigma_alpha_m"] < 2.0
    assert "none" not in names
    # a look-alike is never a named word, and what it explained alone is a share
    assert diag.look_alikes.keys().isdisjoint(names), diag.look_alikes
    assert all(0.0 < v <= 1.0 for v in diag.look_alikes.values()), diag.look_alikes
    fit = diag.fit
    assert fit["heldout_improved"]["Fy"]["rmse"] < fit["heldout_baseline"]["Fy"]["rmse"]


def test_delay_is_told_from_relaxation(model):
    """The confuser of relaxation: the same lag at every speed and load is a time delay."""
    wheels, _ = _session(model, {"delay": True})
    diag = diagnose(wheels, model, seed=0)
    assert diag.effects[0].name == "time_delay", diag.details["log"]
    # A relaxation is a lag too: alone it explains much of a delay, beside it nothing; the
    # diagnosis says the recording does not tell the two apart there, in text and JSON.
    assert diag.look_alikes.get("relaxation", 0.0) > 0.3, diag.details["log"]
    # ... and what would tell them apart (the speed)
    assert {
        "name": "relaxation",
        "explained_alone": diag.look_alikes["relaxation"],
        "told_apart_by": TOLD_APART_BY["relaxation"],
    } in diag.to_json()["look_alikes"]
    assert "two speeds" in TOLD_APART_BY["relaxation"]
    # A pure delay and the DAQ filter's lag add at low frequency: the rig's 20 ms in all.
    p = diag.effects[0].parameters
    assert p["tau_delay_s"] + p["tau_filter_s"] == pytest.approx(0.02, abs=0.005)


def test_delay_models_the_load_on_the_forces_clock_only_where_the_load_moves(model):
    """A wheel-force transducer's Fz is late with its Fx and Fy, a rig's commanded load is
    not: where the load moves within a delay's span both models are tried, and the one with
    the load on the forces' clock leaves the recorded load as it is; on a rig's held load the
    two are the same model, and only one is tried."""
    from tire_model_ros.diagnosis.effects.transient import Delay
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    wheels, _ = _session(model, {"delay": True})
    w = wheels[0]
    held = make_context(prepare_wheel(w, model, np.random.default_rng(0)), model)
    assert [m.load_with_forces for m in Delay.propose(held)] == [False]
    moving = dataclasses.replace(w, Fz=w.Fz * (1.0 + 0.1 * np.sin(2 * np.pi * 2.0 * w.t)))
    ctx = make_context(prepare_wheel(moving, model, np.random.default_rng(0)), model)
    late, with_load = Delay.propose(ctx)
    x = np.array([0.03, 0.0])
    for m, load_shifted in ((late, True), (with_load, False)):
        inp = dict(ctx.wheel.inputs)
        m.inputs(x, ctx, inp)
        assert (not np.array_equal(inp["Fz"], ctx.wheel.x("Fz"))) == load_shifted
        assert not np.array_equal(inp["alpha"], ctx.wheel.x("alpha"))


def test_a_recorded_pressure_refits_the_camber_stiffness_term_where_the_inclination_moves(model):
    """MF 6.1's PPY5 (pressure on the camber stiffness, 4.E30) is refitted with the other
    pressure terms where the wheel runs more than one inclination: a programme that ran its
    low pressure only at 3 degrees let the camber coefficients take the pressure's camber
    thrust (flattrac pressure_recorded s1, named camber). On one inclination it is not."""
    from tire_model_ros.diagnosis.effects.pressure import RecordedPressure
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    wheels, _ = _session(model, {"noise": True})
    w = wheels[0]
    low = np.sin(2.0 * np.pi * w.t / 60.0) > 0.0
    p = np.where(low, 0.8, 1.0) * model.params["NOMPRES"]
    for gamma, has_ppy5 in ((np.where(low, np.radians(3.0), 0.0), True), (0.0 * w.t, False)):
        series = dataclasses.replace(w, p=p, gamma=gamma)
        ctx = make_context(prepare_wheel(series, model, np.random.default_rng(0)), model)
        (m,) = RecordedPressure.propose(ctx)
        assert ("PPY5" in m.pnames) == has_ppy5, m.pnames
        assert "PPY1" in m.pnames


def test_combined_slip_can_show_where_a_small_drive_slip_meets_a_slip_angle(model):
    """A car corners under a little drive torque: a slip ratio of a few thousandths, below any
    'both slips swept' threshold, while its Fx is weighted by the slip angle. Combined slip is
    tried, and its region is where a usual weighting would change a force beyond the noise:
    the cornering part, not the straight."""
    from tire_model_ros.diagnosis.effects.static import CombinedSlip
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel
    from tire_model_ros.diagnosis.result import set_noise

    wheels, _ = _session(model, {"noise": True})
    w = wheels[0]

    def context(series):  # type: ignore[no-untyped-def]
        ctx = make_context(prepare_wheel(series, model, np.random.default_rng(0)), model)
        set_noise(ctx)
        return ctx

    pure = context(w)
    assert CombinedSlip.propose(pure) == []
    braking = np.sin(2.0 * np.pi * w.t / 20.0) > 0.9  # a short stop now and then: Fx swept
    kappa = np.where(braking, -0.03, 0.004)
    noise = np.random.default_rng(1).normal(0.0, 15.0, len(w.t))
    Fx = 60e3 * kappa * np.cos(w.alpha) + noise  # a linear Fx at a usual slip stiffness
    driven = dataclasses.replace(w, kappa=kappa, Fx=Fx)
    ctx = context(driven)
    (m,) = CombinedSlip.propose(ctx)
    region = m.support(ctx)
    assert region is not None
    alpha = np.abs(ctx.wheel.x("alpha"))
    driving = ~braking
    assert region[driving & (alpha > np.radians(5.0))].mean() > 0.9
    assert not region[driving & (alpha < np.radians(0.5))].any()


def test_a_concealed_pressure_rising_like_a_ramp_is_named_pressure_not_drift(model):
    """A sealed tyre on a car that never pauses warms its gas like a ramp: that it followed the
    heat cannot be told, that the pressure rose can (stiffness and grip move in the file's
    pressure proportions, a friction drift moves grip alone). The forces here are the file's
    at a pressure rising 12 % over the session, with the rig's noise; no pressure recorded."""
    wheels, _ = _session(model, {"noise": True})
    w = wheels[0]
    assert w.p is not None
    clean = model.evaluate(w.Fz, w.kappa, w.alpha, w.gamma, w.Vx, w.p, w.T)
    p = w.p * (1.0 + 0.12 * (w.t - w.t[0]) / (w.t[-1] - w.t[0]))
    risen = model.evaluate(w.Fz, w.kappa, w.alpha, w.gamma, w.Vx, p, w.T)
    forces = {
        ch: getattr(w, ch) + getattr(risen, ch) - getattr(clean, ch) for ch in ("Fx", "Fy", "Mz")
    }
    sealed = dataclasses.replace(w, p=None, **forces)
    diag = diagnose([sealed], model, seed=0)
    names = [e.name for e in diag.effects]
    assert names[0] == "pressure", names
    assert "drift" not in names


def test_a_pre_warmed_sealed_tyre_cooling_back_is_named_pressure(model):
    """A sealed tyre that comes to the rig warm (its gas above ambient) loses pressure as the
    gas cools back over minutes: the hidden gas node starts pre-warmed. The forces here are
    the file's at a pressure 10 % high at the start, falling back with a 150 s time constant,
    with the rig's noise; no pressure recorded."""
    wheels, _ = _session(model, {"noise": True})
    w = wheels[0]
    assert w.p is not None
    clean = model.evaluate(w.Fz, w.kappa, w.alpha, w.gamma, w.Vx, w.p, w.T)
    p = w.p * (1.0 + 0.10 * np.exp(-(w.t - w.t[0]) / 150.0))
    warm = model.evaluate(w.Fz, w.kappa, w.alpha, w.gamma, w.Vx, p, w.T)
    forces = {
        ch: getattr(w, ch) + getattr(warm, ch) - getattr(clean, ch) for ch in ("Fx", "Fy", "Mz")
    }
    diag = diagnose([dataclasses.replace(w, p=None, **forces)], model, seed=0)
    first = diag.effects[0]
    assert first.name == "pressure", diag.details["log"]
    assert first.parameters.get("gas_T0_K", 0.0) > 5.0, first.parameters


def _made_by_hidden_thermal(model, truth: dict[str, float]):
    """A hidden thermal model of a noisy session's first wheel, and that wheel's forces made
    by it at ``truth`` (its other parameters at their starts) with noise: (model, context,
    the true parameter vector)."""
    from tire_model_ros.diagnosis.effects.thermal import HiddenThermal
    from tire_model_ros.diagnosis.predict import predict
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    wheels, _ = _session(model, {"noise": True})
    ctx = make_context(prepare_wheel(wheels[0], model, np.random.default_rng(0)), model)
    hidden = HiddenThermal(ctx)
    x = np.array([truth.get(k, v) for k, v in zip(hidden.pnames, hidden.x0, strict=True)])
    rows = np.arange(len(ctx.wheel.t))
    rng = np.random.default_rng(1)
    for ch, F in predict([hidden], x, ctx, rows).items():
        if ch in ctx.channels:
            ctx.wheel.meas[ch][:] = F + rng.normal(0.0, ctx.sigma[ch], len(rows))
    return hidden, ctx, x


def test_a_carcass_brought_hot_to_the_rig_is_recovered_with_its_warm_start(model):
    """A tyre brought to the rig hot (a blanket, a previous run) starts its carcass far above
    ambient and cools while the tread heats: forces made by the hidden thermal model itself
    with the carcass 75 K up at the start (grip -0.15 per dT on the TT convention's scale:
    0.53 at the hottest), with noise; the fit from the effect's own starts recovers the start
    and the grip, which the table takes over from the quadratic (with a 60 K bound it stopped
    at the bound, 110 times the noise's cost)."""
    from tire_model_ros.diagnosis.fitting import fit

    truth = dict(tau_fast_s=3.0, tau_slow_s=200.0, slow_gain=1.0, T0_K=75.0, grip_per_dT=-0.15)
    hidden, ctx, _ = _made_by_hidden_thermal(model, truth)
    rows = np.arange(len(ctx.wheel.t))
    f = fit([hidden], ctx, rows)
    got = dict(zip(hidden.pnames, f.x, strict=True))
    assert got["T0_K"] == pytest.approx(75.0, abs=3.0), got
    dT = (hidden.knots(f.x, ctx) - ctx.T_amb) / ctx.T_amb
    assert got["grip_per_dT"] == 0.0
    np.testing.assert_allclose(hidden.grip(f.x), 1.0 - 0.15 * dT, atol=0.02)
    assert 2.0 * f.cost / f.m < 2.0  # the noise's own cost per residual is about 1


def test_a_tyre_cooling_unheated_by_the_power_is_a_change_in_time_not_a_temperature(model):
    """Forces made by the hidden thermal model with its carcass 60 K up at the start, cooling
    with 300 s, and no heat from the power put in (its stiffness rising 24 % as it cools, the
    grip as the file's): its plain-time control (a ramp and a start's cooling, the same law)
    predicts the same, so the data show a change in time and not heat, and the engine refuses
    it (brush multi2_b s32: a leak and wear took this form). Heated by the power as well,
    the same tyre beats that control."""
    from tire_model_ros.diagnosis.effects import Scaling
    from tire_model_ros.diagnosis.search import Joint, _controls, cross_validate, joint_add

    def controls(truth: dict[str, float]) -> tuple[bool, str]:
        hidden, ctx, _ = _made_by_hidden_thermal(model, truth)
        p = ctx.wheel.prefix
        base = Joint({p: cross_validate([Scaling(ctx)], ctx, [None, None])})
        t = joint_add(base, ("HiddenThermal", hidden.label), {p: hidden})
        return _controls(t, base)

    cooling = dict(slow_gain=0.0, T0_K=60.0, tau_slow_s=300.0, stiffness_per_K=-0.004)
    ok, note = controls(cooling)
    assert not ok and "a change in time, its cause not shown" in note, note
    ok, note = controls({**cooling, "slow_gain": 1.0, "grip_per_dT": -0.15})
    assert ok and "beats its controls" in note, note


def test_wear_only_ever_takes_grip_away(model):
    """Wear is an irreversible loss with the work done (INTERFACE/issue: never a gain, which
    is a warming tyre's below its optimum): its loss is bounded at zero from below."""
    from tire_model_ros.diagnosis.effects.friction import Wear
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    wheels, _ = _session(model, {"noise": True})
    ctx = make_context(prepare_wheel(wheels[0], model, np.random.default_rng(0)), model)
    wear = Wear(ctx)
    loss, stiffening = wear.params
    assert loss.lo == 0.0 and loss.hi > 0.0 and stiffening.lo == 0.0
    every = ctx.rows["all"]
    assert np.all(wear.mu_scale(np.array([loss.lo, 1.0]), ctx, every) == 1.0)
    assert np.all(np.diff(wear.mu_scale(np.array([loss.hi, 1.0]), ctx, every)) <= 0.0)
    # the slip stiffness rises with the grip lost, in the proportion fitted
    w = ctx.wheel
    inp = {"kappa": np.full(len(w.t), 0.01), "alpha": np.full(len(w.t), 0.02)}
    wear.per_sample(np.array([0.1, 2.0]), ctx, inp, every)
    gain = inp["kappa"] / 0.01 - 1.0
    np.testing.assert_allclose(gain, 2.0 * 0.1 * w.E / ctx.E_ref)
    assert gain[-1] > 0.0 and np.all(np.diff(gain) >= 0.0)


def test_a_window_flat_beyond_its_optimum_is_followed_by_the_hidden_grip_table(model):
    """Concealed heating of a tyre whose grip rises 8 % over its coldest quarter, then holds
    (a skewed window, flat beyond: PHYSICS.md), which a quadratic cannot follow: fitted first
    with a quadratic leading the nodes, then with the table that takes its shape over, the
    model comes near the noise (the quadratic alone stays far from it), and the quadratic is
    gone. The table holds the grip beyond the hottest fitted sample (a quadratic keeps
    rising: seed 30 car multi2_b, held-out sweeps 20 K hotter than any fitted one were tens
    of times the noise worse); the effects file carries the table."""
    from tire_model_ros.diagnosis.fitting import fit

    truth = dict(tau_fast_s=3.0, tau_slow_s=150.0, slow_gain=2.0)
    truth.update({f"mu_at_T_p{q:03d}": 1.08 for q in (25, 50, 75, 100)})
    hidden, ctx, _ = _made_by_hidden_thermal(model, truth)
    rows = np.arange(len(ctx.wheel.t))
    only_quadratic = np.array([p.stage < 2 for p in hidden.params])
    f_quad = fit([hidden], ctx, rows, free=only_quadratic)
    f = fit([hidden], ctx, rows)
    # the noise's own cost per residual is about 1 (measured: 2.0 staged, 145 the quadratic)
    assert 2.0 * f.cost / f.m < 3.0 and 2.0 * f_quad.cost / f_quad.m > 30.0, (f.cost, f_quad.cost)
    got = dict(zip(hidden.pnames, f.x, strict=True))
    assert got["grip_per_dT"] == got["grip_per_dT2"] == 0.0
    np.testing.assert_allclose(hidden.grip(f.x), [1.0, 1.0, 1.08, 1.08, 1.08, 1.08], atol=0.01)
    carried = hidden.carry(f.x, ctx)
    assert carried is not None and carried["grip_table"] == hidden.grip_table(f.x, ctx)
    # fitted on rows below the last quarter only: the hottest knot holds the one below it
    lifted = f.x.copy()
    lifted[-1] = 1.3
    knots = hidden.knots(lifted, ctx)
    cool = rows[hidden.temperature(lifted, ctx) < knots[4]]
    assert hidden.grip(hidden.settle(lifted, [(ctx, cool)]))[5] == hidden.grip(lifted)[4]
    assert hidden.grip(hidden.settle(lifted, [(ctx, rows)]))[5] == 1.3  # all rows: it is seen


def test_friction_step_is_named_drift_and_located(model):
    """A belt friction step: drift, in the step form, at the rig's time; model error gone."""
    wheels, truth = _session(model, {"mu_step": {"ratio": 0.93}})
    diag = diagnose(wheels, model, seed=0)
    first = diag.effects[0]
    assert first.name == "drift", diag.details["log"]
    # Located within the gap of the training sweeps where the rig stepped (the fits see no
    # sample between the two times; a held-out sweep may lie in that gap).
    at = truth["wheels"][wheels[0].prefix]["hidden_summary"]["mu_step_at_s"]
    fitted = first.parameters["t_step_s"]
    prefix = wheels[0].prefix
    t = wheels[0].t - wheels[0].t[0]
    moving = np.abs(wheels[0].alpha) > np.radians(1.0)
    between = (t > min(at, fitted) + 1.0) & (t < max(at, fitted) - 1.0)
    assert not np.any(between & moving & diag.train_mask[prefix]), (at, fitted)
    assert first.parameters["step_mu_loss"] == pytest.approx(0.07, abs=0.015)
    assert any(n.startswith("drift") for n in diag.node_effects().not_carried)  # history
    # Against the noise-free twin: the model error falls. Not to zero here: the sweep right
    # after the step is held out, so where in its gap the step falls is unknowable.
    twin, _ = _session(model, {"mu_step": {"ratio": 0.93}, "noise": False})
    ref = diag.score_reference(twin)
    a, b = (ref[k]["Fy"]["rmse"] for k in ("heldout_baseline", "heldout_improved"))
    assert b < 0.9 * a
    short = [twin[0].select(np.arange(len(twin[0])) < len(twin[0]) - 5)]
    with pytest.raises(ValueError, match="does not match"):
        diag.score_reference(short)


def test_friction_step_is_placed_at_the_belt_stop(model):
    """A belt change between runs: when the gap of the training sweeps that holds the step
    also holds a belt stop, the step is put there (on seed 5 a held-out sweep lies in that gap:
    a ramp across it left a model error of 50 N, the stop brings it to a few N)."""
    opts = {"stop_s": 20.0}
    effects = {"mu_step": {"ratio": 0.93}}
    wheels, truth = simulate_session(
        model, "lateral_sweeps", effects=effects, seed=5, programme_options=opts
    )
    diag = diagnose(wheels, model, seed=0)
    first = diag.effects[0]
    assert first.name == "drift", diag.details["log"]
    at = truth["wheels"][wheels[0].prefix]["hidden_summary"]["mu_step_at_s"]
    assert first.parameters["t_step_s"] == pytest.approx(at, abs=1.0)
    twin, _ = simulate_session(
        model,
        "lateral_sweeps",
        effects={**effects, "noise": False},
        seed=5,
        programme_options=opts,
    )
    ref = diag.score_reference(twin)
    a, b = (ref[k]["Fy"]["rmse"] for k in ("heldout_baseline", "heldout_improved"))
    assert b < 0.1 * a
    # The model error left is a few N: on the recording it scores the floor, the RMSE of the
    # true physics (force noise and input noise through the slip stiffness).
    raw = diag.fit["heldout_improved"]["Fy"]["rmse"]
    assert ref["heldout_floor"]["Fy"]["rmse"] == pytest.approx(raw, rel=0.05)


def test_wear_is_drift_not_a_tread_node_stretched_to_its_bound(model):
    """Wear that grows with tread heat (the confuser of concealed heating), on the seed where
    the slow thermal node came within its margin of drift: its tread node ran to the bound of
    its time constant, which is no heating of seconds, so drift is named and nothing else."""
    wheels, _ = simulate_session(
        model,
        "flat_trac",
        effects={"wear": {"loss_per_km": 0.08, "abrasion_per_K": 0.032}},
        omit=["temperature"],
        seed=41,
    )
    diag = diagnose(wheels, model, seed=0)
    assert [e.name for e in diag.effects] == ["drift"], diag.details["log"]


def test_offset_is_named_constant_and_sized(model):
    """A ply-steer offset (3 % of Fz at alpha = 0) passes the constancy guards and is sized."""
    wheels, _ = _session(model, {"offset": True})
    diag = diagnose(wheels, model, seed=0)
    first = diag.effects[0]
    assert first.name == "offset", diag.details["log"]
    assert "constant" in first.evidence
    Fz = float(np.median(wheels[0].Fz))
    shift = first.parameters["ply_steer_rad"]
    m = diag.improved_model
    Fy_shift = float(m.evaluate(Fz, 0.0, shift).Fy - m.evaluate(Fz, 0.0, 0.0).Fy)
    conicity = first.parameters["conicity_Fy_N_at_FNOMIN"]
    Fy_at_rest = first.parameters["offset_Fy_N"] + conicity * Fz / m.params["FNOMIN"] + Fy_shift
    assert abs(Fy_at_rest) == pytest.approx(0.03 * Fz, rel=0.2)
    carried = diag.node_effects().for_wheel(wheels[0].prefix)
    assert carried.offsets["Fy"] == (first.parameters["offset_Fy_N"], conicity)
    assert carried.alpha_shift_rad == shift


def test_a_zero_that_wanders_within_spec_is_not_named_an_offset(model):
    """A null whose force zeros wander over minutes (tau 150 s, RMS about 0.9 of the noise the
    diagnosis estimates) is no missing physics: a constant offset fitted to it is refused
    because the zeros wandering in time predict held-out sweeps better (brush null_5 s23 was
    named `offset`). A side force in proportion to the load (conicity) on a programme that runs its
    loads in turn is an offset, not a wandering zero (flattrac offset s1)."""
    wheels, _ = _session(model, {"noise": True})
    w = wheels[0]
    rng = np.random.default_rng(5)
    dt = float(np.median(np.diff(w.t)))
    a = np.exp(-dt / 150.0)
    walk = np.zeros((len(w.t), 2))
    kick = rng.standard_normal(walk.shape) * np.sqrt(1.0 - a * a)
    for i in range(1, len(w.t)):
        walk[i] = a * walk[i - 1] + kick[i]
    sigma = 0.6 * np.std(np.diff(w.Fy)) / np.sqrt(2.0)
    walk *= sigma / np.std(walk, axis=0)
    wandering = dataclasses.replace(w, Fx=w.Fx + walk[:, 0], Fy=w.Fy + walk[:, 1])
    diag = diagnose([wandering], model, seed=0)
    assert "offset" not in [e.name for e in diag.effects], diag.details["log"]
    conic = dataclasses.replace(w, Fy=w.Fy + 0.02 * w.Fz)
    diag = diagnose([conic], model, seed=0)
    assert [e.name for e in diag.effects] == ["offset"], diag.details["log"]
    assert diag.effects[0].parameters["conicity_Fy_N_at_FNOMIN"] == pytest.approx(
        0.02 * model.params["FNOMIN"], rel=0.2
    )


def test_a_load_cell_zero_within_the_noise_is_not_named_and_one_beyond_it_is(model):
    """A constant Fx zero of 0.48 of the (white) noise passes the significance tests on ten
    minutes of sweeps (the code before the materiality test named it) but changes the forces
    by less than the measurement's own error: not named. 1.5 times the noise is named. (0.42
    until the offset took a conicity term: one parameter more to pay for.)"""

    def session(fx_N: float) -> list:
        eff = {"offset": {"fy_per_Fz": 0.0, "fx_N": fx_N}, "noise": {"colour": 0.0}}
        return _session(model, eff)[0]

    sigma = next(iter(diagnose(session(0.0), model, seed=0).wheels.values())).sigma["Fx"]
    diag = diagnose(session(0.48 * sigma), model, seed=0)
    assert [e.name for e in diag.effects] == ["none"], diag.details["log"]
    assert any("within the measurement's own error" in s for s in diag.details["log"])
    diag = diagnose(session(1.5 * sigma), model, seed=0)
    assert [e.name for e in diag.effects] == ["offset"], diag.details["log"]
    assert "changes Fx by" in diag.effects[0].evidence


def test_cli_on_a_null_bag_names_none_and_writes_outputs(model, tmp_path):
    """Noise only: 'none', nothing invented; JSON/report/improved .tir written atomically;
    scores against the noise-free twin (--reference) far below the raw ones."""
    from tire_model_ros.recording import write_recording

    wheels, _ = _session(model, {}, seed=5)
    bag = tmp_path / "null_bag"
    write_recording(bag, wheels)
    twin = tmp_path / "twin_bag"
    write_recording(twin, _session(model, {"noise": False}, seed=5)[0])
    out_json = tmp_path / "diag.json"
    ref_json = tmp_path / "twin.json"
    report = tmp_path / "report"
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    cmd = [
        *TOOL,
        "diagnose",
        str(bag),
        "--tir",
        str(MF61_TIR),
        "--json",
        str(out_json),
        "--report",
        str(report),
        "--reference",
        str(twin),
        "--reference-json",
        str(ref_json),
    ]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=240, env=env, check=False)
    assert res.returncode == 0, res.stderr
    doc = json.loads(out_json.read_text())
    _check_json(doc)
    assert [e["name"] for e in doc["effects"]] == ["none"], res.stdout
    assert doc["look_alikes"] == [] and "look-alikes" not in res.stdout  # of nothing named
    assert "none" in res.stdout
    ref = json.loads(ref_json.read_text())
    for ch in ("Fx", "Fy"):
        raw, clean = doc["fit"]["heldout_baseline"][ch]["rmse"], ref["heldout_baseline"][ch]["rmse"]
        assert 0.0 <= clean < 0.5 * raw, (ch, clean, raw)
    assert (report / "improved.tir").exists()
    TireModel.from_file(report / "improved.tir")  # a readable property file
    effects = Effects.read(report / "improved.effects.json")  # beside it: nothing to carry
    assert effects.tir == "improved.tir" and effects.for_wheel(wheels[0].prefix).thermal is None
    # Never over an existing output unless asked.
    res2 = subprocess.run(cmd, capture_output=True, text=True, timeout=240, env=env, check=False)
    assert res2.returncode == 1 and "exists" in res2.stderr
    assert json.loads(out_json.read_text()) == doc


def test_cli_reports_a_missing_bag_clearly(tmp_path):
    cmd = [*TOOL, "diagnose", str(tmp_path / "nope"), "--tir", str(MF61_TIR)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 1
    assert "nope" in res.stderr


def test_cli_refuses_a_missing_reference_before_diagnosing(tmp_path):
    out_json = tmp_path / "d.json"
    cmd = [*TOOL, "diagnose", str(ROOT / "bags" / "flat_trac_nominal"), "--tir", str(MF61_TIR),
           "--json", str(out_json), "--reference", str(tmp_path / "twin"),
           "--reference-json", str(tmp_path / "clean.json")]  # fmt: skip
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 1
    assert "twin: no such file" in res.stderr
    assert not out_json.exists()  # refused up front, not after the diagnosis


def test_rare_sweeps_are_stratified_over_all_folds():
    """A stratum with enough rare sweeps (two left per selection fold) gives one at the
    interior condition farthest from the usual one to the final held-out fold, the kinds at
    different conditions; a condition visited twice has a visit in each selection fold, the
    pieces of a condition visited once alternate between them; a smaller stratum stays in
    the selection folds."""
    levels = [(-4, 0), (2, 0), (4, 0), (-2, 0), (-6, 0), (6, 0)]  # pressures, not monotone
    rare: list = [None]
    for lv in levels:  # a lateral sweep in two pieces
        rare += [("y", lv, 0), ("y", lv, 0), None, ("x", lv, 0), None]
    rare += [("y", (0, 4), 0), None, ("y", (0, 8), 0)]  # two camber sweeps
    folds = rare_folds(rare, np.random.default_rng(0))
    assert set(folds) == {j for j, r in enumerate(rare) if r is not None}
    held = {rare[j] for j, f in folds.items() if f == 2}
    assert {k for k, _, _ in held} == {"x", "y"} and len(held) == 2
    assert {lv for _, lv, _ in held} == {(-4, 0), (4, 0)}  # interior, farthest from usual
    for j, r in enumerate(rare[:-1]):
        if r is not None and rare[j + 1] == r and folds[j] != 2:
            assert {folds[j], folds[j + 1]} == {0, 1}  # a condition visited once: split
    y4 = ("y", (-4, 0), 0)
    twice = [None, y4, None, ("y", (3, 0), 0), None, y4, y4]
    f2 = rare_folds(twice, np.random.default_rng(1))
    assert f2[1] != f2[5] and f2[5] == f2[6]  # two visits: one in each, a visit kept whole
    # The same low pressure at a higher load (a corner: the sidewall's deflection) is a visit
    # of its own: its pieces are split between the selection folds, not kept in one.
    corner = [None, ("y", (-4, 0), 3), ("y", (-4, 0), 3), ("y", (-4, 0), 3), None, y4, y4]
    f3 = rare_folds(corner, np.random.default_rng(2))
    assert {f3[1], f3[2], f3[3]} == {0, 1}
    once = [None, ("y", (-4, 0), 3), None, y4, None, y4]  # a corner swept in one block
    assert rare_folds(once, np.random.default_rng(3))[1] == SPLIT
    for kind in ("x", "y"):
        sel_folds = [f for j, f in folds.items() if rare[j][0] == kind and f != 2]
        for f in (0, 1):  # a split sweep is in both
            assert sel_folds.count(f) + sel_folds.count(SPLIT) >= 2
    assert folds[len(rare) - 3] == folds[len(rare) - 1] == SPLIT  # camber: in both, split
    # Four pressures, one sweep of each kind at each: too few to hold one out.
    four = [r for r in rare[: 1 + 5 * 4]]
    assert 2 not in rare_folds(four, np.random.default_rng(0)).values()


def test_a_programme_cycling_its_sweeps_has_each_mix_of_sweeps_in_every_fold():
    """Pure drive slip, then combined at 3 and at 6 degrees, at each of three speeds (one block
    each, no pause between them): taken three at a time in time order, every pure block fell at
    the same place of its triple, and one draw in 27 sent all three to the final held-out fold
    (unseen brush speed, seed 15: the fit never saw a pure slip ratio sweep, held-out 27 -> 68
    N). A draw that leaves a mix out of a fold is replaced: each fold has one, whatever the draw."""
    from tire_model_ros.diagnosis.folds import assign_folds
    from tire_model_ros.fit.sweeps import Segment

    n_blk, gap = 200, 20
    n = 9 * (n_blk + gap)
    t = np.arange(n) * 0.05
    ramp = np.abs(np.sin(np.linspace(0.0, 3.0 * np.pi, n_blk))) * 0.15
    kappa, alpha = np.zeros(n), np.zeros(n)
    segs = []
    for b in range(9):
        i = np.arange(b * (n_blk + gap), b * (n_blk + gap) + n_blk)
        kappa[i] = ramp
        alpha[i] = np.radians((0.0, 3.0, 6.0)[b % 3])
        segs.append(Segment(i, "ramp", {"kappa": 1}, b, {}))
        segs.append(Segment(np.arange(i[-1] + 1, i[-1] + 1 + gap), "pause", {}, -1, {}))
    inputs = {"kappa": kappa, "alpha": alpha, "gamma": np.zeros(n), "Fz": np.full(n, 3000.0),
              "p": None}  # fmt: skip
    pure = [b * (n_blk + gap) for b in (0, 3, 6)]
    for seed in range(12):
        fold = assign_folds(segs, t, np.random.default_rng(seed), inputs, block_s=5.0)
        assert sorted(int(fold[i]) for i in pure) == [0, 1, 2], seed


def test_a_sweep_reaching_far_beyond_the_usual_slip_is_split_between_the_selection_folds():
    """A car's one hard corner (8 degrees where every other corner reaches 2 to 3) is the only
    sweep at its slip: in one selection fold only, a fit on the other fold would be scored on
    an extrapolation. It is a rare condition, split between the folds like a rare pressure."""
    from tire_model_ros.diagnosis.folds import assign_folds
    from tire_model_ros.fit.sweeps import Segment

    t = np.arange(0.0, 400.0, 0.01)
    reach = np.array([2.0, 3.0, 2.5, 2.2, 2.8, 2.4, 3.0, 2.6, 8.0, 2.5, 2.1, 2.9, 2.3, 2.7])
    n = len(t) // len(reach)
    alpha = np.radians(np.concatenate([r * np.sin(np.linspace(0, 4 * np.pi, n)) for r in reach]))
    t = t[: len(alpha)]
    segments = [
        Segment(np.arange(i, min(i + n // 8, len(t))), "ramp", {"alpha": 1}, i // n)
        for i in range(0, len(t), n // 8)
    ]
    inputs = {
        "kappa": 0.01 * np.sin(t), "alpha": alpha, "gamma": np.zeros_like(t),
        "Fz": np.full_like(t, 4000.0), "p": None,
    }  # fmt: skip
    for seed in range(5):
        fold = assign_folds(segments, t, np.random.default_rng(seed), inputs, block_s=25.0)
        hard = np.abs(alpha) > np.radians(5.0)
        assert set(np.unique(fold[hard])) == {0, 1}, seed
    unswept = {**inputs, "kappa": np.zeros_like(t)}  # a slip held at zero: no reach to exceed
    assert set(np.unique(assign_folds(segments, t, np.random.default_rng(0), unswept))) <= {0, 1, 2}


def test_unmeasured_torque_leaves_the_mz_coefficients_alone(model):
    """A wrench whose torque is not measured (zeros) is no Mz to refit the trail to."""
    wheels, _ = _session(model, {"heating": True}, omit=["temperature"])
    wheels = [dataclasses.replace(w, Mz=np.zeros_like(w.Mz)) for w in wheels]
    diag = diagnose(wheels, model, seed=0)
    assert diag.effects[0].name == "temperature"
    assert any("Mz not refitted" in line for line in diag.details["log"])
    for k in MZ_COEFS:
        assert diag.improved_model.params[k] == model.params[k], k


def test_an_effect_is_stable_when_two_fits_do_the_same_to_the_forces():
    """The stability test every effect faces (evidence.agree_doing): fitted on two independent
    parts of the session, the effect changes the forces alike, within half of what it does.
    On a speed session one fold once put a 5.7 % friction step at t = 0 s and the other a
    0.3 % one at 159 s: what they did differed by more than it did."""
    t = np.linspace(0.0, 300.0, 3001)
    a = -0.057 * (t >= 0.0)  # what each fold's step does to the forces (relative)
    b = -0.0027 * (t >= 159.0)
    size, diff = rms(0.5 * (a + b)), rms(a - b)
    assert not agree_doing(size, diff)
    c = -0.05 * (t >= 150.0)  # a real step: the two folds place it in the same gap
    d = -0.055 * (t >= 152.0)
    assert agree_doing(rms(0.5 * (c + d)), rms(c - d))


def _moved(m):
    """Parameters of ``m`` a third of the way from their starts to their upper bounds."""
    return np.array([p.x0 + (p.hi - p.x0) / 3.0 for p in m.params])


@pytest.mark.parametrize("omit", [[], ["temperature"]])
def test_every_model_predicts_at_a_folds_rows_what_it_predicts_on_the_whole_session(model, omit):
    """A fit evaluates its fold's rows only, the states integrated over the whole session and
    what acts per sample at those rows: every model of the library (recorded and concealed
    temperature alike), moved away from its start, predicts there what it predicts on every
    sample."""
    from tire_model_ros.diagnosis.effects import candidates
    from tire_model_ros.diagnosis.predict import predict
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    wheels, _ = _session(model, {"heating": True, "wear": True}, omit=omit)
    ctx = make_context(prepare_wheel(wheels[0], model, np.random.default_rng(0)), model)
    rows, every = ctx.rows["a"], ctx.rows["all"]
    models = candidates(ctx)
    assert len(models) >= 10
    for m in models:
        x = _moved(m)
        part, whole = predict([m], x, ctx, rows), predict([m], x, ctx, every)
        for ch in ("Fx", "Fy", "Mz"):
            np.testing.assert_allclose(
                part[ch], whole[ch][rows], rtol=1e-12, atol=1e-9, err_msg=f"{m} {ch}"
            )


def test_the_same_effects_predict_the_same_whichever_was_chosen_first(model):
    """States and lags act first, then the slip stiffness they set: a concealed warm-up and a
    relaxation length give one prediction in either order (the stiffness scales the lagged
    slip, as the node's forward model does)."""
    from tire_model_ros.diagnosis.effects.thermal import HiddenThermal
    from tire_model_ros.diagnosis.effects.transient import Relaxation
    from tire_model_ros.diagnosis.predict import predict
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    wheels, _ = _session(model, {"heating": True, "relaxation": True}, omit=["temperature"])
    ctx = make_context(prepare_wheel(wheels[0], model, np.random.default_rng(0)), model)
    (heat,), (lag,) = HiddenThermal.propose(ctx), Relaxation.propose(ctx)
    xh, xl = _moved(heat), _moved(lag)
    xh[heat.pnames.index("stiffness_per_K")] = -0.01
    rows = ctx.rows["ab"]
    one = predict([heat, lag], np.r_[xh, xl], ctx, rows)
    other = predict([lag, heat], np.r_[xl, xh], ctx, rows)
    for ch in ("Fx", "Fy"):
        np.testing.assert_allclose(one[ch], other[ch], rtol=1e-12, atol=1e-9)
    alone = predict([heat], xh, ctx, rows)
    assert np.max(np.abs(one["Fy"] - alone["Fy"])) > 10.0  # the lag does act


def test_a_remembered_hidden_state_is_never_served_stale(model):
    """The hidden thermal model integrates its nodes once per node parameters; whatever moves
    between calls (a node parameter, the stiffness, a grip coefficient, the slips an earlier
    effect made, the wheel), what it gives is what a fresh model computes."""
    from tire_model_ros.diagnosis.effects.thermal import HiddenThermal
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    wheels, _ = _session(model, {"heating": True}, omit=["temperature"])
    ctxs = [
        make_context(prepare_wheel(w, model, np.random.default_rng(i)), model)
        for i, w in enumerate([wheels[0], dataclasses.replace(wheels[0], Fx=1.5 * wheels[0].Fx)])
    ]
    (m,) = HiddenThermal.propose(ctxs[0])
    x = m.x0.copy()
    x[m.pnames.index("stiffness_per_K")] = -0.004
    steps = [("tau_fast_s", 2.0), ("mu_at_T_p100", 0.1), ("stiffness_per_K", 0.002), ("T0_K", 10.0)]
    for i, (name, dx) in enumerate([*steps, *steps]):
        ctx = ctxs[i // len(steps)]
        x[m.pnames.index(name)] += dx
        for slips in ("same", "equal", "other"):  # the arrays an earlier effect hands on
            inp = dict(ctx.wheel.inputs)
            if slips != "same":
                inp["kappa"] = inp["kappa"] * (1.0 if slips == "equal" else 0.9)
            ref = dict(inp)
            for effect, arrays in ((m, inp), (HiddenThermal(ctx), ref)):
                effect.inputs(x, ctx, arrays)
                effect.per_sample(x, ctx, arrays, ctx.rows["all"])
            for k in ("T", "kappa", "alpha"):
                assert np.array_equal(inp[k], ref[k]), (name, slips, k)
            assert not inp["T"].flags.writeable  # a remembered array cannot be changed


def test_a_recorded_temperature_reaches_the_grip_as_the_node_feeds_it(model):
    """A recorded (surface) temperature reaches the grip partly at once and partly through
    the lag of the tread's bulk, and the grip follows it through a table (a window of any
    shape, 1 at the channel's median); the stiffness falls with the lagged channel (the
    carcass): what the diagnosis fits on is, sample for sample, what the node computes from
    the effects file it carries. The temperature differs from
    both the channel and its lag alone; the table holds its end values beyond its knots."""
    from tire_model_ros.diagnosis.dynamics import first_order
    from tire_model_ros.diagnosis.effects.thermal import RecordedThermal
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel
    from tire_model_ros.model.states import EffectState, WheelEffects

    wheels, _ = _session(model, {"heating": True})
    ctx = make_context(prepare_wheel(wheels[0], model, np.random.default_rng(0)), model)
    (m,) = RecordedThermal.propose(ctx)
    x = m.x0.copy()
    x[m.pnames.index("tau_T_s")], x[m.pnames.index("T_surface_weight")] = 30.0, 0.4
    for name, v in (("tau_carcass_s", 90.0), ("T0_K", 8.0), ("stiffness_per_K", -0.01)):
        x[m.pnames.index(name)] = v
    x[-4:] = [1.1, 1.05, 0.9, 0.7]  # a window: grip peaks below the median
    fitted, scale = m.temperature(x, ctx), m.mu_scale(x, ctx, ctx.rows["all"])
    slips: dict[str, np.ndarray | None] = {"kappa": np.full(ctx.wheel.n, 0.1),
                                           "alpha": np.full(ctx.wheel.n, 0.05)}  # fmt: skip
    m.per_sample(x, ctx, slips, ctx.rows["all"])
    carried = m.carry(x, ctx)
    assert carried is not None
    knots, mu = carried["grip_table"]
    assert mu[2] == 1.0 and np.all(np.diff(knots) > 0)
    state = EffectState(WheelEffects(**carried))
    w, T = ctx.wheel, ctx.wheel.inputs["T"]
    assert T is not None
    node = np.array([
        state.inputs(float(ti), 0.1, 0.05, 10.0, float(Ti), None, ctx.p_nom, ctx.T_amb)
        for ti, Ti in zip(w.t, T, strict=True)
    ])  # fmt: skip
    np.testing.assert_allclose(node[:, 2], fitted, rtol=1e-10)
    np.testing.assert_allclose(node[:, 4], scale, rtol=1e-10)
    # the carcass' stiffness, then the grip's similarity: the slips the model sees
    np.testing.assert_allclose(node[:, 0] * node[:, 4], slips["kappa"], rtol=1e-10)
    assert slips["kappa"] is not None and np.ptp(slips["kappa"]) > 0.002  # 2 % of it
    gap = float(np.max(np.abs(fitted - T)))
    assert gap > 0.5 and np.max(np.abs(fitted - first_order(T, w.t, 30.0, T[0]))) > 0.5 * gap
    assert np.ptp(scale) > 0.1 and np.interp([-50.0, 500.0], knots, mu).tolist() == [1.1, 0.7]


def test_the_grip_tables_knots_rise_on_a_channel_that_mostly_sits_still():
    """A quantised channel that sits at one value most of the time still gives rising knots,
    each its own parameter name."""
    from tire_model_ros.diagnosis.effects.thermal import GRIP_KNOTS_PCT, _rising

    T = np.r_[np.full(900, 40.0), np.linspace(40.0, 45.0, 100)]
    k = np.round(_rising(np.percentile(T, GRIP_KNOTS_PCT)), 2)  # as RecordedThermal's
    assert np.all(np.diff(k) >= 0.09) and len({f"{v:.2f}" for v in k}) == len(k)


def test_a_tyre_fits_jacobian_by_blocks_is_the_dense_one_at_a_fraction_of_the_cost():
    """The block Jacobian of a fit shared by the wheels of a car equals scipy's dense forward
    differences (the same steps, bounds respected), each wheel differenced only in the shared
    parameter and its own."""
    from tire_model_ros.diagnosis.fitting import _forward_steps, block_jacobian

    t = np.linspace(0.0, 1.0, 50)
    calls = []

    def part(k: int, x: np.ndarray) -> np.ndarray:
        calls.append(k)
        return np.sin(x[0] * t) * np.exp(x[1 + k] * t) + k

    x, lo, hi = np.array([0.7, -0.3, 2.0]), np.array([0.0, -1.0, 0.0]), np.array([1.0, 1.0, 2.0])
    r0 = [part(k, x) for k in range(2)]
    calls.clear()
    J = block_jacobian(part, r0, x, lo, hi, [[0, 1], [0, 2]])
    assert len(calls) == 4  # dense: 2 parts x 3 columns
    h = _forward_steps(x, lo, hi)
    assert h[2] < 0.0  # at its upper bound: differenced backwards
    dense = np.stack(
        [(np.concatenate([part(k, x + h * np.eye(3)[j]) for k in range(2)]) - np.concatenate(r0))
         / h[j] for j in range(3)], axis=1,
    )  # fmt: skip
    assert np.array_equal(J, dense)
    numdiff = pytest.importorskip("scipy.optimize._numdiff")
    step = numdiff._compute_absolute_step(1e-4, x, r0[0], "2-point")
    step, _ = numdiff._adjust_scheme_to_bounds(x, step, 1, "1-sided", lo, hi)
    assert np.array_equal((x + step) - x, h)


def test_improved_model_run_forward_as_the_node_runs_it_keeps_the_improvement(model, heated):
    """The improved .tir and its effects file, run sample by sample as the node runs them
    (model.states.EffectState: hidden nodes driven by the model's own forces, no temperature
    channel), on the whole recorded session.

    On the diagnosis' own view of the inputs (slips smoothed without lag) the node gives the
    diagnosis' improved forces; on the raw recorded inputs, as the node gets them, it keeps
    the improvement over the file's model run the same way (the slip noise, through the slip
    stiffness, adds to both). ``make demo`` does this through the real node.
    """
    from dataclasses import replace

    from tire_model_ros.demo import offline
    from tire_model_ros.diagnosis.prepare import prepare_wheel

    wheels, diag = heated
    assert diag.effects[0].name == "temperature", diag.details["log"]
    w, prefix = wheels[0], wheels[0].prefix
    fx = diag.node_effects().for_wheel(prefix)
    assert fx is not None and fx.thermal is not None and fx.thermal_slow is not None
    held = diag.heldout_mask[prefix]
    seen = prepare_wheel(w, model, np.random.default_rng(0)).inputs
    smooth = replace(w, **{k: seen[a] for k, a in (("kappa", "kappa"), ("alpha", "alpha"),
                                                   ("gamma", "gamma"), ("Fz", "Fz"))})  # fmt: skip

    def rss(out: np.ndarray, ref: dict[str, np.ndarray]) -> float:
        return float(np.sqrt(sum(np.mean((out[held, k] - ref[ch][held]) ** 2)
                                 for k, ch in enumerate(("Fx", "Fy")))))  # fmt: skip

    meas = {"Fx": w.Fx, "Fy": w.Fy}
    improved = {ch: diag.predictions[prefix][f"improved_{ch}"] for ch in ("Fx", "Fy")}
    node = offline(diag.improved_model, fx, smooth)
    assert rss(node, improved) < 0.1 * rss(node, meas), "the node computes another model"
    raw_node = rss(offline(diag.improved_model, fx, w), meas)
    raw_base = rss(offline(model, None, w), meas)
    assert raw_node < 0.5 * raw_base, (raw_node, raw_base)


def _score(per_block: list[float], noise_units_per_sample: float) -> Score:
    """A held-out score of sweeps of 100 samples each (noise units)."""
    blocks = {("w", i): v for i, v in enumerate(per_block)}
    n = 100 * len(per_block)
    assert sum(per_block) == pytest.approx(noise_units_per_sample * n)
    return Score(sum(per_block), n, {"Fx": 1.0, "Fy": 1.0}, {"Fx": n, "Fy": n}, blocks)


def test_a_sweep_held_out_in_two_parts_counts_whole_in_the_per_sweep_evidence():
    """A rare sweep seen once is split between the folds (way out in one, way back in the
    other): merging the two folds' scores must add its parts, so that the per-sweep evidence
    (sign test, t, control and near-tie tests) sees the same error as the RMS. Keeping one
    part dropped a third of a car wheel's held-out error from the evidence (seed 19 car
    heat_above: 98 % of the sweeps better while the RMS got worse)."""
    a = Score(30.0, 20, {"Fx": 1.0}, {"Fx": 20}, {("w", 0): 10.0, ("w", 1): 20.0})
    b = Score(45.0, 20, {"Fx": 2.0}, {"Fx": 20}, {("w", 1): 40.0, ("w", 2): 5.0})
    m = merge([a, b])
    assert m.per_block == {("w", 0): 10.0, ("w", 1): 60.0, ("w", 2): 5.0}
    assert sum(m.per_block.values()) == pytest.approx(m.total)
    # worse on the way out only (held out in the first fold): the evidence must see it
    out_worse = dataclasses.replace(a, total=70.0, per_block={("w", 0): 10.0, ("w", 1): 60.0})
    c = compare(m, merge([out_worse, b]))
    assert c.rel_gain < 0 and c.t_stat < 0 and not c.significant, c.text()


def test_a_weaker_effect_beside_a_strong_one_is_judged_on_what_is_left_beyond_the_noise():
    """After a large effect is in, the current model's held-out error is the noise (1 per
    sample) plus a remainder: an effect that removes 20 % of that remainder, on every sweep,
    is significant, though it lowers the RMS (noise included) by less than 4 %; a gain far
    below the remainder (1 %) is not, and at the noise there is nothing left to explain."""
    cur = _score([160.0] * 40, 1.6)  # remainder 0.6 per sample
    weak = _score([148.0] * 20 + [149.0] * 20, 1.485)  # 0.115 per sample: 19 % of it
    c = compare(cur, weak)
    assert c.rel_gain < 0.04 and c.significant, c.text()
    assert not compare(cur, _score([159.4] * 40, 1.594)).significant  # 1 % of the remainder
    at_noise = _score([100.0] * 40, 1.0)
    assert not compare(at_noise, _score([96.0] * 20 + [104.0] * 20, 1.0)).significant


def test_a_large_gain_on_half_the_sweeps_counts_when_it_dominates_and_is_consistent():
    """A crude model of a large effect (a friction law in the sliding speed, on a rig that
    runs a few speeds) halves the error on the sweeps where the effect is strong and moves the
    rest a little the wrong way: significant, though only half the sweeps improve. A gain
    carried by one sweep is not, however large."""
    cur = _score([300.0] * 20 + [200.0] * 20, 2.5)
    crude = _score([150.0] * 20 + [210.0] * 20, 1.8)
    c = compare(cur, crude)
    assert c.block_fraction == pytest.approx(0.5) and c.significant, c.text()
    one = _score([100.0] + [300.0] * 19 + [210.0] * 20, 2.5)
    assert not compare(_score([2100.0] + [300.0] * 19 + [200.0] * 20, 2.95), one).significant


def test_an_effect_beats_its_control_by_a_margin_or_on_most_sweeps():
    """A recorded pressure that rises almost like a ramp in time: its model is 1.9 % better
    (RMS) than the ramp, on 34 of 40 held-out sweeps. The data tell them apart; 1 % on half
    the sweeps does not. Past the margin the sweeps are not asked."""
    ramp = _score([150.0] * 40, 1.5)
    assert beats_control(_score([140.0] * 34 + [170.0] * 6, 1.445), ramp)
    assert not beats_control(_score([130.0] * 20 + [164.0] * 20, 1.47), ramp)
    assert beats_control(_score([60.0] * 10 + [160.0] * 30, 1.35), ramp)
    assert not beats_control(ramp, ramp)


def test_a_near_tie_goes_to_the_richer_model_only_when_most_sweeps_prefer_it():
    """Two models within the Occam margin: the fewer parameters win unless the richer one is
    better on most held-out sweeps (a constant-speed rig's relaxation against a delay)."""
    from tire_model_ros.diagnosis.effects.base import EffectModel, Param
    from tire_model_ros.diagnosis.search import Joint, Trial, _ranked

    class Simple(EffectModel):
        word, label = "time_delay", "two"

        def __init__(self) -> None:
            super().__init__([Param("a", 0, 0, 1, 1), Param("b", 0, 0, 1, 1)])

    class Rich(EffectModel):
        word, label = "relaxation", "three"

        def __init__(self) -> None:
            super().__init__([Param(k, 0, 0, 1, 1) for k in "abc"])

    cur = _score([200.0] * 40, 2.0)
    library = {("Simple", "two"): {"w": Simple()}, ("Rich", "three"): {"w": Rich()}}

    def joint(key, per_block):  # type: ignore[no-untyped-def]
        sc = _score(per_block, sum(per_block) / 100 / len(per_block))
        j = Joint({"w": Trial(None, [], [], sc, [sc, sc])}, [key])  # type: ignore[arg-type]
        j.vs = compare(cur, sc)
        return j

    simple = joint(("Simple", "two"), [149.0, 151.0] * 20)
    tied = joint(("Rich", "three"), [138.0] * 20 + [160.0] * 20)  # better on half the sweeps
    assert _ranked([tied, simple], library)[0] is simple
    richer = joint(("Rich", "three"), [141.0] * 36 + [206.0] * 4)  # better on 36 of 40
    assert richer.score.rms < simple.score.rms * 1.02
    assert _ranked([richer, simple], library)[0] is richer
    # Past the margin, within one standard error: 2.7 % better (RMS) by one sweep, worse on
    # the 11 others (a recorded temperature against the rig's belt step): no tie broken.
    cur = _score([200.0] * 12, 2.0)
    simple = joint(("Simple", "two"), [149.0, 151.0] * 6)
    on_one = joint(("Rich", "three"), [0.0] + [155.0] * 11)
    assert on_one.score.rms < simple.score.rms * 0.98
    assert _ranked([on_one, simple], library)[0] is simple
    on_most = joint(("Rich", "three"), [140.0] * 10 + [155.0] * 2)  # t > 1
    assert _ranked([on_most, simple], library)[0] is on_most


def test_a_tyre_effect_shares_the_union_of_what_its_wheels_propose():
    """A car wheel that sweeps no slip ratio proposes no Fx camber coefficient (PDX3), the
    others do; the tyre's one parameter set is the union, so every wheel carries PDX3 (it
    acts on that wheel's Fx too). Zipping the wheels' lists crashed the diagnosis of a car
    (car sidewall seed 18: 'zip() argument 2 is shorter than argument 1')."""
    from tire_model_ros.diagnosis.effects.base import EffectModel, Param, shared

    class Coefs(EffectModel):
        word, label, tyre = "camber", "coefficients", True

        def __init__(self, names: str, lo: float) -> None:
            super().__init__([Param(k, 0.0, lo, 1.0, 0.1) for k in names])

    full, lateral = Coefs("abx", -1.0), Coefs("ab", -2.0)
    shared([full, lateral, Coefs("abx", -1.0)])
    assert full.pnames == lateral.pnames == ["a", "b", "x"]
    assert [p.lo for p in lateral.params] == [-2.0, -2.0, -1.0]  # x: only the wheels with it


def test_a_tyre_effect_runs_in_each_of_its_forms_on_every_wheel_of_the_car(model):
    """A driven front wheel proposes camber with its combined-slip terms and combined slip, a
    free-rolling rear wheel only the plain camber; both run the same tyre. Were the combined
    forms fitted on the front wheels alone, the rear wheels would keep the baseline's missing
    camber thrust and a per-wheel offset would take it (car camber s35: named offset first,
    then camber), or keep the combined-slip error a braking rear wheel shows (car combined
    s35). Each form runs on both wheels, with one parameter space."""
    from tire_model_ros.diagnosis.effects.static import Camber, CombinedSlip
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel
    from tire_model_ros.diagnosis.result import set_noise
    from tire_model_ros.diagnosis.search import make_library

    wheels, _ = _session(model, {"noise": True})
    w = wheels[0]
    gamma = np.radians(2.0) * np.sin(2.0 * np.pi * w.t / 45.0)
    braking = np.sin(2.0 * np.pi * w.t / 20.0) > 0.9
    kappa = np.where(braking, -0.03, 0.004)
    noise = np.random.default_rng(1).normal(0.0, 15.0, len(w.t))
    front = dataclasses.replace(
        w, prefix="/car/fl", gamma=gamma, kappa=kappa, Fx=60e3 * kappa * np.cos(w.alpha) + noise
    )
    rear = dataclasses.replace(w, prefix="/car/rl", gamma=gamma)
    ctxs = []
    for series in (front, rear):
        ctx = make_context(prepare_wheel(series, model, np.random.default_rng(0)), model)
        set_noise(ctx)
        ctxs.append(ctx)
    pools = [Camber.propose(c) + CombinedSlip.propose(c) for c in ctxs]
    assert [len(p) for p in pools] == [3, 1]  # the rear wheel alone cannot tell the terms
    library = make_library(ctxs, pools)
    assert len(library) == 3
    for ms in library.values():
        assert list(ms) == ["/car/fl", "/car/rl"]
        assert ms["/car/rl"].pnames == ms["/car/fl"].pnames
    combined = library[("CombinedSlip", CombinedSlip.label)]["/car/rl"]
    assert {"RVY2", "RBX3", "RBY4", "RVY3"} <= set(combined.pnames)  # camber's: gamma moves


def test_sidewall_contact_acts_where_its_fitted_gate_opens_and_has_an_ungated_control(model):
    """Sidewall contact's region is the fitted model's own (past the threshold deflection,
    beyond the contact slip angle), not a fixed quantile of the session; the corner is the
    upper half of the deflections past the force peak; its control drops at any deflection."""
    from tire_model_ros.diagnosis.effects.sidewall import SidewallContact, deflection
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    wheels, _ = _session(model, {"noise": True})
    w = wheels[0]
    ramp = dataclasses.replace(w, Fz=np.linspace(0.5, 1.6, len(w.t)) * model.params["FNOMIN"])
    ctx = make_context(prepare_wheel(ramp, model, np.random.default_rng(0)), model)
    (m,) = SidewallContact.propose(ctx)
    rho, alpha = deflection(ctx), np.abs(ctx.wheel.x("alpha"))
    th_lo = m.params[0].lo
    assert th_lo > float(np.min(rho))  # the gate cannot open over the whole range
    x = np.array([1.3, np.radians(6.0), 1.0, 0.3, 0.05])
    acts = m.support(ctx, x)
    assert acts is not None
    inside = (rho > 1.4) & (alpha > np.radians(7.0))
    assert inside.sum() > 10 and acts[inside].all()
    assert not acts[(rho < 0.95) | (alpha < np.radians(6.0))].any()
    (control,) = m.controls(ctx)
    assert not control.params[0].fitted and control.params[0].x0 < float(np.min(rho))
    assert control.controls(ctx) == []


def test_sidewall_contact_is_proposed_on_how_long_its_corner_runs_not_its_share(model):
    """A corner run for as long in a session four times as long (the rest straight running)
    is proposed all the same: the gate is a duration (a car's front wheels reach their corner
    in seconds of an 8-minute session, under 1 % of its samples); a corner run for about a
    second is not."""
    from tire_model_ros.diagnosis.effects.sidewall import MIN_CORNER_S, SidewallContact, _corner
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    wheels, _ = _session(model, {"noise": True})
    w = wheels[0]
    n, dt = len(w.t), float(np.median(np.diff(w.t)))
    ramp = dataclasses.replace(w, Fz=np.linspace(0.5, 1.6, n) * model.params["FNOMIN"])

    def ctx_of(keep: int, repeat: int):
        """``ramp`` swept past its peak on its last ``keep`` samples only (elsewhere to 0.3
        of its slip angles), ``repeat`` times as long (the time added straight running)."""
        alpha = np.where(np.arange(n) >= n - keep, ramp.alpha, 0.3 * ramp.alpha)
        cols = {f.name: getattr(ramp, f.name) for f in dataclasses.fields(ramp)}
        arrays = {k: v for k, v in cols.items() if isinstance(v, np.ndarray) and v.shape == (n,)}
        arrays["alpha"] = alpha
        longer = {k: np.concatenate([v[:1].repeat(n * (repeat - 1)), v]) for k, v in arrays.items()}
        longer["t"] = np.arange(n * repeat) * dt
        wheel = dataclasses.replace(ramp, **longer)
        return make_context(prepare_wheel(wheel, model, np.random.default_rng(0)), model)

    def corner_s(ctx) -> float:
        return float(np.count_nonzero(_corner(ctx))) * dt

    short, long = ctx_of(n // 8, 1), ctx_of(n // 8, 4)
    assert corner_s(long) >= MIN_CORNER_S and float(np.mean(_corner(long))) < 0.01
    assert SidewallContact.propose(short) and SidewallContact.propose(long)
    brief = ctx_of(n // 32, 1)
    assert brief.informative["y"] and 0.5 < corner_s(brief) < MIN_CORNER_S
    assert not SidewallContact.propose(brief)


def test_sidewall_gate_spans_the_deflections_the_fitted_rows_leave_open(model):
    """Fitted rows that run past the contact slip angle only below rho 0.8 and above 1.4 do not
    place the threshold between them: the settled gate is centred in that gap and spans it (a
    corner the fit did not see gets the expected drop, not all or none); rows with no gap keep
    the fitted gate."""
    from tire_model_ros.diagnosis.effects.sidewall import SidewallContact, deflection
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel
    from tire_model_ros.model.states import Sidewall, sidewall_factor

    wheels, _ = _session(model, {"noise": True})
    w = wheels[0]
    ramp = dataclasses.replace(w, Fz=np.linspace(0.5, 1.6, len(w.t)) * model.params["FNOMIN"])
    ctx = make_context(prepare_wheel(ramp, model, np.random.default_rng(0)), model)
    (m,) = SidewallContact.propose(ctx)
    rho = deflection(ctx)
    x = np.array([0.85, np.radians(3.0), 3.0, 0.3, 0.05])
    every = np.arange(ctx.wheel.n)
    assert np.allclose(m.settle(x, [(ctx, every)]), x, rtol=0.02)  # no gap: as fitted
    gap = np.flatnonzero((rho < 0.8) | (rho > 1.4))
    sx = m.settle(x, [(ctx, gap[gap < ctx.wheel.n // 2]), (ctx, gap[gap >= ctx.wheel.n // 2])])
    assert 1.0 < sx[0] < 1.25 and np.allclose(sx[1:4], x[1:4])
    f = sidewall_factor(np.array([0.8, sx[0], 1.4]), np.radians(20.0), Sidewall(*sx))
    loss = 1.0 - f
    assert loss[0] < 0.1 * loss[2] and 0.3 < loss[1] / loss[2] < 0.7, loss
    assert m.controls(ctx)[0].settle(x, [(ctx, gap)]) is x  # the control has no gate


def test_a_tyre_effect_is_fitted_to_the_wheels_of_a_car_with_one_parameter_set(model):
    """Sidewall contact on two wheels of one tyre: the loaded one runs its sweeps at one
    deflection, so on it alone a drop gated by the deflection is no better than the same
    drop at every deflection (its control); the other reaches the same slip angles at a third
    of the load without a drop. One parameter set fitted to both tells the gate: named, the
    same on both wheels, acting on the loaded one only. (The drop here is a linear ramp in
    the slip angle with a hard gate, not the diagnosis' logistic form.)"""
    from tire_model_ros.diagnosis.effects.sidewall import deflection
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    wheels, _ = _session(model, {"noise": True})
    w, rng = wheels[0], np.random.default_rng(7)
    FN = model.params["FNOMIN"]

    def wheel(prefix: str, load: float, drop: float):
        Fz = load * FN * (1.0 + 0.002 * rng.standard_normal(len(w.t)))
        out = model.evaluate(Fz, w.kappa, w.alpha, w.gamma, w.Vx, w.p, w.T)
        beyond = np.clip((np.abs(w.alpha) - np.radians(8.0)) / np.radians(4.0), 0.0, None)
        Fy = out.Fy * (1.0 - drop * beyond)
        noise = [20.0 * rng.standard_normal(len(w.t)) for _ in range(2)]
        return dataclasses.replace(w, prefix=prefix, Fz=Fz, Fx=out.Fx + noise[0],
                                   Fy=Fy + noise[1], Mx=None, My=None, Mz=out.Mz)  # fmt: skip

    loaded, light = wheel("/car/fl", 1.5, 0.15), wheel("/car/fr", 0.5, 0.0)
    rho = deflection(make_context(prepare_wheel(loaded, model, np.random.default_rng(0)), model))
    assert np.quantile(rho, 0.95) < 1.05 * np.quantile(rho, 0.05)  # one deflection
    diag = diagnose([loaded, light], model)
    log = "\n".join(diag.details["log"])
    assert diag.effects[0].name == "sidewall_contact", log
    fx = [diag.node_effects().for_wheel(p) for p in ("/car/fl", "/car/fr")]
    assert fx[0] is not None and fx[1] is not None and fx[0].sidewall == fx[1].sidewall, log
    ex = {p: next(e.explained or 0.0 for e in d.effects if e.name == "sidewall_contact")
          for p, d in diag.wheels.items()}  # fmt: skip
    assert ex["/car/fl"] > 0.3 and ex["/car/fr"] < 0.05 * ex["/car/fl"], (ex, log)


def test_camber_is_the_tyres_one_set_of_coefficients_on_the_wheels_of_a_car(model):
    """Two wheels of one tyre at opposite inclinations (+-1.5 deg, +-0.4 of roll), its camber thrust
    stronger than the file's by 2.6 % of Fz per degree (PHYSICS.md's figure, a linear law,
    not the MF terms): camber is named, one set of coefficients for both wheels, and it
    predicts both wheels' opposite side forces."""
    wheels, _ = _session(model, {"noise": True})
    w, rng = wheels[0], np.random.default_rng(11)

    def wheel(prefix: str, gamma_deg: float):
        gamma = np.radians(gamma_deg + 0.4 * np.sign(gamma_deg) * np.sin(w.t / 20.0))
        out = model.evaluate(w.Fz, w.kappa, w.alpha, gamma, w.Vx, w.p, w.T)
        Fy = out.Fy - 0.026 * w.Fz * np.degrees(gamma)
        noise = [20.0 * rng.standard_normal(len(w.t)) for _ in range(2)]
        return dataclasses.replace(w, prefix=prefix, gamma=gamma, Fx=out.Fx + noise[0],
                                   Fy=Fy + noise[1], Mx=None, My=None, Mz=out.Mz)  # fmt: skip

    diag = diagnose([wheel("/car/fl", 1.5), wheel("/car/fr", -1.5)], model)
    log = "\n".join(diag.details["log"])
    assert diag.effects[0].name == "camber", log
    tirs = diag.improved_models
    coefs = ("PVY3", "PKY6", "PHY3", "PDY3")
    assert all(tirs["/car/fl"].params[k] == tirs["/car/fr"].params[k] for k in coefs), log
    assert tirs["/car/fl"].params["PVY3"] != model.params["PVY3"], log
    before, after = (diag.fit[k]["Fy"]["rmse"] for k in ("heldout_baseline", "heldout_improved"))
    assert after < 0.2 * before, (diag.fit, log)


def test_camber_thrust_that_grows_with_load_is_found_on_the_wheels_of_an_axle(model):
    """The outer and inner wheels of an axle (1.4 and 0.6 of FNOMIN) at one inclination
    (3 +- 0.5 deg of roll), the tyre's camber thrust more load dependent than its file says
    (PVY4, PKY7). Without those terms the per-wheel difference passes for an offset; with
    them camber is named and its load dependence recovered, one set for both wheels."""
    truth = model.with_params({"PVY4": -1.5, "PKY7": -1.0})
    wheels, _ = _session(model, {"noise": True})
    w, rng = wheels[0], np.random.default_rng(5)
    FN = model.params["FNOMIN"]

    def wheel(prefix: str, load: float):
        Fz = load * FN * (1.0 + 0.002 * rng.standard_normal(len(w.t)))
        gamma = np.radians(3.0 + 0.5 * np.sin(w.t / 20.0))
        out = truth.evaluate(Fz, w.kappa, w.alpha, gamma, w.Vx, w.p, w.T)
        noise = [20.0 * rng.standard_normal(len(w.t)) for _ in range(2)]
        return dataclasses.replace(w, prefix=prefix, Fz=Fz, gamma=gamma, Fx=out.Fx + noise[0],
                                   Fy=out.Fy + noise[1], Mx=None, My=None, Mz=out.Mz)  # fmt: skip

    diag = diagnose([wheel("/car/fl", 1.4), wheel("/car/fr", 0.6)], model)
    log = "\n".join(diag.details["log"])
    assert diag.effects[0].name == "camber", log
    tirs = diag.improved_models
    for k in ("PVY4", "PKY7"):
        assert tirs["/car/fl"].params[k] == tirs["/car/fr"].params[k], log
        assert tirs["/car/fl"].params[k] == pytest.approx(truth.params[k], rel=0.1), log


def test_camber_under_drive_slip_is_named_with_its_combined_slip_terms(model):
    """A car's two front wheels at their static camber (+-1.5 deg, +-0.4 of roll) cornering
    under a drive slip of a few per cent: the tyre's camber-induced side force under slip
    ratio (RVY3 of DVyk, 4.E67) is the opposite of its file's. Without the combined-slip
    camber terms among camber's coefficients a per-wheel conicity fitted it better (unseen
    car camber, seed 24: named offset); with them camber is named, RVY3 recovered, one value
    for both wheels."""
    truth = model.with_params({"RVY3": -model.params["RVY3"]})
    wheels, _ = _session(model, {"noise": True})
    w, rng = wheels[0], np.random.default_rng(12)
    kappa = 0.04 + 0.02 * np.sin(w.t / 7.0)

    def wheel(prefix: str, gamma_deg: float):
        gamma = np.radians(gamma_deg + 0.4 * np.sign(gamma_deg) * np.sin(w.t / 20.0))
        out = truth.evaluate(w.Fz, kappa, w.alpha, gamma, w.Vx, w.p, w.T)
        noise = [20.0 * rng.standard_normal(len(w.t)) for _ in range(2)]
        return dataclasses.replace(w, prefix=prefix, kappa=kappa, gamma=gamma,
                                   Fx=out.Fx + noise[0], Fy=out.Fy + noise[1], Mx=None,
                                   My=None, Mz=out.Mz)  # fmt: skip

    diag = diagnose([wheel("/car/fl", 1.5), wheel("/car/fr", -1.5)], model)
    log = "\n".join(diag.details["log"])
    assert diag.effects[0].name == "camber", log
    tirs = diag.improved_models
    assert tirs["/car/fl"].params["RVY3"] == tirs["/car/fr"].params["RVY3"], log
    assert tirs["/car/fl"].params["RVY3"] == pytest.approx(truth.params["RVY3"], rel=0.15), log


def test_friction_relative_to_the_files_reference_speed_is_named_and_carried(model):
    """The file is the tyre at its reference speed V0 (LONGVL), its fall beyond the peak the
    friction of the sliding speeds V0 |s| there; the rig runs 0.6, 1 and 1.6 V0 and friction
    follows the sliding speed V |s| (0.8 + 0.2 exp(-Vs / 1.3 m/s), a brush's kinetic law). An
    absolute law in Vs rescales the file's curve at V0 too (unseen brush speed, seed 24:
    held-out 37 -> 25 N, floor 18); relative to V0 it is named, carried with its reference
    speed, and it predicts the held-out sweeps within twice the noise (5 knots in ln Vs)."""
    wheels, _ = _session(model, {"noise": True})
    w, rng = wheels[0], np.random.default_rng(4)
    V0 = model.params["LONGVL"]
    V = V0 * np.array([0.6, 1.0, 1.6])[(w.t // 25.0).astype(int) % 3]
    slip = np.hypot(w.kappa, np.tan(w.alpha))
    s = (0.8 + 0.2 * np.exp(-V * slip / 1.3)) / (0.8 + 0.2 * np.exp(-V0 * slip / 1.3))
    out = model.evaluate(w.Fz, w.kappa / s, np.arctan(np.tan(w.alpha) / s), w.gamma, V, w.p, w.T)
    noise = [20.0 * rng.standard_normal(len(w.t)) for _ in range(2)]
    wheel = dataclasses.replace(w, Vx=V, Fx=out.Fx * s + noise[0], Fy=out.Fy * s + noise[1],
                                Mx=None, My=None, Mz=out.Mz * s)  # fmt: skip
    diag = diagnose([wheel], model)
    log = "\n".join(diag.details["log"])
    assert diag.effects[0].name == "speed", log
    fx = diag.node_effects().for_wheel(w.prefix)
    assert fx is not None and fx.speed_reference_mps == pytest.approx(V0), log
    before, after = (diag.fit[k]["Fy"]["rmse"] for k in ("heldout_baseline", "heldout_improved"))
    assert after < 0.4 * before and after < 2.0 * 20.0, (diag.fit, log)


def test_a_local_effect_is_credited_with_relieving_the_baseline_but_not_with_more():
    """Support: an effect acting in one corner gains 30 there (noise units) and 70 outside,
    where the baseline fitted without the corner gains 60 (relief: the baseline no longer
    bends to the corner): 90 of 100 are its own, supported. With no relief the 70 outside is
    the refitted baseline doing something else: 30 %, not supported."""
    rel, share, n = region_gains(np.array([100.0, 70.0, 70.0, 200, 60.0]))
    assert share == pytest.approx(0.9) and supported(rel, share, n)
    rel, share, n = region_gains(np.array([100.0, 70.0, 70.0, 200, 0.0]))
    assert share == pytest.approx(0.3) and not supported(rel, share, n)
    rel, share, n = region_gains(np.array([100.0, 70.0, 70.0, 200, -5.0]))  # no worse than none
    assert share == pytest.approx(0.3)


def _backward(
    monkeypatch: pytest.MonkeyPatch, loses: dict[frozenset[str], list[float]], base: str
) -> tuple[list[tuple[str, str]], list[str]]:
    """The backward step on effects named by letters, each set of effects left in scoring
    the held-out per-sweep errors ``loses`` gives it; the effects in and the log after it."""
    from tire_model_ros.diagnosis import search
    from tire_model_ros.diagnosis.effects.base import EffectModel, Param

    def effect(name: str) -> type[EffectModel]:
        def init(self: EffectModel) -> None:
            EffectModel.__init__(self, [Param("a", 0, 0, 1, 1)])

        return type(name, (EffectModel,), {"word": name, "label": "", "__init__": init})

    names = sorted(max(loses, key=len))
    models = {k: effect(k)() for k in names}

    def trial(left: frozenset[str]) -> search.Trial:
        sc = _score(loses[left], sum(loses[left]) / 100 / len(loses[left]))
        return search.Trial(None, [models[k] for k in sorted(left)], [], sc, [sc, sc])  # type: ignore[arg-type]

    def without(cur: search.Trial, key: search.Key, hold: object = ()) -> search.Trial:
        return trial(frozenset(type(m).__name__ for m in cur.models) - {key[0]})

    monkeypatch.setattr(search, "without", without)
    keys = [(k, "") for k in names]
    library = {key: {"w": models[key[0]]} for key in keys}
    cur = search.Joint({"w": trial(frozenset(names))}, keys)
    log: list[str] = []
    out, _, _ = search._backward(cur, search.Joint({"w": trial(frozenset(base))}), log, library)  # type: ignore[arg-type]
    return out.keys, log


def test_backward_step_drops_the_effect_the_model_loses_least_without(monkeypatch):
    """Two overlapping effects (the first accepted, camber, and one that shadows it, an
    offset) and a third the data need: without either of the two the loss is not significant,
    but the model loses less without the shadow, so the shadow goes; once one is out, the
    other is needed. Dropping the first in order instead would keep the shadow."""
    full = [100.0] * 40
    loses = {  # held-out per-sweep error with the effects left in
        frozenset("ABC"): full,
        frozenset("BC"): [101.0, 99.5] * 20,  # without A: a little worse, not significant
        frozenset("AC"): [100.2, 99.9] * 20,  # without B: the least loss
        frozenset("AB"): [160.0] * 40,
        frozenset("A"): [150.0] * 40,
        frozenset("B"): [150.0] * 40,
        frozenset("C"): [150.0] * 40,
    }
    keys, log = _backward(monkeypatch, loses, "C")
    assert keys == [("A", ""), ("C", "")]
    assert len(log) == 1 and log[0].startswith("dropped")


def test_backward_step_keeps_an_effect_the_model_loses_much_without_on_a_few_sweeps(monkeypatch):
    """A speed law that matters on a few sweeps (without it 4 of 40 sweeps are 5 times worse,
    the rest a little better: not significant by the count of sweeps) and a step in time that
    shadows part of it (without the step every sweep a little worse: significant). The model
    loses least without the step, and that loss is significant: both stay. Dropping the
    speed law because its loss alone was not significant named the step for brush speed
    seed 21, whose held-out Fy then got worse (52 -> 61 N)."""
    loses = {
        frozenset("SD"): [200.0] * 40,
        frozenset("D"): [1000.0] * 4 + [188.0] * 36,  # without S: a few sweeps far worse
        frozenset("S"): [230.0, 226.0] * 20,  # without D: every sweep a little worse
        frozenset(): [1050.0] * 4 + [235.0] * 36,
    }
    keys, log = _backward(monkeypatch, loses, "")
    assert keys == [("D", ""), ("S", "")] and not log


def _swap(
    monkeypatch: pytest.MonkeyPatch,
    loses: dict[frozenset[str], list[float]],
    words: dict[str, str],
    runner_up: dict[str, str] | None = None,
) -> tuple[list[tuple[str, str]], list[str]]:
    """The swap step on models named by letters of the given words (the letters of
    ``max(loses)`` in, each chosen ahead of its ``runner_up``): each set of models in scoring
    the held-out per-sweep errors ``loses`` gives it, every swap believed (the evidence tests
    are tested on their own)."""
    from tire_model_ros.diagnosis import search
    from tire_model_ros.diagnosis.effects.base import EffectModel, Param

    def effect(name: str) -> EffectModel:
        def init(self: EffectModel) -> None:
            EffectModel.__init__(self, [Param("a", 0, 0, 1, 1)])

        cls = type(name, (EffectModel,), {"word": words[name], "label": "", "__init__": init})
        return cls()

    models = {k: effect(k) for k in words}

    def joint(names: list[str]) -> search.Joint:
        left = loses[frozenset(names)]
        sc = _score(left, sum(left) / 100 / len(left))
        t = search.Trial(None, [models[k] for k in names], [], sc, [sc, sc])  # type: ignore[arg-type]
        return search.Joint({"w": t}, [(k, "") for k in names])

    def joint_add(cur: search.Joint, key: search.Key, ms: object, everything: bool = False):  # type: ignore[no-untyped-def]
        return joint([k for k, _ in cur.keys] + [key[0]])

    monkeypatch.setattr(search, "joint_add", joint_add)
    monkeypatch.setattr(
        search, "_without", lambda cur, key: joint([k for k, _ in cur.keys if k != key[0]])
    )
    monkeypatch.setattr(search, "_believed", lambda *a: True)
    library = {(k, ""): {"w": models[k]} for k in words}
    log: list[str] = []
    runner = {(k, ""): (r, "") for k, r in (runner_up or {}).items()}
    out = search._swap(joint(sorted(max(loses, key=len))), {}, runner, library, log)  # type: ignore[arg-type]
    return out.keys, log


def test_a_model_chosen_before_the_others_gives_way_to_one_of_its_word_that_does_better(
    monkeypatch,
):
    """A friction step (S) was chosen first, before the speed law (V) whose blocks ran in time
    order; given V, wear (W, the same word) predicts every held-out sweep better: it takes S's
    place. One that does better on half the sweeps by less than the margin does not."""
    words = {"S": "drift", "W": "drift", "V": "speed"}
    loses = {frozenset("SV"): [120.0] * 40, frozenset("V"): [150.0] * 40,
             frozenset("WV"): [100.0] * 40, frozenset("S"): [200.0] * 40}  # fmt: skip
    keys, log = _swap(monkeypatch, loses, words)
    assert sorted(keys) == [("V", ""), ("W", "")] and log[0].startswith("swapped"), log
    loses[frozenset("WV")] = [119.0, 121.0] * 20
    keys, log = _swap(monkeypatch, loses, words)
    assert sorted(keys) == [("S", ""), ("V", "")] and not log, log


def test_a_model_chosen_before_the_others_gives_way_to_its_steps_runner_up_that_does_better(
    monkeypatch,
):
    """Concealed heating (T) was chosen ahead of wear (W) and the speed law (V) came after it:
    T's fast tread node stood in for V, its slow carcass for W (flattrac multi3 s1). Given V,
    W, the runner-up of T's step, predicts every held-out sweep better: it takes T's place.
    Another effect that was not the runner-up is not tried, nor a runner-up of a word
    already chosen (V itself)."""
    words = {"T": "temperature", "W": "drift", "V": "speed"}
    loses = {frozenset("TV"): [120.0] * 40, frozenset("V"): [150.0] * 40,
             frozenset("WV"): [100.0] * 40, frozenset("T"): [130.0] * 40}  # fmt: skip
    keys, log = _swap(monkeypatch, loses, words, {"T": "W"})
    assert sorted(keys) == [("V", ""), ("W", "")] and log[0].startswith("swapped"), log
    for runner_up in ({}, {"T": "V"}):
        keys, log = _swap(monkeypatch, loses, words, runner_up)
        assert sorted(keys) == [("T", ""), ("V", "")] and not log, (runner_up, log)


def test_the_final_refit_starts_from_the_folds_fit_that_fits_best_not_their_mean(model):
    """The two selection folds fitted a friction scale 1 and 1.4 (a non-convex model's two
    fits can be far apart): their mean, 1.2, fits the training sweeps worse than either; the
    final refit starts from the better one. A parameter held for the wheels of a car (here
    the baseline's) keeps the mean, one value for every wheel."""
    from tire_model_ros.diagnosis.effects.baseline import Scaling
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel
    from tire_model_ros.diagnosis.result import _final_start, set_noise

    wheels, _ = _session(model, {"noise": True})
    ctx = make_context(prepare_wheel(wheels[0], model, np.random.default_rng(0)), model)
    set_noise(ctx)
    m = Scaling(ctx)
    xs = [np.ones(m.n), np.full(m.n, 1.4)]
    rows = ctx.rows["ab"]
    x = _final_start([m], ctx, rows, xs, np.ones(m.n, bool))
    assert np.all(x == 1.0)
    held = np.zeros(m.n, bool)
    assert np.allclose(_final_start([m], ctx, rows, xs, held), 1.2)


def test_the_input_smoother_window_follows_each_channels_noise_and_pace():
    """A slow sweep under sensor noise is smoothed over a long window, a fast input with little
    noise over a short one (a fixed 90 ms window distorted a car's load transfer and brake
    slip); either way the smoothed input is nearer the true one than the recorded. Noise that
    a DAQ's anti-alias filter has coloured is smoothed as long as white noise is (generalised
    cross-validation took it for signal and kept the shortest window: a flattrac null's slip
    noise then passed into the forces, and a relaxation length fitted to that noise was named
    on it)."""
    from scipy.signal import firwin, sawtooth

    from tire_model_ros.diagnosis.prepare import SMOOTH_WINDOWS, cv_window, savgol

    rng = np.random.default_rng(3)
    t = np.arange(0.0, 60.0, 0.01)
    slow = 0.1 * np.sin(2 * np.pi * t / 10.0)
    sweeps = np.radians(8.0) * sawtooth(2 * np.pi * t / 8.0, 0.5)  # +-8 deg at 4 deg/s
    fast = 1000.0 * np.sin(2 * np.pi * t / 0.2) * np.sin(2 * np.pi * t / 7.0)
    fir = firwin(31, 36.0, fs=100.0)  # a 100 Hz DAQ's anti-alias filter
    coloured = np.convolve(rng.standard_normal(len(t)), fir, "same") / np.sqrt(fir @ fir)
    cases = (
        (slow, 3e-3 * rng.standard_normal(len(t)), 21, 0.5),
        (sweeps, 4e-4 * coloured, 15, 0.6),  # generalised CV: 5 samples, 0.83 of the noise
        (fast, 5.0 * rng.standard_normal(len(t)), None, 0.8),
    )
    for true, noise, longer_than, left in cases:
        w = cv_window(true + noise)
        out = savgol(true + noise, w)
        assert np.sqrt(np.mean((out - true) ** 2)) < left * np.std(noise), w
        if longer_than is not None:
            assert w >= longer_than, w
        else:
            assert w < 9, w
            fixed = np.sqrt(np.mean((smooth_fixed(true + noise, 9) - true) ** 2))
            assert np.sqrt(np.mean((out - true) ** 2)) < fixed
    assert set(SMOOTH_WINDOWS) >= {7, 61}


Windows = dict[str, int]


def _shortened(
    model: TireModel,
    Fz: np.ndarray,
    alpha: np.ndarray,
    noise: dict[str, np.ndarray],
    rng: np.random.Generator,
) -> tuple[Windows, Windows, float, float]:
    """The cross-validated and the shortened windows of a recording of ``model`` (true
    inputs plus ``noise``; forces with 20 N of noise), and each's force error against the true
    forces [N]."""
    from tire_model_ros.diagnosis.prepare import SMOOTHED, cv_window, savgol, shorten

    n = len(Fz)
    true = {"kappa": np.zeros(n), "alpha": alpha, "gamma": np.zeros(n), "Fz": Fz,
            "V": np.full(n, 16.7)}  # fmt: skip
    raw = {k: true[k] + noise.get(k, 0.0) for k in SMOOTHED}
    o = model.evaluate(Fz, true["kappa"], alpha, true["gamma"], Vx=true["V"], full=False)
    meas = {ch: np.asarray(getattr(o, ch)) + 20.0 * rng.standard_normal(n) for ch in ("Fx", "Fy")}
    cv = {k: cv_window(raw[k]) for k in SMOOTHED}
    short = shorten(raw, cv, model, meas, {"p": None, "T": None}, np.zeros(n, dtype=bool))

    def err(windows: dict[str, int]) -> float:
        x = {k: savgol(raw[k], windows[k]) for k in SMOOTHED}
        e = model.evaluate(x["Fz"], x["kappa"], x["alpha"], x["gamma"], Vx=x["V"], full=False)
        return float(np.sqrt(np.mean((np.asarray(e.Fy) - np.asarray(o.Fy)) ** 2)))

    return cv, short, err(cv), err(short)


def test_the_forces_shorten_a_window_that_distorts_a_fast_load(model):
    """A car's load transfer (here +-1.5 kN in 50 ms, every 1.5 s) with a load cell's 17 N of
    noise: the cross-validated window rounds it off; the file model's forces against the
    measured ones ask for a shorter one, and the forces on the inputs so smoothed are nearer
    the true ones."""
    from scipy.ndimage import uniform_filter1d

    rng = np.random.default_rng(5)
    t = np.arange(0.0, 120.0, 0.01)
    Fz = 4000.0 + 1500.0 * uniform_filter1d(np.sign(np.sin(2 * np.pi * t / 3.0)), 5)
    alpha = np.radians(4.0) * np.sin(2 * np.pi * t / 6.0)
    cv, short, e_cv, e_short = _shortened(
        model, Fz, alpha, {"Fz": 17.0 * rng.standard_normal(len(t))}, rng
    )
    assert short["Fz"] < cv["Fz"], (cv, short)
    assert e_short < 0.8 * e_cv, (e_cv, e_short)
    assert all(short[k] <= cv[k] for k in cv), (cv, short)  # never longer


def test_the_forces_keep_a_long_window_on_slip_noise_a_daq_coloured(model):
    """Slow slip-angle sweeps under DAQ-coloured noise (which let a relaxation length fitted
    to the noise be named on a null): shortening the window would pass that noise into the
    forces, and the forces do not ask for it."""
    from scipy.signal import firwin, sawtooth

    rng = np.random.default_rng(6)
    t = np.arange(0.0, 120.0, 0.01)
    alpha = np.radians(8.0) * sawtooth(2 * np.pi * t / 8.0, 0.5)  # +-8 deg at 4 deg/s
    fir = firwin(31, 36.0, fs=100.0)
    coloured = np.convolve(rng.standard_normal(len(t)), fir, "same") / np.sqrt(fir @ fir)
    noise = {"alpha": 4e-4 * coloured}
    cv, short, e_cv, e_short = _shortened(model, np.full(len(t), 4000.0), alpha, noise, rng)
    assert short["alpha"] >= 9, (cv, short)
    assert e_short <= e_cv


def test_a_nan_stretch_in_an_input_is_bridged_left_out_and_counted(model):
    """A load cell that sends NaN for 3 s: the load is bridged between its neighbours (never
    zero, which the smoother would spread into good samples), those samples are fitted and
    scored on by nothing, and the diagnosis says how many there were."""
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    (w,), _ = _session(model, {})
    i = np.flatnonzero(w.t - w.t[0] >= 100.0)[:300]
    Fz = np.array(w.Fz, dtype=float)
    Fz[i] = np.nan
    gappy = dataclasses.replace(w, Fz=Fz)
    pw = prepare_wheel(gappy, model, np.random.default_rng(0))
    good = prepare_wheel(w, model, np.random.default_rng(0))
    assert pw.gaps == {"Fz": 300}
    assert np.flatnonzero(pw.bridged).tolist() == i.tolist()
    fz = pw.x("Fz")
    assert np.isfinite(fz).all()
    lo, hi = sorted((w.Fz[i[0] - 1], w.Fz[i[-1] + 1]))
    assert lo - 200.0 <= fz[i].min() and fz[i].max() <= hi + 200.0  # no zero-load stretch
    near = np.r_[i[0] - 100 : i[0], i[-1] + 1 : i[-1] + 101]
    assert np.max(np.abs(fz[near] - good.x("Fz")[near])) < 200.0  # neighbours unharmed
    ctx = make_context(pw, model)
    for rows in ctx.rows.values():
        if len(rows) < pw.n:
            assert not np.isin(rows, i).any()
    d = diagnose([gappy], model)
    assert any("Fz 300 samples" in line and "bridged" in line for line in d.details["log"])
    assert d.to_json()["inputs_bridged"] == {w.prefix: {"Fz": 300}}
    assert np.all(np.isfinite(d.wheels[w.prefix].predictions["improved_Fy"]))


def test_a_nan_stretch_in_a_recorded_temperature_is_bridged_not_a_step_to_its_median(model):
    """A temperature channel that sends NaN for 3 s while the tyre heats: bridged between its
    neighbours (its median would be a step down and back, which a lag of it, the carcass,
    carries on), left out of the fits and counted."""
    from tire_model_ros.diagnosis.prepare import make_context, prepare_wheel

    (w,), _ = _session(model, {"heating": True})
    assert w.T is not None
    i = np.arange(300) + int(0.05 * len(w.t))  # early: the tyre still cool
    T = np.array(w.T, dtype=float)
    T[i] = np.nan
    rng = np.random.default_rng(0)
    pw = prepare_wheel(dataclasses.replace(w, T=T), model, rng)
    assert pw.gaps == {"T": 300}
    got = pw.inputs["T"]
    assert got is not None and np.isfinite(got).all()
    lo, hi = sorted((w.T[i[0] - 1], w.T[i[-1] + 1]))
    assert lo - 1.0 <= got[i].min() and got[i].max() <= hi + 1.0
    assert abs(float(np.median(w.T)) - lo) > 2.0  # the median would have been a step
    ctx = make_context(pw, model)
    assert not np.isin(ctx.rows["ab"], i).any()
    # a channel with no finite sample is not recorded (said), a load without one is refused
    none = prepare_wheel(dataclasses.replace(w, T=np.full(len(T), np.nan)), model, rng)
    assert none.inputs["T"] is None and none.dropped == ("T",) and not none.bridged.any()
    with pytest.raises(ValueError, match="Fz has no finite sample"):
        prepare_wheel(dataclasses.replace(w, Fz=np.full(len(T), np.nan)), model, rng)


def smooth_fixed(x: np.ndarray, w: int) -> np.ndarray:
    from scipy.signal import savgol_filter

    return np.asarray(savgol_filter(x, w, 2, mode="interp"))
