"""The package builds with colcon and the installed node runs as ``ros2 run`` would start it.

A copy of the package sources goes to a temporary workspace, with the numba cache this source
tree holds (a developer's tree); ``colcon build`` (the venv's colcon) installs it, and its
``setup.py install`` makes the kernels ready beside the installed modules (the tree's cache
copied for the same sources, else compiled). The test then executes
``install/tire_model_ros/lib/tire_model_ros/tire_model_node`` with the workspace environment
(PYTHONPATH to the installed site-packages, AMENT_PREFIX_PATH to the install prefix) and no
tir_file parameter, so the node must find the installed ``share/tire_model_ros/config/
default.tir`` through the ament index, and start without compiling (no first-start notice).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT
from ros_util import NodeProcess, RosClient, exited_cleanly, ros_env, wait_for

from tire_model_ros.model import TireModel
from tire_model_ros.model.startup import COMPILE_NOTICE

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(600)]

SOURCES = ("setup.py", "setup.cfg", "package.xml", "resource", "config", "tire_model_ros")


def _copy_package(dest: Path) -> None:
    """The sources and their numba cache, with their times (numba's key)."""
    dest.mkdir(parents=True)
    ignore = shutil.ignore_patterns("*.pyc")
    for name in SOURCES:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=ignore)
        else:
            shutil.copy2(src, dest / name)


def _colcon_build(ws: Path) -> tuple[Path, str]:
    colcon = Path(sys.executable).parent / "colcon"
    cmd = [str(colcon), "--log-base", str(ws / "log"), "build", "--base-paths", str(ws / "src"),
           "--build-base", str(ws / "build"), "--install-base", str(ws / "install"),
           "--event-handlers", "console_direct+"]  # fmt: skip
    # a cache that does not match compiles the kernels here: minutes on a busy machine
    res = subprocess.run(cmd, cwd=ws, capture_output=True, text=True, timeout=480)
    assert res.returncode == 0, res.stdout + res.stderr
    return ws / "install" / "tire_model_ros", res.stdout + res.stderr


def test_colcon_build_and_run_installed_node(tmp_path):
    # the source tree's cache holds the node's kernels (make venv compiled them)
    TireModel.from_file(ROOT / "config" / "default.tir").evaluate_one(
        5000.0, 0.05, 0.05, 0.0, 16.6, 2.6e5, 25.0
    )
    _copy_package(tmp_path / "src" / "tire_model_ros")
    prefix, build_log = _colcon_build(tmp_path)
    assert "making the Magic Formula kernels ready" in build_log, build_log
    exe = prefix / "lib" / "tire_model_ros" / "tire_model_node"
    share_tir = prefix / "share" / "tire_model_ros" / "config" / "default.tir"
    assert os.access(exe, os.X_OK) and share_tir.is_file()
    assert prefix / "share" / "ament_index" / "resource_index" / "packages" / "tire_model_ros"
    site = next(prefix.glob("lib/python3*/site-packages"))
    cache = site / "tire_model_ros" / "model" / "__pycache__"
    assert list(cache.glob("kernel.evaluate_point-*.nbi")), "no kernels compiled at install"

    client = RosClient("test_colcon_client")
    env = ros_env(
        client.domain_id,
        {"PYTHONPATH": str(site), "AMENT_PREFIX_PATH": str(prefix)},
    )
    proc = NodeProcess([str(exe), "--ros-args", "-p", "timeout.load:=0.0"], env, cwd=tmp_path)
    try:
        from geometry_msgs.msg import Vector3Stamped, WrenchStamped

        out = client.collect(WrenchStamped, "/wheel/forces")
        slip = client.publisher(Vector3Stamped, "/wheel/slip")
        load = client.publisher(WrenchStamped, "/wheel/load")
        client.wait_matched([slip, load], 60, proc)
        # The installed package and the installed default.tir, found through the ament index.
        proc.wait_log("models:", 10)
        log = proc.log()
        assert COMPILE_NOTICE not in log, log  # ready from the install, not compiled now
        assert f"from {site / 'tire_model_ros'}" in log, log
        assert f"shared={share_tir.resolve()}" in log, log

        msg = WrenchStamped()
        msg.header.stamp.sec = 42  # with the slips (a load stamped behind them holds them)
        msg.wrench.force.z = 5500.0
        load.publish(msg)
        model = TireModel.from_file(share_tir)

        def forces_with_load():
            s = Vector3Stamped()
            s.header.stamp.sec = 42
            s.vector.x, s.vector.y = 0.05, 0.03
            slip.publish(s)
            return [m for m in list(out) if m.wrench.force.z == 5500.0]

        got = wait_for(forces_with_load, 20, "forces computed with the published load")[0]
        want = model.evaluate(5500.0, 0.05, 0.03, 0.0)
        f, t = got.wrench.force, got.wrench.torque
        np.testing.assert_allclose(
            [f.x, f.y, t.x, t.y, t.z],
            [float(want.Fx), float(want.Fy), float(want.Mx), float(want.My), float(want.Mz)],
            rtol=1e-9,
        )
        assert got.header.stamp.sec == 42
    finally:
        rc, log = proc.stop(signal.SIGTERM)
        client.close()
    assert exited_cleanly(rc, log) and "Traceback" not in log, log
