"""tire_model_node as its own process, driven over loopback ROS 2 from this test process.

Two node processes are shared by the tests of this file: ``tire1`` (one wheel ``wheel``, the
parameter and bad-input tests) and ``tire_model_node`` (config/car4.yaml, four wheels, the
rear axle on its own file). Every published force is checked against ``TireModel.evaluate``
on the same inputs.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import DEFAULT_TIR, ROOT, TIR_DIR
from ros_util import NodeProcess, RosClient, exited_cleanly, node_command, ros_env, wait_for

from tire_model_ros.model import TireModel
from tire_model_ros.ros import realtime
from tire_model_ros.vocabulary import NODE_INPUTS
from tire_model_ros.wheel import params as pn
from tire_model_ros.wheel.state import Nominal

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]

FSAE_TIR = TIR_DIR / "FSAE_Defaults.tir"
BOOK_TIR = TIR_DIR / "PacejkaBook_Defaults.tir"
N1 = "/tire1"
N4 = "/tire_model_node"
CAR = ("/car/fl", "/car/fr", "/car/rl", "/car/rr")
_clock = {"ns": 1_000_000_000}


def next_stamp(step_s: float = 0.001) -> tuple[int, int]:
    """(sec, nanosec) of a fresh header stamp, ``step_s`` after the last one: inputs and slips
    share this stamp clock, so the node aligns them in the order they were sent."""
    _clock["ns"] += round(step_s * 1e9)
    return divmod(_clock["ns"], 1_000_000_000)


# ------------------------------------------------------------------ ROS-free parts
def test_wheel_key_mapping_and_classification():
    assert pn.wheel_key("/car/rl") == "car.rl"
    assert pn.wheel_key("wheel") == "wheel"
    for bad in ("/car/1x", "", "/car//x-y", "/timeout"):
        with pytest.raises(ValueError):
            pn.wheel_key(bad)
    with pytest.raises(ValueError, match="twice"):
        pn.wheel_keys(["/car/fl", "car/fl"])
    keys = ["car.rl", "car.fl"]
    assert pn.classify("car.rl.tir_file", keys) == pn.ParamName("file", "car.rl", "tir_file")
    assert pn.classify("car.rl.PDY1", keys) == pn.ParamName("coef", "car.rl", "PDY1")
    assert pn.classify("PDY1", keys) == pn.ParamName("coef", "", "PDY1")
    assert pn.classify("timeout.load", keys).kind == "node"
    assert pn.coefficient_range("FNOMIN")[0] == 0.0 and pn.coefficient_range("FNOMIN")[2]
    with pytest.raises(ValueError, match="PDY1"):
        pn.coefficient_value("car.rl.PDY1", math.nan)


def test_realtime_refuses_what_it_cannot_apply():
    before = os.sched_getscheduler(0), os.sched_getaffinity(0)
    assert "outside 0..99" in realtime.apply(100)[0]
    assert "not all available" in realtime.apply(0, [max(os.sched_getaffinity(0)) + 1])[0]
    assert realtime.apply(0, []) == []
    assert (os.sched_getscheduler(0), os.sched_getaffinity(0)) == before


def test_cdr_fast_path_agrees_with_rclpy_serialisation():
    from geometry_msgs.msg import TwistStamped, Vector3Stamped, WrenchStamped
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import FluidPressure

    from tire_model_ros.ros import cdr_fast

    for n in range(10):  # every frame_id length modulo the 8-byte alignment
        slip = Vector3Stamped()
        slip.header.frame_id = "f" * n
        slip.header.stamp.sec, slip.header.stamp.nanosec = 1234 + n, 999_999_999
        slip.vector.x, slip.vector.y, slip.vector.z = 0.1 * n, -2.5, 1e-300
        data = serialize_message(slip)
        end, x, y, z = cdr_fast.read_vector(data)
        assert (x, y, z) == (slip.vector.x, slip.vector.y, slip.vector.z)
        vals = (1.0, -2.0, 3.5, math.pi, -1e9, 7e-7)
        out = deserialize_message(cdr_fast.wrench_like(data, end, vals), WrenchStamped)
        assert out.header == slip.header
        w = out.wrench
        assert (w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z) == vals
        load = WrenchStamped()
        load.header.frame_id = "g" * n
        load.wrench.force.z = 4321.5 + n
        assert cdr_fast.read_double(serialize_message(load), 2) == load.wrench.force.z
        tw = TwistStamped()
        tw.header.frame_id = "h" * n
        tw.twist.linear.x = -3.25
        assert cdr_fast.read_double(serialize_message(tw), 0) == -3.25
        fp = FluidPressure(fluid_pressure=2.4e5)
        assert cdr_fast.read_double(serialize_message(fp), 0) == 2.4e5
    big_endian = b"\x00\x00" + data[2:]
    assert cdr_fast.read_vector(big_endian) is None and cdr_fast.read_double(data[:20], 0) is None


# ------------------------------------------------------------------ fixtures
def warm_jit() -> None:
    """Compile (or load from numba's cache) the single-sample kernel in this process first,
    so node processes started next find it cached instead of compiling it themselves."""
    TireModel.from_file(DEFAULT_TIR).evaluate_one(5000.0, 0.05, 0.05, 0.0, 16.6, 2.6e5, 25.0)


@pytest.fixture(scope="module")
def client():
    warm_jit()
    c = RosClient("test_node_client")
    yield c
    c.close()


@pytest.fixture(scope="module")
def tir_copy(tmp_path_factory):
    path = tmp_path_factory.mktemp("tir") / "edited.tir"
    shutil.copyfile(DEFAULT_TIR, path)
    return path


# A probe's answer is awaited this long before another probe is sent (within the settle's
# bound): an answer published before the node's writer has matched our reader is never sent
# (volatile durability), and one lost probe failed a fresh-clone run (effects-file test).
PROBE_WAIT_S = 5.0


class Wheel:
    """Test side of one wheel: input publishers and the collected forces by stamp."""

    def __init__(self, client: RosClient, prefix: str) -> None:
        from geometry_msgs.msg import TwistStamped, Vector3Stamped, WrenchStamped
        from sensor_msgs.msg import FluidPressure, Temperature

        self.client = client
        self.prefix = prefix
        self.out = client.collect(WrenchStamped, f"{prefix}/forces")
        self.slip = client.publisher(Vector3Stamped, f"{prefix}/slip")
        self.load = client.publisher(WrenchStamped, f"{prefix}/load")
        self.pressure = client.publisher(FluidPressure, f"{prefix}/pressure")
        self.temperature = client.publisher(Temperature, f"{prefix}/temperature")
        self.velocity = client.publisher(TwistStamped, f"{prefix}/velocity")
        self.types = (Vector3Stamped, WrenchStamped, FluidPressure, Temperature, TwistStamped)

    def pubs(self):
        return [self.slip, self.load, self.pressure, self.temperature, self.velocity]

    def send_inputs(self, Fz=None, p=None, T=None, Vx=None) -> int:
        """Publish inputs stamped before every slip sent after them; returns the stamp [s]."""
        _, Wrench, Fluid, Temp, Twist = self.types
        sec, nsec = next_stamp()
        msgs = []
        if Fz is not None:
            m = Wrench()
            m.wrench.force.z = float(Fz)
            msgs.append((self.load, m))
        if p is not None:
            msgs.append((self.pressure, Fluid(fluid_pressure=float(p))))
        if T is not None:
            msgs.append((self.temperature, Temp(temperature=float(T))))
        if Vx is not None:
            m = Twist()
            m.twist.linear.x = float(Vx)
            msgs.append((self.velocity, m))
        for pub, m in msgs:
            m.header.stamp.sec, m.header.stamp.nanosec = sec, nsec
            pub.publish(m)
        return sec

    def send_slips(self, slips, step_s: float = 0.001) -> list[tuple[int, int]]:
        """Publish slips (kappa, alpha, gamma) with fresh stamps ``step_s`` apart; returns the
        stamps."""
        Vector3Stamped = self.types[0]
        stamps = []
        for kappa, alpha, gamma in slips:
            m = Vector3Stamped()
            m.header.stamp.sec, m.header.stamp.nanosec = next_stamp(step_s)
            m.header.frame_id = "test"
            m.vector.x, m.vector.y, m.vector.z = float(kappa), float(alpha), float(gamma)
            self.slip.publish(m)
            stamps.append((m.header.stamp.sec, m.header.stamp.nanosec))
        return stamps

    def results(self, stamps, timeout=60.0) -> np.ndarray:
        """Forces (Fx, Fy, Fz, Mx, My, Mz) for the stamps, in order; fails if one is missing."""

        def by_stamp():
            return {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in list(self.out)}

        wait_for(lambda: all(s in by_stamp() for s in stamps), timeout, f"{self.prefix}/forces")
        got = by_stamp()
        rows = []
        for s in stamps:
            w = got[s].wrench
            assert got[s].header.frame_id == "test"
            rows.append([w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z])
        return np.array(rows)

    def settle(self, model, inputs, timeout=60.0, limits=True, send=True) -> None:
        """Send ``inputs`` and wait until the node computes with them (probe slips)."""
        if send:
            self.send_inputs(**inputs)
        probe = [(0.03, 0.04, 0.01)]

        def applied():
            stamps = self.send_slips(probe)
            try:
                got = self.results(stamps, timeout=PROBE_WAIT_S)
            except TimeoutError:  # answered before the node's writer had found our reader
                return False
            want = expected(model, inputs, probe, limits)
            return np.allclose(got, want, rtol=1e-9, atol=1e-6)

        wait_for(applied, timeout, f"{self.prefix} computing with {inputs}", interval=0.05)


def expected(model: TireModel, inputs: dict, slips, limits=True) -> np.ndarray:
    s = np.asarray(slips, dtype=float)
    o = model.evaluate(inputs["Fz"], s[:, 0], s[:, 1], s[:, 2], Vx=inputs["Vx"], p=inputs["p"],
                       T=inputs["T"], limits=limits)  # fmt: skip
    Fz = np.broadcast_to(np.asarray(inputs["Fz"], dtype=float), s[:, 0].shape)
    return np.column_stack([o.Fx, o.Fy, Fz, o.Mx, o.My, o.Mz])


def check(wheel: Wheel, model: TireModel, inputs: dict, slips, limits=True) -> np.ndarray:
    got = wheel.results(wheel.send_slips(slips))
    np.testing.assert_allclose(got, expected(model, inputs, slips, limits), rtol=1e-9, atol=1e-6)
    return got


def random_slips(seed: int, n: int = 40) -> list[tuple[float, float, float]]:
    rng = np.random.default_rng(seed)
    k = rng.uniform(-0.4, 0.4, n)
    a = rng.uniform(-0.25, 0.25, n)
    g = rng.uniform(-0.08, 0.08, n)
    return list(zip(k, a, g, strict=True))


def start_node(args, client) -> NodeProcess:
    """The node, answering each slip on arrival (``align.wait`` 0): these tests send inputs
    once, then slips stamped after them, which the default would hold for the inputs still
    arriving until they stop (up to 1 s each time); holding is tested in test_wheel.py and
    test_node_hostile.py."""
    args = [*args, "-p", "align.wait:=0.0"]
    return NodeProcess([*node_command(), "--ros-args", *args], ros_env(client.domain_id))


@pytest.fixture(scope="module")
def node1(client, tir_copy):
    proc = start_node(
        ["-r", "__node:=tire1", "-p", f"tir_file:={DEFAULT_TIR}", "-p", "diagnostics_period:=0.3"]
        + [a for k in NODE_INPUTS for a in ("-p", f"timeout.{k}:=0.0")],
        client,
    )
    wheel = Wheel(client, "/wheel")
    client.wait_matched(wheel.pubs(), 90, proc)
    yield proc, wheel
    proc.stop()


@pytest.fixture(scope="module")
def node4(client):
    proc = start_node(
        ["--params-file", str(ROOT / "config" / "car4.yaml"),
         "-p", f"tir_file:={DEFAULT_TIR}", "-p", f"car.rl.tir_file:={BOOK_TIR}",
         "-p", f"car.rr.tir_file:={BOOK_TIR}",
         "-p", "timeout.load:=0.0", "-p", "timeout.velocity:=0.0"],
        client,
    )  # fmt: skip
    wheels = {p: Wheel(client, p) for p in CAR}
    client.wait_matched([pub for w in wheels.values() for pub in w.pubs()], 90, proc)
    yield proc, wheels
    proc.stop()


def current_model(client, node: str, file: Path, names=("PDY1",)) -> TireModel:
    """The model the node should run: the file plus its coefficient parameters now."""
    values = client.get_parameters(node, list(names))
    return TireModel.from_file(file).with_params(values)


# ------------------------------------------------------------------ outputs = model
def test_one_wheel_outputs_match_model(node1):
    _, wheel = node1
    model = TireModel.from_file(DEFAULT_TIR)
    for i, inputs in enumerate(
        [
            {"Fz": 4000.0, "p": 2.2e5, "T": 45.0, "Vx": 20.0},
            {"Fz": 7500.0, "p": 2.7e5, "T": 5.0, "Vx": 3.0},
        ]
    ):
        wheel.settle(model, inputs)
        got = check(wheel, model, inputs, random_slips(i))
        assert np.all(got[:, 2] == inputs["Fz"])


def test_four_wheels_each_own_inputs_and_models(node4):
    _, wheels = node4
    front = TireModel.from_file(DEFAULT_TIR)
    rear = TireModel.from_file(BOOK_TIR).with_params({"LMUY": 0.95, "LMUX": 0.97})  # car4.yaml
    models = {"/car/fl": front, "/car/fr": front, "/car/rl": rear, "/car/rr": rear}
    inputs = {
        p: {"Fz": 3000.0 + 900 * i, "p": 2.0e5 + 2e4 * i, "T": 20.0 + 10 * i, "Vx": 10.0 + i}
        for i, p in enumerate(CAR)
    }
    for p, w in wheels.items():
        w.settle(models[p], inputs[p])
    slips = {p: random_slips(10 + i) for i, p in enumerate(CAR)}
    stamps = {p: [] for p in CAR}
    for k in range(len(slips["/car/fl"])):  # interleaved, as a car would publish
        for p, w in wheels.items():
            stamps[p] += w.send_slips([slips[p][k]])
    for p, w in wheels.items():
        got = w.results(stamps[p])
        np.testing.assert_allclose(got, expected(models[p], inputs[p], slips[p]), rtol=1e-9,
                                   atol=1e-6, err_msg=p)  # fmt: skip
    # The rear really runs another model than the front on the same inputs.
    same = expected(front, inputs["/car/rl"], slips["/car/rl"])
    assert not np.allclose(same, expected(rear, inputs["/car/rl"], slips["/car/rl"]), rtol=1e-3)


def test_wheel_gets_own_file_live_and_back(client, node4):
    _, wheels = node4
    fr = wheels["/car/fr"]
    front = TireModel.from_file(DEFAULT_TIR)
    inputs = {"Fz": 950.0, "p": 9.0e4, "T": 30.0, "Vx": 11.0}
    fr.settle(front, inputs)
    # The wheel's coefficient parameters exist once its file is set: two requests.
    res = client.set_parameters(N4, {"car.fr.tir_file": str(FSAE_TIR)}, atomically=True)
    assert res.successful, res.reason
    assert client.set_parameters(N4, {"car.fr.LMUX": 0.9})[0].successful
    own = TireModel.from_file(FSAE_TIR).with_params({"LMUX": 0.9})
    slips = random_slips(21, 10)
    check(fr, own, inputs, slips)  # the very next messages use the wheel's own model
    got = client.get_parameters(N4, ["car.fr.LMUX", "car.fr.FNOMIN", "FNOMIN"])
    assert got == {"car.fr.LMUX": 0.9, "car.fr.FNOMIN": 1000.0, "FNOMIN": 6752.0}
    fl_inputs = {"Fz": 3000.0, "p": 2.0e5, "T": 20.0, "Vx": 10.0}
    wheels["/car/fl"].settle(front, fl_inputs)
    check(wheels["/car/fl"], front, fl_inputs, slips)  # the other front wheel: shared model

    res = client.set_parameters(N4, {"car.fr.tir_file": ""})
    assert res[0].successful, res[0].reason
    check(fr, front, inputs, slips)
    res = client.set_parameters(N4, {"car.fr.PDY1": 1.0})  # no own model: not a parameter now
    assert not res[0].successful


def test_pressure_is_absolute(client, node1):
    _, wheel = node1
    model = TireModel.from_file(DEFAULT_TIR)
    wheel.settle(model, INPUTS1)
    assert client.set_parameters(N1, {"pressure_is_absolute": True})[0].successful
    try:
        gauge = 2.1e5
        wheel.send_inputs(p=gauge + 101325.0)  # FluidPressure documents absolute pressure
        wheel.settle(model, dict(INPUTS1, p=gauge), send=False)
    finally:
        assert client.set_parameters(N1, {"pressure_is_absolute": False})[0].successful


# ------------------------------------------------------------------ live parameter changes
INPUTS1 = {"Fz": 5000.0, "p": 2.4e5, "T": 30.0, "Vx": 15.0}


def test_set_parameters_and_atomically_take_effect_next_message(client, node1):
    _, wheel = node1
    base = TireModel.from_file(DEFAULT_TIR)
    wheel.settle(base, INPUTS1)
    slips = random_slips(3, 20)
    before = check(wheel, base, INPUTS1, slips)

    res = client.set_parameters(N1, {"PDY1": 1.25, "PKY1": -20.0})
    assert all(r.successful for r in res), res
    m1 = base.with_params({"PDY1": 1.25, "PKY1": -20.0})
    after = check(wheel, m1, INPUTS1, slips)  # no probing: the very next messages
    assert not np.allclose(before[:, 1], after[:, 1], rtol=1e-3)

    res = client.set_parameters(N1, {"PDX1": 1.4, "LMUY": 0.8, "PKX1": 30.0}, atomically=True)
    assert res.successful, res.reason
    m2 = m1.with_params({"PDX1": 1.4, "LMUY": 0.8, "PKX1": 30.0})
    check(wheel, m2, INPUTS1, slips)
    assert client.get_parameters(N1, ["PDX1", "LMUY"]) == {"PDX1": 1.4, "LMUY": 0.8}


def test_changes_under_streaming_drop_nothing_mix_nothing(client, node1):
    """Slips stream while coefficients and the file flip: every slip gets one output, each
    equal to one whole model (never a mix), and the models follow the changes in order."""
    import threading

    _, wheel = node1
    assert client.set_parameters(N1, {"tir_file": str(DEFAULT_TIR)})[0].successful
    models = [
        TireModel.from_file(DEFAULT_TIR),
        TireModel.from_file(DEFAULT_TIR).with_params({"PDY1": 1.3, "PDX1": 1.4}),
    ]
    wheel.settle(models[0], INPUTS1)
    slips = random_slips(30, 600)
    stamps: list = []
    sender = threading.Thread(
        target=lambda: [stamps.extend(wheel.send_slips([s])) or time.sleep(0.002) for s in slips]
    )
    sender.start()
    for k in range(6):
        time.sleep(0.12)
        if k % 3 == 2:  # a whole-file reload now and then
            res = client.set_parameters(N1, {"tir_file": str(DEFAULT_TIR)})
        else:
            res = client.set_parameters(N1, {"PDY1": 1.3, "PDX1": 1.4}, atomically=True)
        assert (res if k % 3 != 2 else res[0]).successful
    sender.join(30)
    got = wheel.results(stamps, timeout=30)  # every slip answered
    want = [expected(m, INPUTS1, slips) for m in models]
    which = []
    for i in range(len(slips)):
        hits = [j for j in (0, 1) if np.allclose(got[i], want[j][i], rtol=1e-9, atol=1e-6)]
        assert hits, f"output {i} matches neither model: {got[i]}"
        which.append(hits[0])
    assert 1 in which  # the coefficient change took effect while streaming
    check(wheel, models[0], INPUTS1, slips[:5])  # the last change, a reload, holds now


def test_coefficient_descriptors(client, node1):
    from rcl_interfaces.srv import DescribeParameters

    req = DescribeParameters.Request(names=["FNOMIN", "PDY1", "timeout.load", "align.wait"])
    d = client.call(DescribeParameters, f"{N1}/describe_parameters", req).descriptors
    assert "load" in d[0].description.lower() and d[0].floating_point_range[0].from_value == 0.0
    rng = d[1].floating_point_range[0]  # |mu_y| <= 10 (every coefficient has a range)
    assert d[1].description and (rng.from_value, rng.to_value) == (-10.0, 10.0)
    assert d[2].floating_point_range[0].from_value == 0.0
    rng = d[3].floating_point_range[0]
    assert "ROS clock" in d[3].description and (rng.from_value, rng.to_value) == (0.0, 300.0)
    assert client.set_parameters(N1, {"align.wait": 0.25})[0].successful  # live
    assert not client.set_parameters(N1, {"align.wait": 301.0})[0].successful
    assert client.get_parameters(N1, ["align.wait"]) == {"align.wait": 0.25}
    assert client.set_parameters(N1, {"align.wait": 0.0})[0].successful


def test_bad_values_rejected_outputs_unchanged(client, node1):
    _, wheel = node1
    names = ("PDY1", "PKY1", "PDX1", "LMUY", "PKX1", "FNOMIN")
    model = current_model(client, N1, DEFAULT_TIR, names)
    slips = random_slips(4, 10)
    check(wheel, model, INPUTS1, slips)
    for values, atomic, word in [
        ({"PDY1": math.nan}, False, "PDY1"),
        ({"FNOMIN": 0.0}, False, "FNOMIN"),
        ({"FNOMIN": -5.0}, False, "FNOMIN"),  # outside the descriptor's range
        ({"PDY1": "high"}, False, ""),  # wrong type
        ({"PDX1": 2.0, "PDY1": math.inf}, True, "PDY1"),  # one bad value rejects the batch
        ({"NOPE1": 1.0}, False, ""),  # not a parameter of the node
        ({"wheel.PDY1": 1.0}, False, ""),  # the wheel has no own model
        ({"limits": 3}, False, ""),
        ({"PDY1": 1e9}, False, ""),  # beyond |mu_y| <= 10: refused by its range
        # each within its range, swapped: NaN Fx above 1.4 FNOMIN; the operating grid finds it
        ({"PKX3": 1747.3832, "RBY4": -0.11254}, True, "not a tyre on its operating range"),
    ]:
        res = client.set_parameters(N1, values, atomically=atomic)
        results = [res] if atomic else res
        assert not any(r.successful for r in results), values
        assert word in " ".join(r.reason for r in results), (values, results)
    assert client.get_parameters(N1, ["PDY1", "PDX1"]) == {
        "PDY1": model.params["PDY1"],
        "PDX1": model.params["PDX1"],
    }
    check(wheel, model, INPUTS1, slips)


def test_switch_tir_file_and_bad_file(client, node1, tmp_path):
    _, wheel = node1
    res = client.set_parameters(N1, {"tir_file": str(FSAE_TIR)})
    assert res[0].successful, res[0].reason
    fsae = TireModel.from_file(FSAE_TIR)
    inputs = {"Fz": 900.0, "p": 8.0e4, "T": 25.0, "Vx": 12.0}
    wheel.settle(fsae, inputs)
    slips = random_slips(5, 20)
    check(wheel, fsae, inputs, slips)
    # Coefficient parameters now carry the new file's values.
    got = client.get_parameters(N1, ["FNOMIN", "PDY1", "NOMPRES"])
    assert got == {k: fsae.params[k] for k in got}

    bad = tmp_path / "broken.tir"
    text = FSAE_TIR.read_text().replace("FNOMIN", "FNOMIN = = oops\nX", 1)
    bad.write_text(text)
    for path, word in [(bad, "broken.tir"), (tmp_path / "missing.tir", "missing.tir")]:
        res = client.set_parameters(N1, {"tir_file": str(path)})
        assert not res[0].successful and word in res[0].reason, res[0].reason
    assert client.get_parameters(N1, ["tir_file"])["tir_file"] == str(FSAE_TIR)
    check(wheel, fsae, inputs, slips)


def test_lenient_reads_what_strict_refuses(client, node1, tmp_path):
    proc, wheel = node1
    cut = tmp_path / "no_pky4.tir"
    cut.write_text(re.sub(r"^PKY4\s*=.*\n", "", DEFAULT_TIR.read_text(), flags=re.M))
    res = client.set_parameters(N1, {"tir_file": str(cut)})
    assert not res[0].successful and "PKY4" in res[0].reason, res[0].reason
    res = client.set_parameters(N1, {"lenient": True, "tir_file": str(cut)}, atomically=True)
    assert res.successful, res.reason
    proc.wait_log("model file: ", 10)  # the node lists what it filled
    assert re.search(r"model file: .*no_pky4\.tir: line \d+: .*PKY4=2\b", proc.log()), proc.log()
    try:
        model = TireModel.from_file(cut, lenient=True)
        assert model.params["PKY4"] == 2.0  # the documented default
        wheel.settle(model, INPUTS1)
        check(wheel, model, INPUTS1, random_slips(9, 10))
    finally:
        res = client.set_parameters(N1, {"lenient": False, "tir_file": str(DEFAULT_TIR)},
                                    atomically=True)  # fmt: skip
        assert res.successful, res.reason


def _edit(path: Path, key: str, value: float) -> None:
    text = path.read_text()
    new, n = re.subn(rf"^({key}\s*=\s*)\S+", rf"\g<1>{value!r}", text, count=1, flags=re.M)
    assert n == 1
    path.write_text(new)


def test_edit_file_and_reload(client, node1, tir_copy):
    from std_srvs.srv import Trigger

    _, wheel = node1
    res = client.set_parameters(N1, {"tir_file": str(tir_copy)})
    assert res[0].successful, res[0].reason
    m0 = TireModel.from_file(tir_copy)
    wheel.settle(m0, INPUTS1)
    slips = random_slips(6, 20)
    before = check(wheel, m0, INPUTS1, slips)

    _edit(tir_copy, "PDY1", 0.7)
    _edit(tir_copy, "PCX1", 1.5)
    r = client.call(Trigger, f"{N1}/reload", Trigger.Request())
    assert r.success and str(tir_copy) in r.message, r.message
    m1 = TireModel.from_file(tir_copy)
    assert m1.params["PDY1"] == 0.7
    after = check(wheel, m1, INPUTS1, slips)
    assert not np.allclose(before, after, rtol=1e-3)
    assert client.get_parameters(N1, ["PDY1", "PCX1"]) == {"PDY1": 0.7, "PCX1": 1.5}

    whole = tir_copy.read_bytes()
    tir_copy.write_text(whole.decode().replace("[LATERAL_COEFFICIENTS]", "[LATERAL\n"))
    r = client.call(Trigger, f"{N1}/reload", Trigger.Request())
    assert not r.success and "edited.tir" in r.message, r.message
    check(wheel, m1, INPUTS1, slips)

    # a file caught half-written (an editor or a copy still at work): inside a line, and at a
    # line end; the reload is refused naming file, line and key, the old model keeps running
    for cut in (len(whole) // 2, whole.index(b"\n", len(whole) // 3) + 1):
        tir_copy.write_bytes(whole[:cut])
        r = client.call(Trigger, f"{N1}/reload", Trigger.Request())
        assert not r.success and "edited.tir: line " in r.message, r.message
        assert "cut short" in r.message, r.message
        check(wheel, m1, INPUTS1, slips)


# ------------------------------------------------------------------ bad inputs
def _diag_values(client_box, name: str, since: float) -> dict[str, str]:
    for arr in reversed(list(client_box)):
        t = arr.header.stamp.sec + 1e-9 * arr.header.stamp.nanosec
        for st in arr.status:
            if st.name == name and t >= since:
                return {kv.key: kv.value for kv in st.values} | {"_level": st.level}
    return {}


def test_bad_inputs_survive_no_nan_diagnostics(client, node1):
    from diagnostic_msgs.msg import DiagnosticArray

    proc, wheel = node1
    diags = client.collect(DiagnosticArray, "/diagnostics")
    client.set_parameters(N1, {"tir_file": str(DEFAULT_TIR)})
    model = TireModel.from_file(DEFAULT_TIR)
    wheel.settle(model, INPUTS1)
    wait_for(lambda: _diag_values(diags, "tire1: wheel", 0.0), 10, "diagnostics of tire1")
    before = {k: int(v) for k, v in _diag_values(diags, "tire1: wheel", 0.0).items()
              if v.isdigit()}  # fmt: skip

    nan_stamps = wheel.send_slips([(math.nan, 0.0, 0.0), (0.0, math.inf, 0.0), (0, 0, -math.inf)])
    wheel.send_inputs(Fz=math.nan, p=math.nan, T=-400.0, Vx=math.inf)  # all rejected: held
    huge = [(1e6, 3.0, 2.0), (-50.0, -1.4, 0.0)]
    check(wheel, model, INPUTS1, huge)  # limits saturate; held inputs are INPUTS1
    wheel.send_inputs(Fz=-100.0)  # off the ground: all-zero wrench
    wait_for(lambda: not wheel.results(wheel.send_slips([(0.1, 0.1, 0.0)])).any(), 10, "Fz<0")
    zero = wheel.results(wheel.send_slips([(0.1, 0.1, 0.0)] * 3))
    wheel.send_inputs(Fz=INPUTS1["Fz"])
    wheel.settle(model, INPUTS1)
    time.sleep(0.2)
    assert proc.alive()
    assert np.all(zero == 0.0)
    stamps = {(m.header.stamp.sec, m.header.stamp.nanosec) for m in list(wheel.out)}
    assert not stamps & set(nan_stamps)  # the NaN slips were not published
    for m in list(wheel.out):
        w = m.wrench
        vals = [w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z]
        assert all(math.isfinite(v) for v in vals)

    t_after = time.time()

    def counted():
        d = _diag_values(diags, "tire1: wheel", t_after)
        return d if d and int(d["no_contact"]) - before.get("no_contact", 0) >= 1 else None

    d = wait_for(counted, 10, "diagnostics with the counts")
    inc = {k: int(d[k]) - before.get(k, 0) for k in before}
    assert inc["slip_rejected"] == 3
    assert inc["load.rejected"] == 1 and inc["pressure.rejected"] == 1
    assert inc["temperature.rejected"] == 1 and inc["velocity.rejected"] == 1
    assert inc["no_contact"] >= 4
    assert d["tir_file"] == str(DEFAULT_TIR)
    assert int(d["forces_out"]) + int(d["slip_rejected"]) <= int(d["slip_in"])


def test_stale_input_falls_back_to_nominal(client, node1):
    from diagnostic_msgs.msg import DiagnosticArray

    _, wheel = node1
    diags = client.collect(DiagnosticArray, "/diagnostics")
    model = TireModel.from_file(DEFAULT_TIR)
    assert client.set_parameters(N1, {"timeout.velocity": 0.2})[0].successful
    wheel.send_inputs(Vx=4.0)
    next_stamp(0.5)  # the slips below are stamped 0.5 s later: stale in stamp time
    nominal = dict(INPUTS1, Vx=model.params["LONGVL"])
    check(wheel, model, nominal, random_slips(8, 5))
    t0 = time.time()
    d = wait_for(lambda: _diag_values(diags, "tire1: wheel", t0), 10, "diagnostics")
    assert int(d["fallback.velocity.stale"]) >= 5
    assert client.set_parameters(N1, {"timeout.velocity": 0.0})[0].successful


def test_limits_off_evaluates_plainly(client, node1):
    _, wheel = node1
    model = TireModel.from_file(DEFAULT_TIR)
    assert client.set_parameters(N1, {"limits": False})[0].successful
    wheel.settle(model, dict(INPUTS1, Fz=5100.0), limits=False)
    slips = [(0.6, 0.3, 0.2), (-0.9, -0.5, 0.0)]
    check(wheel, model, dict(INPUTS1, Fz=5100.0), slips, limits=False)
    assert client.set_parameters(N1, {"limits": True})[0].successful


# ------------------------------------------------------------------ process life
def test_bad_start_exits_1_with_message(client, tmp_path):
    missing = tmp_path / "nope.tir"
    proc = start_node(["-r", "__node:=tire_bad", "-p", f"tir_file:={missing}"], client)
    wait_for(lambda: not proc.alive(), 30, "the node to exit")
    rc, log = proc.stop()
    assert rc == 1 and "nope.tir" in log and "Traceback" not in log, log


def thread_scheduling(pid: int) -> set[tuple[int, int, str]]:
    """(policy, rt priority, allowed CPUs) of every thread of ``pid`` (Linux /proc)."""
    out = set()
    for task in Path(f"/proc/{pid}/task").iterdir():
        fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        cpus = re.search(r"Cpus_allowed_list:\s*(\S+)", (task / "status").read_text()).group(1)
        out.add((int(fields[38]), int(fields[37]), cpus))  # stat fields 41 policy, 40 rt_priority
    return out


def test_rt_priority_and_cpus_apply_to_every_thread(client):
    proc = start_node(
        ["-r", "__node:=tire_rt", "-p", "wheels:=[/rtw]", "-p", "rt_priority:=3",
         "-p", "cpus:=[0]", "-p", "timeout.load:=0.0"],
        client,
    )  # fmt: skip
    try:
        wheel = Wheel(client, "/rtw")
        client.wait_matched(wheel.pubs(), 90, proc)
        wheel.settle(TireModel.from_file(DEFAULT_TIR), INPUTS1)
        sched = thread_scheduling(proc.proc.pid)
        if "scheduling: SCHED_FIFO" in proc.log():  # applied: all threads, DDS ones included
            assert sched == {(1, 3, "0")}, sched
        else:  # no permission here: a warning, normal scheduling, outputs as ever
            assert "scheduling:" in proc.log() and all(p == 0 for p, _, _ in sched), proc.log()
        check(wheel, TireModel.from_file(DEFAULT_TIR), INPUTS1, random_slips(7, 10))
    finally:
        rc, log = proc.stop(signal.SIGINT, timeout=15)
    assert exited_cleanly(rc, log) and "Traceback" not in log, log


def test_rt_priority_out_of_range_refused_at_start(client):
    proc = start_node(["-r", "__node:=tire_rt_bad", "-p", "rt_priority:=100"], client)
    wait_for(lambda: not proc.alive(), 30, "the node to exit")
    rc, log = proc.stop()
    assert rc == 1 and "rt_priority" in log and "Traceback" not in log, log


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_clean_exit(request, sig):
    proc, _ = request.getfixturevalue("node4" if sig == signal.SIGTERM else "node1")
    assert proc.alive()
    rc, log = proc.stop(sig, timeout=15)
    assert exited_cleanly(rc, log), log
    assert "Traceback" not in log, log


# ------------------------------------------------------------------ effects file (hidden states)
def test_effects_file_runs_hidden_states_live_and_bad_file_rejected(client, tmp_path):
    """With an effects file the node runs the hidden states on the slip stamps: its forces
    equal EffectState + the model offline on the same messages, and differ from the plain
    model (the tread heats). A bad file is rejected naming file and key; "" switches off."""
    from tire_model_ros.model.states import Effects, EffectState, Node, WheelEffects

    fx = WheelEffects(
        T_amb_C=25.0,
        thermal=Node(4.0, 5e-3),
        thermal_slow=Node(60.0, 2e-5),  # the carcass node (effects file version 2)
        offsets={"Fy": (20.0, 100.0)},
    )
    good = tmp_path / "improved.effects.json"
    good.write_text(Effects({"/fx": fx}, "default.tir").to_json())
    proc = start_node(
        [
            "-r",
            "__node:=tire_fx",
            "-p",
            f"tir_file:={DEFAULT_TIR}",
            "-p",
            "wheels:=['/fx']",
            "-p",
            "timeout.load:=0.0",
            "-p",
            "timeout.velocity:=0.0",
        ],
        client,
    )
    try:
        from diagnostic_msgs.msg import DiagnosticArray

        diags = client.collect(DiagnosticArray, "/diagnostics")
        wheel = Wheel(client, "/fx")
        client.wait_matched(wheel.pubs(), 90, proc)
        model = TireModel.from_file(DEFAULT_TIR)
        nom = Nominal.from_params(model.params)
        inputs = {"Fz": 5000.0, "p": None, "T": None, "Vx": 15.0}
        wheel.settle(model, inputs)  # no pressure or temperature topic: nominal values
        res = client.set_parameters("/tire_fx", {"effects_file": str(good)})
        assert res[0].successful, res[0].reason
        slips = [(0.1 * math.sin(i / 5), 0.12 * math.sin(i / 7), 0.0) for i in range(40)]
        stamps = wheel.send_slips(slips, step_s=1.0)  # 40 s of stamp time: the tread heats
        got = wheel.results(stamps)
        st, want = EffectState(fx), []
        for (sec, ns), (kappa, alpha, gamma) in zip(stamps, slips, strict=True):
            want.append(
                st.evaluate(
                    model,
                    sec + 1e-9 * ns,
                    5000.0,
                    kappa,
                    alpha,
                    gamma,
                    15.0,
                    None,
                    None,
                    nom.p,
                    nom.T,
                    nom.Fz,
                )
            )
        np.testing.assert_allclose(got, np.array(want), rtol=1e-9, atol=1e-6)
        plain = expected(model, inputs, slips)
        assert st.temperature_C > 30.0 and np.max(np.abs(got[:, 1] - plain[:, 1])) > 100.0
        tread = f"{st.temperature_C:.2f}"  # reported on /diagnostics
        wait_for(
            lambda: _diag_values(diags, "tire_fx: /fx", 0.0).get("effects.tread_C") == tread,
            10,
            "the hidden tread temperature on /diagnostics",
        )

        bad = tmp_path / "bad.effects.json"
        bad.write_text(good.read_text().replace('"tau_s": 4.0', '"tau_s": -4.0'))
        res = client.set_parameters("/tire_fx", {"effects_file": str(bad)})
        assert not res[0].successful
        assert "bad.effects.json" in res[0].reason and "thermal.tau_s" in res[0].reason
        assert client.get_parameters("/tire_fx", ["effects_file"])["effects_file"] == str(good)
        res = client.set_parameters("/tire_fx", {"effects_file": ""})
        assert res[0].successful, res[0].reason
        check(wheel, model, inputs, slips)
    finally:
        proc.stop()
