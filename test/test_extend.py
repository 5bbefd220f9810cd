"""``fit --extend``, sidewall contact named by the diagnosis, and the node's count of inputs
outside the fitted envelope (issue 15). Real bags, real command lines, a real node."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from conftest import DEFAULT_TIR, TOOL
from ros_util import NodeProcess, RosClient, node_command, ros_env, wait_for

from tire_model_ros.model import TireModel, write_tir
from tire_model_ros.model.envelope import RIG, SIMULATION, Envelope
from tire_model_ros.rig import simulate_session, write_session

FNOMIN = 6752.0  # config/default.tir
RATE_HZ = 20.0  # a small session: the fit's sweeps at 20 Hz
FIT_TIMEOUT_S = 900.0


@pytest.fixture(scope="module")
def tyre() -> TireModel:
    return TireModel.from_file(DEFAULT_TIR)


def test_rig_at_an_unknown_temperature_counts_as_the_ambient_in_the_ranges(tyre):
    """A rig with no temperature channel and no heating found: OUT.tir's temperature range
    is still the fitted one (the simulation's set temperatures and the rig's ambient), not
    the start file's; a rig wheel whose temperature is known keeps it."""
    from tire_model_ros.fit.extend import at_ambient, fused_ranges
    from tire_model_ros.recording.series import WheelSeries

    n = 400
    slip = np.linspace(-0.1, 0.1, n)

    def wheel(T: np.ndarray | None) -> WheelSeries:
        return WheelSeries("/w", np.arange(n) * 0.01, slip, slip, np.zeros(n),
                           np.full(n, FNOMIN), np.full(n, 2.6e5), T)  # fmt: skip

    rig, hot_rig, sim = wheel(None), wheel(np.full(n, 45.0)), wheel(np.linspace(-10, 80, n))
    T = at_ambient([rig, hot_rig], [None, hot_rig.T], 20.0)
    assert T[0] is not None and np.all(T[0] == 20.0) and T[1] is hot_rig.T
    ranges, _ = fused_ranges(tyre, [rig, hot_rig, sim], [*T, sim.T])
    assert (ranges["TEMPMIN"], ranges["TEMPMAX"]) == (-10.0, 80.0)
    ranges, _ = fused_ranges(tyre, [rig, sim], [*at_ambient([rig], [None], 90.0), sim.T])
    assert ranges["TEMPMAX"] == 90.0  # the rig's ambient beyond the simulation's


# ------------------------------------------------------------------ sidewall contact
@pytest.mark.parametrize("sidewall", [True, False])
def test_diagnosis_names_sidewall_contact_where_only_it_is_left_out(tyre, sidewall):
    """special_conditions twice over, the file's own temperature terms acting at the set
    temperatures: the model is the tyre except for the sidewall (or, the null, exactly)."""
    from tire_model_ros.diagnosis import diagnose

    wheels, truth = simulate_session(
        tyre,
        "special_conditions",
        seed=3,
        rate_hz=25,
        effects={"sidewall": sidewall, "heating": False, "model_temperature": True},
        programme_options={"repeats": 2},
    )
    assert ("sidewall_contact" in truth["diagnosis_words"]) == sidewall
    diag = diagnose(wheels, tyre)
    named = [e.name for e in diag.effects]
    log = "\n".join(diag.details["log"][-20:])
    if sidewall:
        assert named == ["sidewall_contact"], log
        th = diag.effects[0].parameters["deflection_threshold"]
        # 140 kPa at 120 % load: 2.0; 60 kPa: 3.7 (the file's vertical stiffness law, PFZ1
        # 0.88): the rig's gate (half open at 3.0) lies in that gap, which no condition tells
        assert 2.0 < th < 3.7, th
    else:
        assert named == ["none"], log


@pytest.mark.parametrize("sidewall", [True, False])
def test_sidewall_found_in_a_coarse_fe_table(tyre, sidewall):
    """An FE tool's table has a few points per degree, not a rig's 100 a second: the
    noise-free special_conditions at 2 Hz (some 50 lateral samples in the corner) still
    names sidewall_contact against the tyre without it; the null, nothing."""
    from tire_model_ros.fit.sidewall import find_sidewall

    wheels, _ = simulate_session(
        tyre,
        "special_conditions",
        rate_hz=RATE_HZ,
        effects={"sidewall": sidewall, "heating": False, "model_temperature": True,
                 "noise": False},
    )  # fmt: skip
    w = wheels[0]
    table = w.select(np.arange(len(w)) % 10 == 0)
    sw = find_sidewall(tyre, [table])
    assert sw is not None and sw.named == sidewall, sw
    if sidewall:
        assert 2.0 < sw.params[0] < 3.7 and sw.rms_after < 0.3 * sw.rms_before, sw


