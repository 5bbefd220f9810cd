"""The node's per-wheel logic without ROS: inputs aligned by header stamp with the offline
tool's rule, staleness in stamp time, saturation counted, every slip accounted for."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import DEFAULT_TIR

from tire_model_ros.delivery import NODE, parse_reports
from tire_model_ros.model import TireModel
from tire_model_ros.model.states import EffectState, Node, WheelEffects
from tire_model_ros.recording.align import hold_latest, latest_at_or_before
from tire_model_ros.vocabulary import NODE_INPUTS, NS_PER_S
from tire_model_ros.wheel.history import StampedHistory
from tire_model_ros.wheel.hold import RELEASES, PendingSlip, SlipHold
from tire_model_ros.wheel.state import (
    UNANSWERED,
    Settings,
    WheelModel,
    WheelState,
    final_line,
)

S = NS_PER_S


@pytest.fixture(scope="module")
def wm() -> WheelModel:
    return WheelModel.of(TireModel.from_file(DEFAULT_TIR))


def settings(timeout_s: float = 0.0, limits: bool = True, skip: bool = False) -> Settings:
    return Settings.of(dict.fromkeys(NODE_INPUTS, timeout_s), limits, skip)


def test_history_takes_the_offline_rule_in_any_arrival_order():
    """Random stamps put in a random order: every lookup equals the offline reader's
    latest_at_or_before on the sorted stamps (of equal stamps the later arrival)."""
    rng = np.random.default_rng(3)
    stamps = np.sort(rng.integers(0, 50, 40)) * 1_000_000  # with repeats
    values = rng.normal(size=40)
    h = StampedHistory()
    order = rng.permutation(40)
    for i in order:
        h.put(int(stamps[i]), float(values[i]))
    kept = sorted(range(40), key=lambda i: (stamps[i], list(order).index(i)))
    s_sorted = stamps[kept]
    for t in rng.integers(-5, 55, 60) * 1_000_000:
        value, state, _ = h.at(int(t), 0)
        i = latest_at_or_before(s_sorted, np.array([t]))[0]
        if i < 0:
            assert state == "ahead" and value is None
        else:
            assert state == "ok" and value == values[kept[i]]
    assert len(h) == 40


def test_history_is_short_and_keeps_the_newest():
    h = StampedHistory(capacity=8)
    for k in range(100):
        h.put(k * 10, float(k))
    assert len(h) == 8 and h.latest() == (99.0, 990)
    assert h.at(925, 0)[:2] == (92.0, "ok")
    assert h.at(900, 0)[1] == "ahead"  # older than the history holds
    h.put(955, -1.0)  # late arrival, put in its place
    assert h.at(957, 0)[:2] == (-1.0, "ok") and h.at(990, 0)[0] == 99.0
    assert h.at(990, 5)[:2] == (99.0, "ok") and h.at(996, 5)[1] == "stale"


def test_node_and_offline_tool_pair_the_same_messages():
    """A bag-like stream: load at 7 Hz with jitter, slips at 50 Hz; each slip's load by the
    node's history equals align's choice for the whole recording (after the first load)."""
    rng = np.random.default_rng(5)
    load_ns = np.sort(rng.uniform(0, 3.0, 21) * S).astype(np.int64)
    slip_ns = np.arange(0, 3.0, 0.02)
    slip_ns = (slip_ns * S).astype(np.int64)
    i, _ = hold_latest(load_ns, slip_ns)
    w = WheelState("/w", "w")
    arrivals = sorted([(t, "load", k) for k, t in enumerate(load_ns)]
                      + [(t, "slip", k) for k, t in enumerate(slip_ns)])  # fmt: skip
    model = WheelModel.of(TireModel.from_file(DEFAULT_TIR))
    got = {}
    for t, kind, k in arrivals:
        if kind == "load":
            w.set_input("load", int(t), 3000.0 + 100.0 * k)
        else:
            out, _ = w.compute(0.05, 0.0, 0.0, int(t), model, settings())
            got[k] = out[2]
    for k, t in enumerate(slip_ns):
        if t >= load_ns[0]:
            assert got[k] == 3000.0 + 100.0 * i[k], k
        else:
            assert got[k] == model.nominal.Fz  # the node cannot hold backwards


def test_paused_and_fast_forwarded_stamp_time(wm):
    """A 2 s pause between a load @100.0 s and a slip @100.2 s: fresh (0.2 s of stamp time);
    10 s of stamp time later the load is stale whatever the wall clock did."""
    w = WheelState("/w", "w")
    st = settings(0.3)
    w.set_input("load", 100 * S, 3000.0)
    out, _ = w.compute(0.05, 0.0, 0.0, 100 * S + S // 5, wm, st)
    assert out[2] == 3000.0
    out, events = w.compute(0.05, 0.0, 0.0, 110 * S, wm, st)
    assert out[2] == wm.nominal.Fz and w.inputs["load"].fallback["stale"] == 1
    assert any("stale" in e for e in events)


def test_future_stamped_load_waits_for_its_time(wm):
    w = WheelState("/w", "w")
    w.set_input("load", 150 * S, 3000.0)
    w.set_input("load", 150 * S + S // 2, 5000.0)  # @150.5 s arrives before the slip @150.2 s
    assert w.compute(0.05, 0.0, 0.0, 150 * S + S // 5, wm, settings())[0][2] == 3000.0
    assert w.compute(0.05, 0.0, 0.0, 150 * S + S * 6 // 10, wm, settings())[0][2] == 5000.0
    w2 = WheelState("/w", "w")
    w2.set_input("load", 151 * S, 3000.0)  # only a load after the slip: none at or before it
    out, _ = w2.compute(0.05, 0.0, 0.0, 150 * S, wm, settings())
    assert out[2] == wm.nominal.Fz and w2.inputs["load"].fallback["ahead"] == 1
    assert w2.compute(0.05, 0.0, 0.0, 150 * S, wm, settings(skip=True))[0] is None


def test_saturation_of_every_input_is_counted(wm):
    """500 degC and 1e12 N: saturated with the limits (force.z = FZMAX, Fx of TEMPMAX), as they
    are without (500 degC flips Fx); counted either way; a light load is not raised."""
    model = wm.model
    P = model.params
    w = WheelState("/w", "w")
    for name, value in (("load", 1e12), ("temperature", 500.0), ("pressure", 9e5),
                        ("velocity", 1e4)):  # fmt: skip
        w.set_input(name, 0, value)
    out, events = w.compute(5.0, 2.0, -1.0, S, wm, settings())
    want = model.evaluate_one(P["FZMAX"], 5.0, 2.0, -1.0, 150.0, 9e5, 500.0)  # model saturates
    assert out == pytest.approx(want, rel=1e-12) and out[2] == P["FZMAX"]
    assert all(n == 1 for n in w.out_of_range.values())
    assert "saturated" in events[-1]
    w = WheelState("/w", "w")
    w.set_input("load", 0, 5000.0)
    w.set_input("temperature", 0, 500.0)
    hot = w.compute(0.1, 0.0, 0.0, S, wm, settings(limits=False))[0]
    nominal = w.compute(0.1, 0.0, 0.0, S, wm, settings(limits=True))[0]
    assert hot[0] < 0.0 < nominal[0] and w.out_of_range["temperature"] == 2
    ranged = WheelModel.of(model.with_params({"FZMIN": 500.0}))
    w.set_input("load", 2 * S, 100.0)
    out, _ = w.compute(0.1, 0.0, 0.0, 2 * S, ranged, settings())
    assert out[2] == 100.0 and w.out_of_range["load"] == 1


def test_every_slip_is_answered_or_counted(wm):
    w = WheelState("/w", "w")
    w.malformed("slip")
    w.malformed("load")
    w.inactive()
    assert w.set_input("load", 0, math.nan) is not None
    assert w.set_input("pressure", 0, -1.0) is not None
    assert w.set_input("temperature", 0, -300.0) is not None
    w.compute(math.nan, 0.0, 0.0, S, wm, settings())
    w.compute(0.1, 0.0, 0.0, S, wm, settings(skip=True))  # no load yet
    w.set_input("load", 0, -10.0)  # off the ground
    assert w.compute(0.1, 0.0, 0.0, S, wm, settings())[0] == (0.0,) * 6
    w.set_input("load", 0, 4000.0)
    w.compute(0.1, 0.0, 0.0, 2 * S, wm, settings())
    c = w.counters()
    assert c["slip_in"] == c["forces_out"] + sum(c[k] for k in UNANSWERED) == 6
    assert (c["slip_malformed"], c["slip_inactive"], c["slip_rejected"]) == (1, 1, 1)
    assert (c["skipped_no_load"], c["no_contact"], c["load.malformed"]) == (1, 1, 1)
    assert c["load.rejected"] == c["pressure.rejected"] == c["temperature.rejected"] == 1
    w.unpublished("publish failed: context invalid")  # SIGTERM under the callback
    c = w.counters()
    assert c["slip_in"] == c["forces_out"] + sum(c[k] for k in UNANSWERED) == 6
    assert c["publish_failed"] == 1
    assert parse_reports("x\n" + final_line("/w", c) + "\n", NODE) == {"/w": c}


def test_diagnostics_warn_while_the_last_slip_is_out_of_range(wm):
    """A hot tread WARNs in the period it came and in every period after it until a slip
    comes with its inputs in range, so a status never says "ok" over saturated outputs."""
    from tire_model_ros.ros.diagnostics import level_and_message

    w = WheelState("/w", "w")
    w.set_input("load", 0, 4000.0)
    w.set_input("temperature", 0, 500.0)
    before = w.counters()
    w.compute(0.1, 0.0, 0.0, S, wm, settings(timeout_s=10.0))
    delta = {k: v - before[k] for k, v in w.counters().items()}
    level, message, _, _ = level_and_message(delta, True, w.outside)
    assert level == b"\x01" and message == "out_of_range.temperature +1 (saturated, still)"
    level, message, _, _ = level_and_message({}, True, w.outside)  # no slip this period
    assert level == b"\x01" and message == "out_of_range.temperature +0 (saturated, still)"
    w.set_input("temperature", 2 * S, 40.0)
    w.compute(0.1, 0.0, 0.0, 2 * S, wm, settings(timeout_s=10.0))
    assert level_and_message({}, True, w.outside)[:2] == (b"\x00", "ok")


def test_an_absurd_slip_leaves_the_hidden_states_untouched(wm):
    """kappa = -1e6 once between normal samples, with an effects file: saturated, counted, and
    the hidden states go on as if it had not come (it does not drive them)."""
    fx = WheelEffects(thermal=Node(4.0, 5e-3), thermal_slow=Node(60.0, 2e-5))
    runs = []
    for absurd in (False, True):
        w = WheelState("/w", "w")
        w.effects = EffectState(fx)
        w.set_input("load", 0, 5000.0)
        w.set_input("velocity", 0, 15.0)
        rows = []
        for k in range(100):
            if absurd and k == 50:
                out, _ = w.compute(-1e6, 0.05, 0.0, k * 10_000_000 - 5_000_000, wm, settings())
                assert out is not None and all(math.isfinite(v) for v in out)
            rows.append(w.compute(0.1 * math.sin(k / 9), 0.05, 0.0, k * 10_000_000, wm,
                                  settings())[0])  # fmt: skip
        runs.append((np.array(rows), w))
    np.testing.assert_allclose(runs[1][0], runs[0][0], rtol=1e-12, atol=1e-9)
    assert runs[1][1].out_of_range["kappa"] == 1 and runs[0][1].out_of_range["kappa"] == 0
    assert runs[1][1].effects.y == pytest.approx(runs[0][1].effects.y, rel=1e-12)


def test_first_start_notice_when_loading_the_kernels_takes_long():
    """The node's start says what is happening when the kernels are not ready: quiet on a warm
    cache; the notice, then the time taken, when loading takes longer than the threshold (here
    a real numba compile of a small function against a zero threshold)."""
    from numba import njit

    from tire_model_ros.model.startup import COMPILE_NOTICE, cache_present, warm_up_announced

    assert cache_present()  # make venv compiled them
    quiet: list[str] = []
    warm_up_announced(quiet.append, notice_after_s=60.0)
    assert quiet == []
    said: list[str] = []

    def compile_one() -> float:
        return float(njit(cache=False)(lambda x: math.sin(x) * 2.0)(1.0))

    warm_up_announced(said.append, notice_after_s=0.0, load=compile_one)
    assert said[0] == COMPILE_NOTICE and said[1].startswith("kernels ready after")


# ------------------------------------------------------------------ holding a slip for its inputs
class Glue:
    """The node's glue around a wheel without ROS (``tire_model_ros.ros.node``): each slip goes
    through the hold, each input message too, a timer releases waited-out slips; ``out`` holds
    the answers (stamp, wrench) in the order they were computed. ``now`` is the ROS clock."""

    def __init__(self, wm: WheelModel, wait_s: float = 1.0, timeout_s: float = 0.3) -> None:
        self.w = WheelState("/w", "w")
        self.wm, self.st = wm, settings(timeout_s)
        self.wait = round(wait_s * S)
        self.now = 0
        self.out: list[tuple[int, tuple[float, ...] | None]] = []

    def _answer(self, slips: list[PendingSlip]) -> None:
        for p in slips:
            res, _ = self.w.compute(p.kappa, p.alpha, p.gamma, p.stamp_ns, self.wm, self.st)
            self.out.append((p.stamp_ns, res))

    def slip(self, stamp_ns: int, kappa: float = 0.05) -> None:
        slip = PendingSlip(kappa, 0.02, 0.0, stamp_ns, self.now)
        self._answer(self.w.hold.arrive(slip, self.now, self.wait))

    def input(self, name: str, stamp_ns: int, value: float) -> None:
        self.w.set_input(name, stamp_ns, value)
        self._answer(self.w.hold.take(name, stamp_ns, self.now, self.wait))

    def tick(self, now_ns: int) -> None:
        self.now = now_ns
        self._answer(self.w.hold.release(now_ns, self.wait))

    def loads(self) -> dict[int, float]:
        return {stamp: res[2] for stamp, res in self.out if res is not None}


MS = 1_000_000


def test_a_slip_before_its_load_is_held_and_answered_with_it(wm):
    g = Glue(wm)
    g.input("load", 0, 2000.0)
    g.slip(10 * MS)  # its load, stamped with it, is still in flight
    assert g.out == [] and g.w.hold.pending == 1
    g.input("load", 10 * MS, 3000.0)
    assert g.loads() == {10 * MS: 3000.0}  # not 2000 N (the load before), not FNOMIN
    g.input("load", 20 * MS, 3100.0)
    g.slip(20 * MS)  # its load came first: answered on arrival
    assert g.loads()[20 * MS] == 3100.0
    c = g.w.counters()
    assert (c["held"], c["released_caught_up"], c["released_by_wait"]) == (1, 1, 0)
    want = wm.model.evaluate_one(3000.0, 0.05, 0.02, 0.0, wm.nominal.Vx, wm.nominal.p,
                                 wm.nominal.T)  # fmt: skip
    assert g.out[0][1] == pytest.approx(want, rel=1e-12)


def test_the_usual_slip_is_answered_without_a_look_at_the_clock():
    """Nothing pending and every input received already at the slip's stamp: ``quick``, a
    comparison; an input never received does not count, one behind sends the slip to
    ``arrive`` (which needs the clock)."""
    hold = SlipHold(NODE_INPUTS)
    assert hold.quick(5 * S)  # nothing received: nothing to wait for
    hold.note("load", 10, 0)
    hold.note("velocity", 7, 0)
    assert hold.quick(7) and not hold.quick(8)
    assert hold.arrive(PendingSlip(0.0, 0.0, 0.0, 8, 2 * S), 2 * S, S)  # velocity stopped
    assert not hold.arrive(PendingSlip(0.0, 0.0, 0.0, 8, 0), 0, S)  # velocity arriving
    assert not hold.quick(7)  # behind a pending slip
    hold.note("velocity", 8, 0)
    assert hold.release(0, S) and hold.quick(8)


def test_late_loads_are_matched_as_the_offline_tool_matches_them(wm):
    """Slip and load share stamps every 10 ms; each load arrives up to 0.4 s after its slip
    (in order on its topic, as reliable back-pressure delays one topic): with the hold, every
    slip takes its own load, as ``align`` pairs them offline; answered on arrival, many
    would not."""
    rng = np.random.default_rng(12)
    n = 300
    stamps = np.arange(1, n + 1) * 10 * MS
    load_at = np.maximum.accumulate(stamps + rng.uniform(0, 0.4, n) * S).astype(np.int64)
    events = sorted([(int(t), 1, "slip", k) for k, t in enumerate(stamps)]
                    + [(int(t), 0, "load", k) for k, t in enumerate(load_at)])  # fmt: skip
    for wait_s in (1.0, 0.0):
        g = Glue(wm, wait_s=wait_s)
        g.input("load", 0, 2000.0)  # the stream has begun (a load never received is not awaited)
        for t, _, kind, k in events:
            g.tick(t)
            if kind == "slip":
                g.slip(int(stamps[k]))
            else:
                g.input("load", int(stamps[k]), 3000.0 + k)
        g.tick(load_at[-1] + 2 * S)
        right = sum(g.loads()[int(s)] == 3000.0 + k for k, s in enumerate(stamps))
        if wait_s:
            assert right == n and [s for s, _ in g.out] == list(stamps)
            c = g.w.counters()
            assert c["released_by_wait"] == 0 and c["held"] == c["released_caught_up"] > n // 2
            assert 200 < c["longest_catch_up_ms"] <= 400  # the longest delay of a load
        else:
            assert right < n // 2 and g.w.counters()["held"] == 0  # answered on arrival


def test_a_stopped_input_is_not_waited_for_after_the_bound(wm):
    """The load stops: the slips held for it wait at most one bound from its last arrival
    (not a bound each), are computed with what there is and counted; the next slip is
    answered on arrival."""
    g = Glue(wm, wait_s=1.0)
    g.input("load", 0, 3000.0)
    for k in range(1, 6):
        g.tick(k * 100 * MS)
        g.slip(k * 10 * MS)
    g.tick(999 * MS)
    assert g.out == [] and g.w.hold.pending == 5
    g.tick(S)  # one bound after the load's last arrival: it is no longer live
    assert g.loads() == {k * 10 * MS: 3000.0 for k in range(1, 6)}  # the load at 0, fresh
    assert g.w.counters()["released_by_wait"] == 5
    g.tick(S + 100 * MS)
    g.slip(60 * MS)
    assert g.loads()[60 * MS] == 3000.0 and g.w.counters()["held"] == 5


def test_a_slip_waits_at_most_the_bound_for_an_input_stamped_behind(wm):
    """The load keeps arriving but stamped behind the slips (another clock): each slip is
    released when it has waited the bound, on the ROS clock."""
    g = Glue(wm, wait_s=0.5)
    g.input("load", 0, 3000.0)
    g.tick(100 * MS)
    g.slip(S)
    for k in range(2, 6):  # the load goes on, never reaching 1 s of stamp time
        g.tick(k * 100 * MS)
        g.input("load", k * MS, 3000.0)
    assert g.out == []
    g.tick(599 * MS)
    assert g.out == []
    g.tick(600 * MS)  # arrival 0.1 s + 0.5 s
    assert [s for s, _ in g.out] == [S] and g.w.counters()["released_by_wait"] == 1
    # stale: the load's stamp is 0.994 s before the slip's (timeout 0.3 s)
    assert g.out[0][1][2] == wm.nominal.Fz and g.w.inputs["load"].fallback["stale"] == 1


def test_order_is_kept_and_a_zero_wait_answers_on_arrival(wm):
    g = Glue(wm)
    g.input("load", 0, 3000.0)
    g.input("velocity", 0, 20.0)
    g.slip(20 * MS)  # waits for both
    g.input("load", 30 * MS, 3100.0)
    assert g.out == []  # the velocity has not caught up
    g.slip(10 * MS)  # stamped before what both have seen: ready, but behind the pending one
    assert g.out == []
    g.input("velocity", 20 * MS, 21.0)
    assert [s for s, _ in g.out] == [20 * MS, 10 * MS]  # in arrival order
    g0 = Glue(wm, wait_s=0.0)
    g0.input("load", 0, 3000.0)
    g0.slip(20 * MS)
    assert g0.loads() == {20 * MS: 3000.0} and g0.w.counters()["held"] == 0


def test_overflow_releases_the_oldest_and_is_counted(wm):
    g = Glue(wm)
    g.w.hold.capacity = 3
    g.input("load", 0, 3000.0)
    for k in range(1, 6):
        g.slip(k * MS)
    assert [s for s, _ in g.out] == [1 * MS, 2 * MS] and g.w.hold.pending == 3
    g.input("load", 5 * MS, 3100.0)
    assert [s for s, _ in g.out] == [k * MS for k in range(1, 6)]
    assert set(g.loads().values()) == {3000.0, 3100.0}
    c = g.w.counters()
    assert (c["held"], c["released_by_overflow"], c["released_caught_up"]) == (5, 2, 3)


def test_every_held_slip_is_accounted_for(wm):
    """held = the releases + pending; once flushed (deactivation, shutdown) the node's
    invariant slip_in = forces_out + unanswered holds with every slip offered."""
    g = Glue(wm)
    g.input("load", 0, 3000.0)
    offered = 0
    for k in range(1, 61):  # the load stops after 1.5 s (the slips then wait it out), and
        g.tick(k * 50 * MS)  # comes back at 2.75 s behind the last slips (left pending)
        g.slip(k * 10 * MS, kappa=math.nan if k % 7 == 0 else 0.05)
        offered += 1
        if (k % 3 == 0 and k <= 30) or k == 55:
            g.input("load", k * 10 * MS, 3000.0 + k)
    g.w.malformed("slip")
    offered += 1

    def balanced() -> dict[str, int]:
        c = g.w.counters()
        released = sum(c[k] for k in RELEASES)
        assert c["held"] == released + g.w.hold.pending
        assert c["slip_in"] + g.w.hold.pending == offered
        assert c["slip_in"] == c["forces_out"] + sum(c[k] for k in UNANSWERED)
        return c

    assert balanced()["released_by_wait"] > 0 and g.w.hold.pending > 0
    g._answer(g.w.hold.flush())
    c = balanced()
    assert g.w.hold.pending == 0 and c["released_by_flush"] == 5 and c["slip_rejected"] == 8
    assert parse_reports(final_line("/w", c), NODE)["/w"]["held"] == c["held"]


def test_holding_is_normal_released_without_inputs_warns(wm):
    from tire_model_ros.ros.diagnostics import level_and_message

    assert level_and_message({"held": 4, "released_caught_up": 4, "forces_out": 4}, True)[:2] == (
        b"\x00",
        "ok",
    )
    for key in ("released_by_wait", "released_by_overflow"):
        level, message, _, _ = level_and_message({key: 2, "forces_out": 2}, True)
        assert level == b"\x01" and message == f"{key} +2"


def test_answers_beyond_the_fitted_envelope_are_said_but_not_a_warning():
    from tire_model_ros.ros.diagnostics import level_and_message

    level, message, _, warn = level_and_message({"outside_envelope": 40, "forces_out": 40}, True)
    assert (level, warn) == (b"\x00", []) and message == (
        "ok; outside_envelope +40 (beyond the fitted data)"
    )
    _, message, _, _ = level_and_message({"outside_envelope": 3, "load.malformed": 1}, True)
    assert message == "load.malformed +1; outside_envelope +3 (beyond the fitted data)"
