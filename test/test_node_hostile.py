"""tire_model_node inside a simulator and against hostile input (issue 12): a paused and a
fast-forwarded simulated clock, a future-stamped load, a slip that arrives before its load (held
for it) and one whose load never comes (released by the ROS clock), best-effort publishers,
malformed payloads from a fresh participant, a 500 degC tread and a 1e12 N load with the limits
on and off, kappa = -1e6 with an effects file, and the managed node through its transitions.

Real node processes, driven over loopback from this test process (``test/ros_util.py``).
"""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest
from conftest import DEFAULT_TIR
from ros_util import NodeProcess, RosClient, exited_cleanly, node_command, ros_env, wait_for

from tire_model_ros.delivery import NODE, UNANSWERED, parse_reports
from tire_model_ros.model import TireModel
from tire_model_ros.model.states import Effects, EffectState, Node, WheelEffects
from tire_model_ros.vocabulary import NODE_INPUTS
from tire_model_ros.wheel.state import Nominal

pytestmark = [pytest.mark.ros, pytest.mark.timeout(240)]

S = 1_000_000_000


def stamp_of(msg) -> int:
    return msg.header.stamp.sec * S + msg.header.stamp.nanosec


def stamped(msg, t_ns: int):
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(t_ns), S)
    return msg


def load_msg(Fz: float, t_ns: int):
    """A load message of ``Fz`` [N] stamped ``t_ns``."""
    from geometry_msgs.msg import WrenchStamped

    m = WrenchStamped()
    m.wrench.force.z = Fz
    return stamped(m, t_ns)


def slip_msg(t_ns: int, kappa: float = 0.05, alpha: float = 0.0):
    """A slip message (kappa, alpha [rad], no camber) stamped ``t_ns``."""
    from geometry_msgs.msg import Vector3Stamped

    s = Vector3Stamped()
    s.vector.x, s.vector.y = kappa, alpha
    return stamped(s, t_ns)


def wrench_row(m) -> list[float]:
    f, t = m.wrench.force, m.wrench.torque
    return [f.x, f.y, f.z, t.x, t.y, t.z]


class Box:
    """Messages of one subscription, thread-safe, looked up by stamp."""

    def __init__(self, client: RosClient, msg_type, topic: str, qos) -> None:
        self.items: list = []
        self.lock = threading.Lock()

        def cb(msg) -> None:
            with self.lock:
                self.items.append(msg)

        self.subscription = client.node.create_subscription(msg_type, topic, cb, qos)

    def by_stamp(self) -> dict[int, object]:
        with self.lock:
            return {stamp_of(m): m for m in self.items}

    def wait(self, t_ns: int, timeout: float = 20.0):
        return wait_for(lambda: self.by_stamp().get(t_ns), timeout, f"forces stamped {t_ns}")


def diag(client: RosClient):
    """A new /diagnostics subscription, matched to every publisher the graph knows: a test
    that moves a simulated clock once gets one array, which an unmatched reader would miss."""
    from diagnostic_msgs.msg import DiagnosticArray

    box = Box(client, DiagnosticArray, "/diagnostics", RosClient.qos(100))
    known = client.node.count_publishers

    wait_for(lambda: box.subscription.get_publisher_count() >= known("/diagnostics") > 0, 30,
             "the /diagnostics subscription matched")  # fmt: skip
    return box


def status(box: Box, name: str, after_ns: int = 0):
    """The newest status ``name`` stamped after ``after_ns`` (ROS clock), None if none."""
    with box.lock:
        items = list(box.items)
    for arr in reversed(items):
        if stamp_of(arr) > after_ns:
            for st in arr.status:
                if st.name == name:
                    return st
    return None


def values(st) -> dict[str, str]:
    return {kv.key: kv.value for kv in st.values}


@pytest.fixture(scope="module")
def client():
    TireModel.from_file(DEFAULT_TIR).evaluate_one(5000.0, 0.05, 0.05, 0.0, 16.6, 2.6e5, 25.0)
    c = RosClient("test_hostile_client")
    yield c
    c.close()


@pytest.fixture(scope="module")
def model() -> TireModel:
    """This module's nodes run config/default.tir: overrides conftest's MF 6.1 ``model``."""
    return TireModel.from_file(DEFAULT_TIR)


def start(client: RosClient, name: str, *params: str, cmd=None) -> NodeProcess:
    args = ["--ros-args", "-r", f"__node:={name}", "-p", f"tir_file:={DEFAULT_TIR}"]
    for p in params:
        args += ["-p", p]
    return NodeProcess([*(cmd or node_command()), *args], ros_env(client.domain_id))


# ------------------------------------------------------------------ simulated time
WAIT_S = 2.0  # align.wait of the simulated node