# ------------------------------------------------------------------ the node counts
def test_node_counts_inputs_outside_the_envelope(tyre, tmp_path):
    """A .tir with an envelope (loads 0.4-1.0 FNOMIN at 260 kPa, 20-40 degC): the node's
    outside_envelope on /diagnostics counts exactly the answered samples outside it."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import Vector3Stamped, WrenchStamped
    from sensor_msgs.msg import FluidPressure, Temperature

    rng = np.random.default_rng(0)
    env = Envelope.from_samples(
        rng.uniform(0.4, 1.0, 2000) * FNOMIN, np.full(2000, 2.6e5), rng.uniform(20, 40, 2000),
        RIG, (0.1 * FNOMIN, 20e3, 5.0), 10,
    )  # fmt: skip
    path = tmp_path / "enveloped.tir"
    write_tir(env.into(tyre.tir), path)
    tyre.evaluate_one(5000.0, 0.05, 0.05, 0.0, 16.6, 2.6e5, 25.0)  # the kernel cached first
    client = RosClient("test_extend_client")
    proc = NodeProcess(
        [*node_command(), "--ros-args", "-r", "__node:=tire_env", "-p", f"tir_file:={path}",
         "-p", "wheels:=['/env']", "-p", "diagnostics_period:=0.3",
         "-p", "timeout.load:=0.0", "-p", "timeout.temperature:=0.0",
         "-p", "timeout.pressure:=0.0",
         "-p", "align.wait:=0.0"],  # unstamped inputs set once: answer each slip on arrival
        ros_env(client.domain_id),
    )  # fmt: skip
    try:
        diags = client.collect(DiagnosticArray, "/diagnostics")
        out = client.collect(WrenchStamped, "/env/forces")
        pubs = {
            "slip": client.publisher(Vector3Stamped, "/env/slip"),
            "load": client.publisher(WrenchStamped, "/env/load"),
            "p": client.publisher(FluidPressure, "/env/pressure"),
            "T": client.publisher(Temperature, "/env/temperature"),
        }
        client.wait_matched(list(pubs.values()), 90, proc)
        pubs["p"].publish(FluidPressure(fluid_pressure=2.6e5))
        pubs["T"].publish(Temperature(temperature=30.0))
        stamp = iter(range(1, 10**6))

        def answered_with(Fz: float, n: int) -> None:
            """Set the load, send slips until n answers carry it."""
            load = WrenchStamped()
            load.wrench.force.z = Fz
            pubs["load"].publish(load)

            def enough() -> bool:
                m = Vector3Stamped()
                m.header.stamp.sec = next(stamp)
                m.vector.x, m.vector.y = 0.05, 0.03
                pubs["slip"].publish(m)
                return sum(1 for f in list(out) if f.wrench.force.z == Fz) >= n

            wait_for(enough, 30, f"{n} answers at Fz = {Fz} N", interval=0.02)

        answered_with(0.7 * FNOMIN, 20)
        answered_with(1.5 * FNOMIN, 20)
        answered_with(0.8 * FNOMIN, 5)  # back inside: no more counted

        def settled() -> dict[str, str] | None:
            """The latest report once it counts every answer received (answers still in
            flight when a load changed arrive late)."""
            for arr in reversed(list(diags)):
                for st in arr.status:
                    if st.name == "tire_env: /env":
                        vals = {kv.key: kv.value for kv in st.values}
                        return vals if int(vals["forces_out"]) == len(out) else None
            return None

        vals = wait_for(settled, 30, "diagnostics with every answer counted")
        loads = [f.wrench.force.z for f in list(out)]
        outside = sum(1 for Fz in loads if not env.contains_one(Fz, 2.6e5, 30.0))
        assert outside >= 20 and sum(1 for Fz in loads if Fz == 1.5 * FNOMIN) == outside
        assert int(vals["outside_envelope"]) == outside, (vals, outside, len(loads))
        assert proc.alive()
    finally:
        proc.stop()
        client.close()


# ------------------------------------------------------------------ a small fused fit
@pytest.fixture(scope="module", autouse=True)
def fused_job(tyre, tmp_path_factory):
    """rig (safe_envelope: heating, no temperature) + simulation (special_conditions) as an
    FE tool's table: written as CSV (``export``), brought in with ``import --format csv``;
    fused from a start file without pressure or temperature terms. The fit is started when
    the module starts and runs beside the tests that do not read it (they come first)."""
    d = tmp_path_factory.mktemp("extend")
    rig, rig_truth = simulate_session(tyre, "safe_envelope", seed=4, rate_hz=RATE_HZ)
    sim, sim_truth = simulate_session(tyre, "special_conditions", seed=5, rate_hz=RATE_HZ)
    write_session(d / "rig", rig, rig_truth)
    write_session(d / "sim", sim, sim_truth)
    for cmd in (
        ["export", str(d / "sim"), "-o", str(d / "fe.csv")],
        ["import", "--format", "csv", str(d / "fe.csv"), "-o", str(d / "fe")],
    ):
        res = subprocess.run([*TOOL, *cmd], capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, res.stderr
    zero = [f"PP{a}{i}" for a in "XY" for i in range(1, 5)]
    zero += [f"TT{a}{i}" for a in "XY" for i in range(1, 5)]
    write_tir(tyre.with_params(dict.fromkeys(zero, 0.0)).tir, d / "start.tir")
    cmd = [*TOOL, "fit", str(d / "rig"), "--tir", str(d / "start.tir"), "-o", str(d / "out.tir"),
           "--extend", str(d / "fe")]  # fmt: skip
    with (d / "fit.stdout").open("w") as out, (d / "fit.stderr").open("w") as err:
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, text=True)
    yield d, proc
    if proc.poll() is None:
        proc.kill()
        proc.wait()


@pytest.fixture(scope="module")
def fused(fused_job):
    """The fused fit's result, once it has ended (checked to exit 0)."""
    d, proc = fused_job
    rc = proc.wait(timeout=FIT_TIMEOUT_S)
    res = subprocess.CompletedProcess(
        proc.args, rc, (d / "fit.stdout").read_text(), (d / "fit.stderr").read_text()
    )
    assert rc == 0, res.stderr[-3000:]
    return d, res


