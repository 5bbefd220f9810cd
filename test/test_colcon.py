"""The package builds with colcon and the installed node runs as ``ros2 run`` would start it.

A copy of the package sources goes to a temporary workspace; ``colcon build`` (the venv's
colcon) installs it; the test then executes ``install/tire_model_ros/lib/tire_model_ros/
tire_model_node`` with the workspace environment (PYTHONPATH to the installed site-packages,
AMENT_PREFIX_PATH to the install prefix) and no tir_file parameter, so the node must find the
installed ``share/tire_model_ros/config/default.tir`` through the ament index.
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

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(120)]

SOURCES = ("setup.py", "setup.cfg", "package.xml", "resource", "config", "tire_model_ros")


def _copy_package(dest: Path) -> None:
    dest.mkdir(parents=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc")
    for name in SOURCES:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=ignore)
        else:
            shutil.copy2(src, dest / name)


def _colcon_build(ws: Path) -> Path:
    colcon = Path(sys.executable).parent / "colcon"
    cmd = [str(colcon), "--log-base", str(ws / "log"), "build", "--base-paths", str(ws / "src"),
           "--build-base", str(ws / "build"), "--install-base", str(ws / "install")]  # fmt: skip
    res = subprocess.run(cmd, cwd=ws, capture_output=True, text=True, timeout=90)
    assert res.returncode == 0, res.stdout + res.stderr
    return ws / "install" / "tire_model_ros"


def _seed_numba_cache(site: Path) -> int:
    """Copy the source tree's numba cache beside the installed modules.

    Numba keys its cache on the source's mtime and size; setuptools keeps the mtime only to
    the second, so the installed .py files get the sources' exact mtime back first. Then numba
    reuses the cache instead of compiling every kernel again (20-40 s on a loaded 2-core
    machine); if anything does not match, numba compiles and the test only takes longer.
    """
    for py in (site / "tire_model_ros").rglob("*.py"):
        src = ROOT / py.relative_to(site)
        if src.is_file() and src.read_bytes() == py.read_bytes():
            st = src.stat()
            os.utime(py, ns=(st.st_atime_ns, st.st_mtime_ns))
    n = 0
    pycache = (ROOT / "tire_model_ros").rglob("__pycache__/*")
    # the .sha256 stamp of model/jit.py's cache guard too, or the guard drops the copied cache
    for cached in (f for f in pycache if f.suffix in (".nbi", ".nbc", ".sha256")):
        rel = cached.relative_to(ROOT)
        dest = site / rel
        if dest.parent.parent.is_dir():
            dest.parent.mkdir(exist_ok=True)
            shutil.copy2(cached, dest)
            n += 1
    return n


def test_colcon_build_and_run_installed_node(tmp_path):
    _copy_package(tmp_path / "src" / "tire_model_ros")
    prefix = _colcon_build(tmp_path)
    exe = prefix / "lib" / "tire_model_ros" / "tire_model_node"
    share_tir = prefix / "share" / "tire_model_ros" / "config" / "default.tir"
    assert os.access(exe, os.X_OK) and share_tir.is_file()
    assert prefix / "share" / "ament_index" / "resource_index" / "packages" / "tire_model_ros"
    site = next(prefix.glob("lib/python3*/site-packages"))
    # Make sure the source tree's cache holds the node's kernel, then give it to the install.
    TireModel.from_file(share_tir).evaluate_one(5000.0, 0.05, 0.05, 0.0, 16.6, 2.6e5, 25.0)
    _seed_numba_cache(site)

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
        assert f"from {site / 'tire_model_ros'}" in log, log
        assert f"shared={share_tir.resolve()}" in log, log

        msg = WrenchStamped()
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