@pytest.fixture(scope="module")
def sim(client):
    """One wheel on a simulator's clock; best-effort outputs (the output QoS parameter);
    /diagnostics every 0.1 s of simulated time."""
    from geometry_msgs.msg import Vector3Stamped, WrenchStamped
    from rclpy.qos import qos_profile_sensor_data
    from rosgraph_msgs.msg import Clock

    proc = start(client, "tire_sim", "wheels:=['/sim']", "use_sim_time:=true",
                 "timeout.load:=0.3", "output_reliability:=best_effort",
                 f"align.wait:={WAIT_S}", "diagnostics_period:=0.1")  # fmt: skip
    clock = client.node.create_publisher(Clock, "/clock", 10)
    slip = client.publisher(Vector3Stamped, "/sim/slip")
    load = client.publisher(WrenchStamped, "/sim/load")
    forces = Box(client, WrenchStamped, "/sim/forces", qos_profile_sensor_data)
    reliable = Box(client, WrenchStamped, "/sim/forces", RosClient.qos(10))
    client.wait_matched([slip, load, clock], 90, proc)
    proc.wait_log("/sim/forces: 1 subscriber(s) matched", 30)  # the best-effort one only

    now, lock = Clock(), threading.Lock()

    def tick(t_ns: int) -> None:
        with lock:  # never an older time after a newer one
            now.clock.sec, now.clock.nanosec = divmod(int(t_ns), S)
            clock.publish(now)

    def again() -> None:
        with lock:
            clock.publish(now)

    # A simulator publishes its clock all the time, paused or not; rclpy takes /clock best
    # effort, so the one sample of a single tick can be lost under load (CI, stop 19)
    repeat = client.node.create_timer(0.05, again)

    def send_load(t_ns: int, Fz: float) -> None:
        load.publish(load_msg(Fz, t_ns))

    def send_slip(t_ns: int, kappa: float = 0.05) -> int:
        slip.publish(slip_msg(t_ns, kappa, 0.02))
        return t_ns

    yield proc, tick, send_load, send_slip, forces, reliable
    client.node.destroy_timer(repeat)
    proc.stop()