def test_fused_fit_names_the_difference_and_widens_the_ranges(fused):
    d, res = fused
    assert "the rig differs from it by: temperature" in res.stdout, res.stdout
    assert "concealed temperature corrected" in res.stderr
    out = TireModel.from_file(d / "out.tir")
    P = out.params
    assert P["PRESMIN"] <= 60e3 and P["PRESMAX"] >= 299e3  # the start file: 200 / 400 kPa
    assert 0.35 * FNOMIN < P["FZMIN"] < 0.42 * FNOMIN and P["FZMAX"] >= 1.59 * FNOMIN
    assert P["TEMPMIN"] <= -10.0 and P["TEMPMAX"] >= 80.0
    assert P["FZMAX"] < 1.62 * FNOMIN and P["PRESMIN"] > 58e3  # ... and no more
    ext = json.loads((d / "out_fit_report" / "extension.json").read_text())
    assert ext["comparison"]["words"][0] == "temperature"
    assert ext["ranges"]["PRESMIN"] == {"start": 200e3, "fused": P["PRESMIN"]}
    rows = len((d / "fe.csv").read_text().splitlines()) - 1  # the FE table is the SIM
    assert ext["sources"]["simulation_samples"] == rows
    # the simulation's friction is the tyre's: the rig's level found at about 1; the rig's
    # loads and pressures all simulated (special_conditions' overlap block)
    friction = ext["comparison"]["rig_friction_of_simulation"]
    assert 0.95 < friction["LMUX"] < 1.05 and 0.95 < friction["LMUY"] < 1.05, friction
    assert ext["comparison"]["rig_at_simulated_load_and_pressure"] > 0.9
    md = (d / "out_fit_report" / "extension.md").read_text()
    assert "Friction: the rig's is" in md and "% at its temperatures too" in md
    for name in ("extension.md", "envelope.png", "seed_pressure.png", "seed_load.png",
                 "seed_temperature.png", "fit_report.md", "simulation/fit_report.md"):  # fmt: skip
        assert (d / "out_fit_report" / name).stat().st_size > 0, name


def test_fused_envelope_says_which_source_informed_each_region(fused):
    d, _ = fused
    env = Envelope.from_tir(TireModel.from_file(d / "out.tir").tir)
    assert env is not None
    cell = env.index(np.array([1.6 * FNOMIN]), np.array([60e3]), np.array([25.0]))[0]
    assert env.cells[tuple(cell)] == SIMULATION  # low pressure, high load: simulated only
    cell = env.index(np.array([0.7 * FNOMIN]), np.array([260e3]), np.array([35.0]))[0]
    assert env.cells[tuple(cell)] & RIG  # the rig's own conditions
    assert not env.contains_one(1.6 * FNOMIN, 60e3, 80.0)  # never hot at low pressure


def test_fused_model_follows_the_tyre_beyond_the_rig(fused, tyre):
    """Against the noise-free tyre at 60 kPa and 80 degC, away from the sidewall corner: the
    fused model within a few per cent of the force range; the start file far off."""
    d, _ = fused
    truth, _ = simulate_session(
        tyre, "special_conditions", rate_hz=RATE_HZ, effects={"noise": False, "sidewall": False}
    )
    w = truth[0]
    lat = (np.abs(w.kappa) == 0) & (np.abs(w.alpha) < np.radians(8.0))
    lon = np.abs(w.alpha) == 0
    groups = {"60 kPa": (w.p == 60e3) & (w.Fz < 1.25 * FNOMIN), "80 degC": w.T == 80.0}
    models = {k: TireModel.from_file(d / f"{k}.tir") for k in ("out", "start")}
    for name, g in groups.items():
        for c, sel in (("Fx", g & lon & (w.kappa != 0)), ("Fy", g & lat & (w.alpha != 0))):
            y = getattr(w, c)[sel]
            nrmse = {}
            for k, m in models.items():
                o = m.evaluate(w.Fz[sel], w.kappa[sel], w.alpha[sel], 0.0, w.Vx[sel], w.p[sel],
                               w.T[sel])  # fmt: skip
                nrmse[k] = float(np.sqrt(np.mean((getattr(o, c) - y) ** 2)) / np.ptp(y))
            assert nrmse["out"] < 0.03 and nrmse["out"] < nrmse["start"] / 2, (name, c, nrmse)
