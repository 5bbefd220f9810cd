"""The node on a recording: ``tire-model play`` into the node, ``tire-model record`` of its
forces, compared with ``tire-model eval`` on the same inputs; every message accounted for by
the three stages' reports. Real processes, real bags."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest
import ros_util
from conftest import DEFAULT_TIR, TOOL

from tire_model_ros.delivery import NODE, PLAY, RECORD, account, parse_reports
from tire_model_ros.recording import decode_topic, read_raw, read_recording, write_recording
from tire_model_ros.rig import simulate_session

PREFIX = "/rig/wheel"


def eval_csv(tmp_path: Path, w) -> np.ndarray:
    """``tire-model eval`` on the recorded inputs: rows of Fx, Fy, Mx, My, Mz."""
    cols = {"Fz": w.Fz, "kappa": w.kappa, "alpha": w.alpha, "gamma": w.gamma, "Vx": w.Vx,
            "p": w.p, "T": w.T}  # fmt: skip
    src, out = tmp_path / "in.csv", tmp_path / "out.csv"
    np.savetxt(src, np.column_stack(list(cols.values())), delimiter=",", header=",".join(cols),
               comments="", fmt="%.17g")  # fmt: skip
    cmd = [*TOOL, "eval", "--tir", str(DEFAULT_TIR), str(src), "-o", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    table = np.genfromtxt(out, delimiter=",", names=True)
    return np.column_stack([table[k] for k in ("Fx", "Fy", "Mx", "My", "Mz")])


@pytest.mark.ros
@pytest.mark.timeout(240)
def test_node_on_played_recording_reproduces_eval(tmp_path):
    wheels, _ = simulate_session(
        str(DEFAULT_TIR), "lateral_sweeps", effects={"heating": True}, seed=4, rate_hz=20.0
    )
    w = wheels[0].select(wheels[0].t < wheels[0].t[0] + 25.0)
    write_recording(tmp_path / "run", [w])
    rec = read_recording(tmp_path / "run")[PREFIX]  # exactly what play will publish
    env = ros_util.ros_env()
    node_args = ["--ros-args", "-p", f"tir_file:={DEFAULT_TIR}", "-p", f'wheels:=["{PREFIX}"]',
                 "-p", "align.wait:=30.0"]  # a replay: every slip with its own load  # fmt: skip
    node = ros_util.NodeProcess([*ros_util.node_command(), *node_args], env)
    record_args = ["-o", str(tmp_path / "forces"), "--wheels", PREFIX, "--count", str(len(rec))]
    recorder = ros_util.NodeProcess([*TOOL, "record", *record_args, "--duration", "150"], env)
    try:
        ros_util.wait_for(lambda: "recording" in recorder.log(), 90, "the recorder to start")
        # the recorder matched to the node's output: no force published before it listens
        node.wait_log(f"{PREFIX}/forces: 1 subscriber(s) matched", 90)
        cmd = [*TOOL, "play", str(tmp_path / "run"), "--rate", "4", "--wait", "20"]
        play = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
        assert ros_util.exited_cleanly(play.returncode, play.stderr), play.stderr
        recorder.proc.wait(timeout=60)
    finally:
        node_rc, node_log = node.stop()
        rc, log = recorder.stop()
    assert ros_util.exited_cleanly(rc, log), log  # it stopped by itself after --count messages
    assert ros_util.exited_cleanly(node_rc, node_log), node_log
    # every slip played is accounted for by the three stages' own reports, and none is lost
    acc = account(PREFIX, parse_reports(play.stdout, PLAY), parse_reports(node_log, NODE),
                  parse_reports(log, RECORD))  # fmt: skip
    assert acc.unexplained == 0, acc.text()
    assert acc.played == acc.recorded == len(rec), acc.text()
    ch = decode_topic(read_raw(tmp_path / "forces"), f"{PREFIX}/forces")
    t_ns = rec.meta["t_ns"]
    assert np.array_equal(ch.stamp_ns, t_ns), "one forces message per slip, with its stamp"
    node_out = ch.values[:, [0, 1, 3, 4, 5]]  # force.x, force.y, torque.x, torque.y, torque.z
    np.testing.assert_allclose(ch.values[:, 2], rec.Fz, rtol=1e-12)
    np.testing.assert_allclose(node_out, eval_csv(tmp_path, rec), rtol=1e-9, atol=1e-6)