def test_paused_clock_keeps_a_fresh_load_fresh(sim, model):
    """The simulator pauses 2 s (wall) between a load @100.0 s and the slip @100.2 s: the load
    is 0.2 s old in stamp time, fresh for timeout.load 0.3 s (the slip, held for a later load,
    is answered once the clock has passed align.wait)."""
    _, tick, send_load, send_slip, forces, _ = sim
    tick(100 * S)
    send_load(100 * S, 3000.0)
    time.sleep(2.0)  # the pause itself: wall time passes, the simulated clock does not
    stamp = send_slip(100 * S + S // 5)
    tick(100 * S + round((WAIT_S + 0.1) * S))
    got = forces.wait(stamp)
    assert got.wrench.force.z == 3000.0


def test_fast_forwarded_clock_makes_the_load_stale(sim, model):
    """10 s of simulated time in 0.2 s of wall time: the load @100.0 s is 10 s old for a slip
    @110.2 s (stale: FNOMIN), however little wall time passed."""
    _, tick, _, send_slip, forces, _ = sim
    for k in range(51):  # 100.2 s .. 110.2 s, every 4 ms of wall time
        tick(100 * S + S // 5 + k * S // 5)
        time.sleep(0.004)
    got = forces.wait(send_slip(110 * S + S // 5))
    assert got.wrench.force.z == model.params["FNOMIN"]


def test_future_stamped_load_is_not_applied_early(sim, model):
    """A load @150.5 s that arrives before the slip @150.2 s is not applied to it."""
    _, tick, send_load, send_slip, forces, reliable = sim
    tick(150 * S)
    send_load(150 * S, 3000.0)
    send_load(150 * S + S // 2, 5000.0)

    def later_load_arrived() -> bool:  # a slip stamped with the later load: answered with it
        got = forces.by_stamp().get(send_slip(150 * S + S // 2))
        return got is not None and got.wrench.force.z == 5000.0

    wait_for(later_load_arrived, 20, "the load @150.5 s at the node", interval=0.1)
    got = forces.wait(send_slip(150 * S + S // 5))
    assert got.wrench.force.z == 3000.0
    want = model.evaluate(3000.0, 0.05, 0.02, 0.0)
    assert got.wrench.force.x == pytest.approx(float(want.Fx), rel=1e-9)
    assert not reliable.items  # best-effort output: a reliable subscriber is not served


def test_diagnostics_run_on_the_simulated_clock(sim, client):
    """The /diagnostics timer and stamps follow /clock: stamped in simulated seconds."""
    _, tick, *_ = sim
    box = diag(client)
    t = 200 * S

    def published() -> bool:
        nonlocal t
        t += S // 2
        tick(t)
        st = status(box, "tire_sim: /sim")
        return st is not None

    wait_for(published, 30, "/diagnostics of tire_sim", interval=0.05)
    with box.lock:
        stamps = [stamp_of(a) for a in box.items if any(s.name == "tire_sim: /sim"
                                                        for s in a.status)]  # fmt: skip
    assert all(150 * S < s <= t for s in stamps), stamps  # simulated, not wall-clock seconds


def stream_load(sim, t0: int, Fz: float) -> int:
    """Load and slip messages with the same stamps from ``t0`` on (the clock paused) until a
    slip is answered with that load: the load is arriving. Returns the last stamp sent."""
    _, _, send_load, send_slip, forces, _ = sim
    stamps = iter(range(t0, t0 + S // 2, 1_000_000))
    last = [t0]

    def answered() -> bool:
        last[0] = next(stamps)
        send_load(last[0], Fz)
        send_slip(last[0])
        return any(t >= t0 and m.wrench.force.z == Fz for t, m in forces.by_stamp().items())

    wait_for(answered, 30, f"a slip answered with the load {Fz} N", interval=0.1)
    return last[0]


def held_at(sim, box: Box, clock_ns: int) -> dict[str, str]:
    """Move the simulated clock to ``clock_ns`` and return the wheel's /diagnostics values
    published at that time (the node's counters once it has seen the clock there)."""
    _, tick, *_ = sim
    tick(clock_ns)
    st = wait_for(lambda: status(box, "tire_sim: /sim", after_ns=clock_ns - 1), 20,
                  f"/diagnostics at {clock_ns}")  # fmt: skip
    return values(st)


def test_a_slip_that_arrives_before_its_load_is_answered_with_it(sim, client, model):
    """The load stamped with a slip comes after the slip (as under back-pressure): the slip is
    held until it arrives and answered with it, not with the previous load or FNOMIN."""
    _, tick, send_load, send_slip, forces, _ = sim
    box = diag(client)
    c0 = 300 * S
    tick(c0)
    t = stream_load(sim, c0, 2000.0) + S // 10
    send_slip(t)
    for k in range(1, 10):  # the clock stays well inside align.wait of the slip's arrival
        if held_at(sim, box, c0 + k * S // 10)["pending"] == "1":
            break
    else:
        raise AssertionError("the slip was not held")
    assert t not in forces.by_stamp()
    send_load(t, 3000.0)  # only now
    got = forces.wait(t)
    want = model.evaluate(3000.0, 0.05, 0.02, 0.0)
    assert got.wrench.force.z == 3000.0
    assert got.wrench.force.x == pytest.approx(float(want.Fx), rel=1e-9)
    after = held_at(sim, box, c0 + S)
    assert after["pending"] == "0" and int(after["released_caught_up"]) >= 1


def test_a_slip_whose_load_never_comes_waits_for_the_ros_clock(sim, client):
    """The load stops after a slip: the slip is held while the simulated clock is paused or
    inside align.wait, and answered (with the last load, fresh in stamp time) once the clock
    has passed the bound; /diagnostics WARNs with the count."""
    _, tick, _, send_slip, forces, _ = sim
    box = diag(client)
    c0, step, wait = 400 * S, S // 10, round(WAIT_S * S)
    tick(c0)
    t = stream_load(sim, c0, 2500.0) + S // 10  # the load's last arrival: c0 (clock paused)
    clock = c0 + step
    before = int(held_at(sim, box, clock)["released_by_wait"])
    send_slip(t)
    while held_at(sim, box, clock)["pending"] != "1":  # the node has the slip by `clock`
        clock += step
        assert clock < c0 + wait // 2, "the slip was not held"
    first = clock
    while clock + step < c0 + wait:  # the slip arrived at c0 or later: not released before
        clock += step
        assert held_at(sim, box, clock)["pending"] == "1" and t not in forces.by_stamp(), clock
    clock = first + wait + step  # past the bound of a slip that arrived by `first`
    tick(clock)
    got = forces.wait(t)
    assert got.wrench.force.z == 2500.0  # the load 0.1 s before it in stamp time: fresh
    v = held_at(sim, box, clock + step)
    assert int(v["released_by_wait"]) == before + 1 and v["pending"] == "0"
    with box.lock:
        warned = [st for arr in box.items if stamp_of(arr) > c0 + wait - step
                  for st in arr.status if st.name == "tire_sim: /sim"]  # fmt: skip
    assert any(st.level == b"\x01" and "released_by_wait +1" in st.message for st in warned)


# ------------------------------------------------------------------ hostile inputs
@pytest.fixture(scope="module")
def hostile(client):
    # align.wait 0: these tests send inputs, then slips stamped after them (answered on arrival)
    proc = start(client, "tire_h", "wheels:=['/h']", "diagnostics_period:=0.3", "align.wait:=0.0",
                 *(f"timeout.{k}:=0.0" for k in NODE_INPUTS))  # fmt: skip
    topics = [f"/h/{c}" for c in ("slip", *NODE_INPUTS)]

    def subscribed() -> bool:  # the node's subscriptions exist, resolved with no publisher yet
        proc.check()
        return all(client.node.count_subscribers(t) for t in topics)

    wait_for(subscribed, 90, "the subscriptions of tire_h")
    yield proc
    proc.stop()


def test_best_effort_publishers_are_served(client, hostile):
    """Sensor-data (best-effort) publishers appear after the node subscribed (best available
    then resolved to reliable, as rmw does with no publisher): served, the node subscribed
    again. A reliable publisher on the same topic afterwards too."""
    from geometry_msgs.msg import Vector3Stamped, WrenchStamped
    from rclpy.qos import ReliabilityPolicy, qos_profile_sensor_data

    info = client.node.get_subscriptions_info_by_topic("/h/slip")
    assert [i.qos_profile.reliability for i in info] == [ReliabilityPolicy.RELIABLE]
    slip = client.node.create_publisher(Vector3Stamped, "/h/slip", qos_profile_sensor_data)
    load = client.node.create_publisher(WrenchStamped, "/h/load", qos_profile_sensor_data)
    forces = Box(client, WrenchStamped, "/h/forces", RosClient.qos(100))
    stamps = iter(range(1 * S, 2 * S, 1_000_000))

    def answered(Fz: float, pub) -> bool:
        t = next(stamps)
        pub.publish(load_msg(Fz, t))
        slip.publish(slip_msg(t))
        got = forces.by_stamp()
        return any(m.wrench.force.z == Fz for m in got.values())

    wait_for(lambda: answered(4000.0, load), 30, "forces from best-effort inputs", interval=0.1)
    # said when the handover ends (a tail after the new subscription serves): waited for
    hostile.wait_log("a best-effort publisher appeared; subscribed again", 30)
    reliable = client.publisher(WrenchStamped, "/h/load")
    wait_for(lambda: answered(4100.0, reliable), 30, "a reliable load as well", interval=0.1)


def test_handover_delivers_a_message_that_reached_both_subscriptions_once():
    from tire_model_ros.ros.topics import Handover

    h = Handover()
    assert [h.first("old", b"a"), h.first("new", b"b"), h.first("new", b"a")] == [1, 1, 0]
    assert h.first("old", b"b") is False and h.first("old", b"a") is True  # a sent twice
    h.closed = True  # the old one gone: its late copies still dropped, nothing new recorded
    h.pending["new"].clear()
    assert [h.first("new", b"a"), h.first("new", b"a"), h.first("new", b"c")] == [0, 1, 1]
    assert h.duplicates == 3 and not h.pending["old"] and not h.pending["new"]


def test_subscribing_again_mid_stream_loses_and_repeats_nothing(client):
    """A reliable slip stream at ~500 Hz; a best-effort publisher appears in its middle: the
    node subscribes again, and every reliable slip is answered exactly once."""
    from geometry_msgs.msg import Vector3Stamped, WrenchStamped
    from rclpy.qos import qos_profile_sensor_data

    proc = start(client, "tire_ho", "wheels:=['/ho']", "qos_depth:=2000")
    slip = client.publisher(Vector3Stamped, "/ho/slip", depth=2000)  # no load: FNOMIN
    forces = Box(client, WrenchStamped, "/ho/forces", RosClient.qos(2000))
    client.wait_matched([slip], 90, proc)
    proc.wait_log("/ho/forces: 1 subscriber(s) matched", 30)
    sent: list[int] = []
    for k in range(1500):
        if k == 500:  # mid-stream, as a simulator's sensor would start
            client.node.create_publisher(Vector3Stamped, "/ho/slip", qos_profile_sensor_data)
        m = Vector3Stamped()
        m.vector.x = 0.05
        sent.append(k * 1_000_000 + S)
        slip.publish(stamped(m, sent[-1]))
        time.sleep(0.002)  # pacing of the stream, not a wait on an event
    wait_for(lambda: len(forces.items) >= len(sent), 60, "an answer to every slip")
    proc.wait_log("subscribed again", 30)  # logged when the handover ends
    time.sleep(0.5)  # a duplicate would arrive right behind the last answer
    with forces.lock:
        got = [stamp_of(m) for m in forces.items]
    _, log = proc.stop()
    assert sorted(got) == sent  # none lost, none twice
    handover = [line for line in log.splitlines() if "subscribed again" in line]
    assert len(handover) == 1 and "every publisher matched" in handover[0], log
    print(handover[0])


MALFORMED = textwrap.dedent(
    """
    import sys, time
    import rclpy
    from geometry_msgs.msg import TwistStamped, Vector3Stamped, WrenchStamped
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import FluidPressure, Temperature
    rclpy.init()
    node = rclpy.create_node("malformed_sender")  # a fresh participant
    types = {"slip": Vector3Stamped, "load": WrenchStamped, "pressure": FluidPressure,
             "temperature": Temperature, "velocity": TwistStamped}
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    pubs = {c: node.create_publisher(t, "/h/" + c, qos) for c, t in types.items()}
    end = time.monotonic() + 60
    while any(p.get_subscription_count() == 0 for p in pubs.values()):
        assert time.monotonic() < end, "no subscriber"
        time.sleep(0.05)
    payloads = [
        b"\\x00\\x01\\x00\\x00",                              # encapsulation only
        b"\\x00\\x01\\x00\\x00\\x01\\x02\\x03",                  # a stamp cut short
        b"\\x00\\x01\\x00\\x00" + bytes(8) + b"\\xff\\xff\\xff\\x7f",  # frame_id of 2 GB
        b"\\x00\\x01\\x00\\x00" + bytes(8) + b"\\x02\\x00\\x00\\x00a\\x00",  # no values after it
        b"\\x00\\x00\\x00\\x00" + b"\\x7f" * 9,                 # big-endian, cut short
        b"\\x00\\x00\\x00\\x00" + bytes(8) + b"\\xff\\xff\\xff\\xf0",  # big-endian, huge string
        b"\\x07\\x07\\x00\\x00" + b"\\xa5" * 5,                 # unknown encapsulation
        b"\\x13\\x37\\xbe\\xef" * 2,
    ]
    for channel, pub in pubs.items():
        for data in payloads:
            pub.publish(data)
    for pub in pubs.values():
        assert pub.wait_for_all_acked(rclpy.duration.Duration(seconds=20))
    print("sent", len(payloads), flush=True)
    node.destroy_node()
    rclpy.shutdown()
    """
)


def test_malformed_payloads_on_every_input_are_counted_and_dropped(client, hostile, model):
    from geometry_msgs.msg import Vector3Stamped, WrenchStamped

    box = diag(client)
    sender = subprocess.run([sys.executable, "-c", MALFORMED], env=ros_env(client.domain_id),
                            capture_output=True, text=True, timeout=120)  # fmt: skip
    assert sender.returncode == 0 and "sent 8" in sender.stdout, sender.stdout + sender.stderr
    keys = ["slip_malformed"] + [f"{c}.malformed" for c in NODE_INPUTS]

    def counted():
        st = status(box, "tire_h: /h")
        v = values(st) if st is not None else {}
        return v if v and all(int(v[k]) >= 8 for k in keys) else None

    v = wait_for(counted, 30, "the malformed messages counted on /diagnostics")
    assert all(int(v[k]) == 8 for k in keys), {k: v[k] for k in keys}
    assert hostile.alive()
    # still answering: a good slip now
    slip, load = (
        client.publisher(Vector3Stamped, "/h/slip"),
        client.publisher(WrenchStamped, "/h/load"),
    )
    forces = Box(client, WrenchStamped, "/h/forces", RosClient.qos(100))
    client.wait_matched([slip, load], 30, hostile)
    t = 3 * S

    def answered() -> bool:
        nonlocal t
        t += 1_000_000
        load.publish(load_msg(4500.0, t))
        slip.publish(slip_msg(t))
        return any(m.wrench.force.z == 4500.0 for m in forces.by_stamp().values())

    wait_for(answered, 30, "an answer after the malformed messages", interval=0.1)


class Inputs:
    """Reliable publishers of every input of wheel /h, stamped on one clock."""

    def __init__(self, client: RosClient) -> None:
        from geometry_msgs.msg import TwistStamped, Vector3Stamped, WrenchStamped
        from sensor_msgs.msg import FluidPressure, Temperature

        self.t = 10 * S
        self.types = (Vector3Stamped, WrenchStamped, FluidPressure, Temperature, TwistStamped)
        self.pubs = {
            c: client.publisher(t, f"/h/{c}")
            for c, t in zip(("slip", *NODE_INPUTS), self.types, strict=True)
        }
        self.forces = Box(client, WrenchStamped, "/h/forces", RosClient.qos(1000))
        self.client = client

    def wait_matched(self, proc) -> None:
        """Discovery done both ways: the node reads every input and its forces reach us (a
        reliable answer to a reader not yet matched is lost, not late)."""
        self.client.wait_matched(list(self.pubs.values()), 30, proc)
        sub = self.forces.subscription
        wait_for(lambda: sub.get_publisher_count() > 0, 30, "the /h/forces subscription matched")

    def send(self, Fz=None, p=None, T=None, Vx=None) -> None:
        _, Wrench, Fluid, Temp, Twist = self.types
        self.t += 1_000_000
        if Fz is not None:
            m = Wrench()
            m.wrench.force.z = float(Fz)
            self.pubs["load"].publish(stamped(m, self.t))
        if p is not None:
            self.pubs["pressure"].publish(stamped(Fluid(fluid_pressure=float(p)), self.t))
        if T is not None:
            self.pubs["temperature"].publish(stamped(Temp(temperature=float(T)), self.t))
        if Vx is not None:
            m = Twist()
            m.twist.linear.x = float(Vx)
            self.pubs["velocity"].publish(stamped(m, self.t))

    def slips(self, slips, step_ns: int = 1_000_000) -> list[int]:
        out = []
        for kappa, alpha, gamma in slips:
            self.t += step_ns
            m = self.types[0]()
            m.vector.x, m.vector.y, m.vector.z = kappa, alpha, gamma
            self.pubs["slip"].publish(stamped(m, self.t))
            out.append(self.t)
        return out

    def rows(self, stamps, timeout: float = 20.0) -> np.ndarray:
        wait_for(lambda: all(t in self.forces.by_stamp() for t in stamps), timeout, "forces")
        got = self.forces.by_stamp()
        return np.array([wrench_row(got[t]) for t in stamps])

    def settle(self, model: TireModel, Fz: float, p: float | None, T: float | None, Vx: float,
               limits: bool = True) -> None:  # fmt: skip
        """Send the inputs (p, T None: not sent) and wait until a probe slip is computed with
        all of them (None: the nominal value): every output of the probe as the model gives
        it. Each probe sends the inputs again before it: one that reached a reader matched on
        our side only, or a subscription the node was making anew for a best-effort publisher
        of an earlier test, is lost, not late."""
        Fz_used = min(Fz, model.params["FZMAX"]) if limits else Fz
        probe = [(0.01, 0.0, 0.0)]
        want = expect(model, Fz_used, T, limits, p, Vx, slips=probe)[0]

        def applied() -> bool:  # a probe whose answer is not back in 5 s: send another
            self.send(Fz=Fz, p=p, T=T, Vx=Vx)
            try:
                row = self.rows(self.slips(probe), timeout=5.0)[0]
            except TimeoutError:
                return False
            # every output, not Fx alone: Fx at this slip does not depend on Vx, My does (a
            # speed left by an earlier test passed the probe and failed the rows after it)
            return row[2] == Fz_used and bool(np.allclose(row, want, rtol=1e-9, atol=1e-6))

        wait_for(applied, 60, f"the node computing with Fz {Fz}, T {T}", interval=0.05)


SLIPS = [(0.08, 0.05, 0.01), (-0.12, -0.03, 0.0), (0.02, 0.1, -0.02)]


def expect(model, Fz, T, limits, p=2.6e5, Vx=15.0, slips=SLIPS) -> np.ndarray:
    """The rows (Fx, Fy, Fz, Mx, My, Mz) the node should publish for ``slips``."""
    s = np.array(slips)
    o = model.evaluate(Fz, s[:, 0], s[:, 1], s[:, 2], Vx, p, T, limits=limits)
    return np.column_stack([o.Fx, o.Fy, np.broadcast_to(Fz, len(s)), o.Mx, o.My, o.Mz])


def test_absurd_temperature_and_load_with_limits_on_and_off(client, hostile, model):
    """500 degC: with the limits, T saturates at TEMPMAX (the file gives none: 150 degC, the
    sanity range) and Fx keeps its sign; without, the plain equations flip it. 1e12 N: with
    the limits force.z = FZMAX and the forces are those of FZMAX. /diagnostics WARNs with the
    counts while it lasts and says "ok" once the inputs are in range again."""
    box = diag(client)
    inp = Inputs(client)
    inp.wait_matched(hostile)
    FZMAX = model.params["FZMAX"]
    inp.settle(model, 5000.0, 2.6e5, 500.0, 15.0)
    hot = inp.rows(inp.slips(SLIPS))
    np.testing.assert_allclose(hot, expect(model, 5000.0, 500.0, True), rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(hot, expect(model, 5000.0, 150.0, True), rtol=1e-9, atol=1e-6)
    traction = np.array(SLIPS)[:, 0] > 0
    assert np.all(hot[traction, 0] > 0)  # traction stays traction (default.tir's illustrative
    # temperature terms leave 2.5 % of the grip at 150 degC: the offset PVX1 rules there)
    t0 = client.node.get_clock().now().nanoseconds
    st = wait_for(lambda: status(box, "tire_h: /h", t0), 10, "a status after the hot tread")
    assert st.level == b"\x01" and "out_of_range.temperature +" in st.message, st.message
    assert "(saturated" in st.message
    inp.settle(model, 1e12, 2.6e5, 500.0, 15.0)
    huge = inp.rows(inp.slips(SLIPS))
    assert np.all(huge[:, 2] == FZMAX)
    np.testing.assert_allclose(huge, expect(model, FZMAX, 150.0, True), rtol=1e-9, atol=1e-6)

    assert client.set_parameters("/tire_h", {"limits": False})[0].successful
    try:
        inp.settle(model, 5000.0, 2.6e5, 500.0, 15.0, limits=False)
        plain = inp.rows(inp.slips(SLIPS))
        np.testing.assert_allclose(plain, expect(model, 5000.0, 500.0, False), rtol=1e-9,
                                   atol=1e-6)  # fmt: skip
        assert np.all(plain[traction, 0] < 0.0)  # 500 degC flips Fx in the plain equations
        t1 = client.node.get_clock().now().nanoseconds
        st = wait_for(lambda: status(box, "tire_h: /h", t1), 10, "a status, limits off")
        assert st.level == b"\x01" and "(limits off: not saturated" in st.message, st.message
    finally:
        assert client.set_parameters("/tire_h", {"limits": True})[0].successful
    inp.settle(model, 5000.0, 2.6e5, 40.0, 15.0)
    inp.rows(inp.slips(SLIPS))
    t2 = client.node.get_clock().now().nanoseconds

    def ok():
        st = status(box, "tire_h: /h", t2)
        return st if st is not None and st.message == "ok" else None

    st = wait_for(ok, 10, "/diagnostics back to ok on in-range inputs")
    assert st.level == b"\x00"


def test_absurd_slip_with_an_effects_file_leaves_the_hidden_states_as_they_were(
    client, hostile, model, tmp_path
):
    """kappa = -1e6 once, then normal slips: the forces after it are those of the hidden
    states run without it (offline, EffectState), the tread stays a tread."""
    fx = WheelEffects(T_amb_C=25.0, thermal=Node(4.0, 5e-3), thermal_slow=Node(60.0, 2e-5))
    path = tmp_path / "improved.effects.json"
    path.write_text(Effects({"/h": fx}, "default.tir").to_json())
    inp = Inputs(client)
    inp.wait_matched(hostile)
    inp.t = 500 * S  # the pressure and temperature of the tests before are stale by now:
    stale = {"timeout.pressure": 1.0, "timeout.temperature": 1.0}  # the hidden nodes stand in
    assert all(r.successful for r in client.set_parameters("/tire_h", stale))
    inp.settle(model, 5000.0, None, None, 15.0)
    res = client.set_parameters("/tire_h", {"effects_file": str(path)})
    assert res[0].successful, res[0].reason
    try:
        before = [(0.1 * math.sin(i / 5), 0.05, 0.0) for i in range(30)]
        after = [(0.1 * math.sin((i + 30) / 5), 0.05, 0.0) for i in range(30)]
        t_before = inp.slips(before, step_ns=S // 10)
        t_absurd = inp.slips([(-1e6, 0.05, 0.0)], step_ns=S // 20)
        t_after = inp.slips(after, step_ns=S // 20)
        got = inp.rows(t_before + t_absurd + t_after)
    finally:
        assert client.set_parameters("/tire_h", {"effects_file": ""})[0].successful
        client.set_parameters("/tire_h", dict.fromkeys(stale, 0.0))
    nom = Nominal.from_params(model.params)
    st, want = EffectState(fx), []
    sent = [*before, (-1e6, 0.05, 0.0), *after]
    for t, (kappa, alpha, gamma) in zip(t_before + t_absurd + t_after, sent, strict=True):
        want.append(st.evaluate(model, t / S, 5000.0, kappa, alpha, gamma, 15.0, None, None,
                                nom.p, nom.T, nom.Fz, True, drive=abs(kappa) < 1.0))  # fmt: skip
    np.testing.assert_allclose(got, np.array(want), rtol=1e-9, atol=1e-6)
    assert np.all(np.isfinite(got)) and 25.0 < st.temperature_C < 100.0  # a warm tread
    ref = EffectState(fx)  # without the absurd sample at all: the same states after it
    for t, (kappa, alpha, gamma) in zip(t_before + t_after, before + after, strict=True):
        ref.evaluate(model, t / S, 5000.0, kappa, alpha, gamma, 15.0, None, None, nom.p, nom.T,
                     nom.Fz)  # fmt: skip
    assert st.y == pytest.approx(ref.y, rel=1e-9)


# ------------------------------------------------------------------ the managed node
def lifecycle_call(client: RosClient, node: str, transition: int | None = None):
    from lifecycle_msgs.srv import ChangeState, GetState

    if transition is None:
        return client.call(GetState, f"{node}/get_state", GetState.Request()).current_state.label
    req = ChangeState.Request()
    req.transition.id = transition
    return client.call(ChangeState, f"{node}/change_state", req, timeout=60).success


def parameter_names(client: RosClient, node: str) -> list[str]:
    from rcl_interfaces.srv import ListParameters

    return list(client.call(ListParameters, f"{node}/list_parameters",
                            ListParameters.Request()).result.names)  # fmt: skip


def test_managed_node_through_its_transitions(client, model, tmp_path):
    from geometry_msgs.msg import Vector3Stamped, WrenchStamped
    from lifecycle_msgs.msg import Transition as Tr

    cmd = [str(node_command()[0]).replace("tire-model-node", "tire-model-lifecycle-node")]
    if not cmd[0].endswith("tire-model-lifecycle-node"):
        cmd = [sys.executable, "-m", "tire_model_ros.ros.lifecycle"]
    proc = start(client, "tire_lc", "wheels:=['/lc']", "timeout.load:=0.0",
                 "diagnostics_period:=0.3", cmd=cmd)  # fmt: skip
    N = "/tire_lc"
    try:
        box = diag(client)
        slip, load = (
            client.publisher(Vector3Stamped, "/lc/slip"),
            client.publisher(WrenchStamped, "/lc/load"),
        )
        forces = Box(client, WrenchStamped, "/lc/forces", RosClient.qos(100))
        wait_for(lambda: lifecycle_call(client, N) == "unconfigured", 90, "the managed node")
        assert client.node.count_publishers("/lc/forces") == 0
        assert client.set_parameters(N, {"tir_file": str(tmp_path / "missing.tir")})[0].successful
        assert not lifecycle_call(client, N, Tr.TRANSITION_CONFIGURE)  # the file is read now
        assert lifecycle_call(client, N) == "unconfigured"
        proc.wait_log("missing.tir", 30)
        assert client.set_parameters(N, {"tir_file": str(DEFAULT_TIR)})[0].successful
        assert lifecycle_call(client, N, Tr.TRANSITION_CONFIGURE)
        assert lifecycle_call(client, N) == "inactive"
        assert "PDY1" in parameter_names(client, N)
        assert client.get_parameters(N, ["PDY1"])["PDY1"] == model.params["PDY1"]
        client.wait_matched([slip, load], 30, proc)
        t = [S]

        def send(n: int) -> list[int]:
            load.publish(load_msg(4200.0, t[0]))
            out = []
            for _ in range(n):
                t[0] += 1_000_000
                slip.publish(slip_msg(t[0], 0.04, 0.03))
                out.append(t[0])
            return out

        def inactive_count() -> int:
            st = status(box, "tire_lc: /lc")
            return int(values(st)["slip_inactive"]) if st is not None else -1

        quiet = send(5)
        wait_for(lambda: inactive_count() >= 5, 30, "slips counted while inactive")
        assert lifecycle_call(client, N, Tr.TRANSITION_ACTIVATE)
        assert lifecycle_call(client, N) == "active"
        active: list[int] = []

        def answers() -> list:
            active.extend(send(1))
            got = forces.by_stamp()
            return [got[s] for s in active if s in got]

        answered = wait_for(answers, 30, "answers once active", interval=0.1)
        want = model.evaluate(4200.0, 0.04, 0.03, 0.0)
        assert answered[0].wrench.force.y == pytest.approx(float(want.Fy), rel=1e-9)
        assert lifecycle_call(client, N, Tr.TRANSITION_DEACTIVATE)
        quiet += send(5)
        n_before = inactive_count()
        wait_for(lambda: inactive_count() >= n_before + 5, 30, "slips counted, inactive again")
        assert not set(quiet) & set(forces.by_stamp())  # none answered while inactive
        assert lifecycle_call(client, N, Tr.TRANSITION_CLEANUP)
        assert lifecycle_call(client, N) == "unconfigured"
        wait_for(lambda: client.node.count_publishers("/lc/forces") == 0, 30, "topics gone")
        assert "PDY1" not in parameter_names(client, N)  # the coefficients are undeclared
        assert lifecycle_call(client, N, Tr.TRANSITION_CONFIGURE)
        assert lifecycle_call(client, N, Tr.TRANSITION_ACTIVATE)
        assert lifecycle_call(client, N, Tr.TRANSITION_ACTIVE_SHUTDOWN)
        proc.proc.wait(timeout=30)  # shutdown ends the process
    finally:
        rc, log = proc.stop()
    assert exited_cleanly(rc, log) and "Traceback" not in log, log
    final = parse_reports(log, NODE)["/lc"]
    assert final["slip_inactive"] >= 10 and final["forces_out"] >= 1


def test_slips_held_at_sigterm_are_answered_or_counted(client):
    """SIGTERM while a slip waits for its load: the final counts account for it (computed at
    shutdown, its publication refused by the closed context: publish_failed)."""
    from geometry_msgs.msg import Vector3Stamped, WrenchStamped

    proc = start(client, "tire_term", "wheels:=['/term']", "align.wait:=60.0",
                 "diagnostics_period:=0.1")  # fmt: skip
    slip = client.publisher(Vector3Stamped, "/term/slip")
    load = client.publisher(WrenchStamped, "/term/load")
    forces = Box(client, WrenchStamped, "/term/forces", RosClient.qos(100))
    box = diag(client)
    client.wait_matched([slip, load], 90, proc)
    proc.wait_log("/term/forces: 1 subscriber(s) matched", 30)
    load.publish(load_msg(3000.0, S))
    slip.publish(slip_msg(S))
    forces.wait(S)  # answered: the load is arriving
    slip.publish(slip_msg(2 * S))  # its load never comes, and the bound is a minute

    last: list[dict | None] = [None]  # the latest status, named if the wait times out

    def pending() -> bool:
        st = status(box, "tire_term: /term")
        last[0] = None if st is None else values(st)
        return last[0] is not None and last[0]["pending"] == "1"

    try:
        wait_for(pending, 30, "the slip held")
    except TimeoutError as e:
        raise TimeoutError(f"{e}; last /diagnostics status of /term: {last[0]}") from e
    rc, log = proc.stop()
    assert exited_cleanly(rc, log) and "Traceback" not in log, log
    c = parse_reports(log, NODE)["/term"]
    assert c["slip_in"] == 2 and c["released_by_flush"] == 1, c
    assert c["slip_in"] == c["forces_out"] + sum(c[k] for k in UNANSWERED), c
    print(c)
