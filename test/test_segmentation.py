"""Sweeps and conditions found from the data (``fit.sweeps.split_segments``) on real-style
programmes: the FSAE TTC's continuous cornering sweeps over load, inclination and pressure
blocks (no pause between, load and inclination following the force), its drive/brake runs
(slip-ratio sweeps at held slip angles), a secondary slip that follows the swept one, and a
slow sensor logged with sample and hold."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import DEFAULT_TIR

from tire_model_ros.fit.sweeps import split_segments
from tire_model_ros.recording.series import WheelSeries
from tire_model_ros.rig import simulate_session

DEG = math.pi / 180.0


def _session(programme: str):
    wheels, truth = simulate_session(
        DEFAULT_TIR, programme, rate_hz=50.0, programme_options={"rate_scale": 2.0}, seed=3
    )
    return wheels[0], truth["wheels"]["/rig/wheel"]["segments"]


def _sweeps(segs):
    out: dict[int, list] = {}
    for g in segs:
        if g.sweep >= 0:
            out.setdefault(g.sweep, []).append(g)
    return out


def _truth_sweep(truth_segs, kind, t_mid):
    for x in truth_segs:
        if x["kind"] == kind and x["t0_s"] <= t_mid <= x["t1_s"]:
            return x
    return None


@pytest.fixture(scope="module")
def cornering():
    s, truth = _session("ttc_cornering")
    return s, truth, split_segments(s)


def test_ttc_cornering_sweeps_one_by_one(cornering):
    s, truth, segs = cornering
    t = s.t - s.t[0]
    programme = [x for x in truth if x["kind"] == "lateral_sweep" and x["label"] != "conditioning"]
    found = {}
    for members in _sweeps(segs).values():
        i = np.concatenate([g.index for g in members])
        x = _truth_sweep(truth, "lateral_sweep", float(np.median(t[i])))
        assert x is not None
        if x["label"] == "conditioning":
            continue
        # the whole programme sweep and nothing else: 0 -> +A -> -A -> 0 in three ramps
        assert [g.label for g in members] == ["ramp alpha+", "ramp alpha-", "ramp alpha+"]
        assert abs(t[i[0]] - x["t0_s"]) < 0.3 and abs(t[i[-1]] - x["t1_s"]) < 0.3
        found[x["label"]] = members
    assert len(found) == len(programme) == 36


def test_ttc_cornering_conditions_are_the_programmes_blocks(cornering):
    s, truth, segs = cornering
    t = s.t - s.t[0]
    levels = {k: sorted({round(g.condition[k], 6) for g in segs if k in g.condition})
              for k in ("Fz", "gamma", "p")}  # fmt: skip
    assert len(levels["Fz"]) == 4 and len(levels["gamma"]) == 3 and len(levels["p"]) == 3
    for members in _sweeps(segs).values():
        x = _truth_sweep(truth, "lateral_sweep", float(np.median(t[members[0].index])))
        for g in members:  # every ramp of the sweep carries the block's levels
            assert g.condition["Fz"] == pytest.approx(x["Fz_N"], rel=0.02)
            assert g.condition["gamma"] == pytest.approx(x["gamma_deg"] * DEG, abs=0.1 * DEG)
            assert g.condition["p"] == pytest.approx(x["p_Pa"], rel=0.01)
            assert "Fz" not in g.direction and "gamma" not in g.direction
    # the load, inclination and pressure changes between sweeps are segments of their own
    changes = [g for g in segs if g.kind == "ramp" and not g.slips]
    assert sum("Fz" in g.direction for g in changes) >= 30
    assert sum("p" in g.direction for g in changes) == 2


def test_ttc_drive_brake_sweeps_at_held_slip_angles():
    s, truth = _session("ttc_drive_brake")
    segs = split_segments(s)
    t = s.t - s.t[0]
    held = sorted(
        {round(math.degrees(g.condition["alpha"]), 1) for g in segs if g.slips == ("kappa",)}
    )
    assert held == [-6.0, -3.0, 0.0]
    n = 0
    for members in _sweeps(segs).values():
        if members[0].slips != ("kappa",):
            continue
        x = _truth_sweep(truth, "longitudinal_sweep", float(np.median(t[members[0].index])))
        if x["label"] == "conditioning":
            continue
        assert [g.label for g in members] == ["ramp kappa-", "ramp kappa+", "ramp kappa-"]
        assert members[0].condition["Fz"] == pytest.approx(x["Fz_N"], rel=0.02)
        want = float(x["label"].split("alpha=")[1].split("deg")[0])
        assert math.degrees(members[0].condition["alpha"]) == pytest.approx(want, abs=0.2)
        n += 1
    assert n == 3 * 2 * 3 * 3


def _synthetic(dt=0.01):
    """Two cornering sweeps with a pause between; kappa follows alpha (a real rig's slip ratio
    wanders with the slip angle), pressure is logged at 10 Hz with sample and hold."""
    rng = np.random.default_rng(1)
    A = 8 * DEG
    leg = np.linspace(0, 1, round(2.0 / dt), endpoint=False)
    sweep = np.concatenate([A * leg, A - 2 * A * leg, -A + A * leg])
    alpha = np.concatenate([sweep, np.zeros(round(3.0 / dt)), sweep])
    n = len(alpha)
    kappa = 0.01 * alpha / A + rng.normal(0, 2e-4, n)
    p = 2e5 + rng.normal(0, 800, n)
    p = p[(np.arange(n) // 10) * 10]  # 10 Hz sample and hold
    return WheelSeries(
        "/w", np.arange(n) * dt, kappa, alpha + rng.normal(0, 0.02 * DEG, n), np.zeros(n),
        4000 + rng.normal(0, 20, n), p=p,
    )  # fmt: skip


def test_following_slip_and_held_sensor_do_not_cut():
    segs = split_segments(_synthetic())
    sweep = ["ramp alpha+", "ramp alpha-", "ramp alpha+"]
    assert [g.label for g in segs] == [*sweep, "pause", *sweep]
    assert [g.sweep for g in segs] == [0, 0, 0, -1, 1, 1, 1]
