"""The offline tool without ROS: nothing outside ``tire_model_ros/ros/`` imports a ROS module.

Each check runs in a subprocess whose ``sitecustomize`` puts an import blocker first on
``sys.meta_path``: importing rclpy, rosidl, ament or any ROS message/service package fails
there as it does on a machine without ROS.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import DEFAULT_TIR, ROOT, TOOL

BLOCKER = '''
import sys

ROS_TOPS = ("rclpy", "rpyutils", "rcl_interfaces", "builtin_interfaces", "unique_identifier_msgs")
ROS_PREFIXES = ("rosidl", "ament", "rmw", "rosgraph", "type_description")
ROS_SUFFIXES = ("_msgs", "_srvs", "_interfaces")


class NoRos:
    """Fails every import of a ROS 2 module, as on a machine without ROS."""

    def find_spec(self, name, path=None, target=None):
        top = name.partition(".")[0]
        if top in ROS_TOPS or top.startswith(ROS_PREFIXES) or top.endswith(ROS_SUFFIXES):
            raise ModuleNotFoundError(f"No module named {name!r} (ROS blocked)", name=name)
        return None


sys.meta_path.insert(0, NoRos())
'''

#: Imports every module of the package outside ``tire_model_ros.ros`` (its ``__init__`` is
#: ROS-free too) and prints any ROS module that got loaded.
IMPORT_ALL = """
import importlib, pkgutil, sys
import tire_model_ros
names = [m.name for m in pkgutil.walk_packages(tire_model_ros.__path__, "tire_model_ros.")]
core = [n for n in names if not n.startswith("tire_model_ros.ros.") and not n.endswith("__main__")]
for name in core:
    importlib.import_module(name)
print(len(core), sorted(m for m in sys.modules if m.startswith(("rclpy", "rosidl", "ament"))))
"""


@pytest.fixture(scope="module")
def no_ros_env(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    site = tmp_path_factory.mktemp("no_ros_site")
    (site / "sitecustomize.py").write_text(BLOCKER)
    path = os.pathsep.join(p for p in (str(site), os.environ.get("PYTHONPATH", "")) if p)
    return {**os.environ, "PYTHONPATH": path, "PYTHONDONTWRITEBYTECODE": "1"}


def _run(cmd: list[str], env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, timeout=300)


def test_the_blocker_blocks(no_ros_env: dict[str, str], tmp_path: Path) -> None:
    done = _run([sys.executable, "-c", "import rclpy"], no_ros_env, tmp_path)
    assert done.returncode == 1 and "ROS blocked" in done.stderr, done.stderr


def test_every_module_outside_ros_imports_without_ros(
    no_ros_env: dict[str, str], tmp_path: Path
) -> None:
    done = _run([sys.executable, "-c", IMPORT_ALL], no_ros_env, tmp_path)
    assert done.returncode == 0, done.stderr
    count, loaded = done.stdout.split(" ", 1)
    assert int(count) > 40 and loaded.strip() == "[]", done.stdout


@pytest.mark.timeout(600)  # the rig's kernels may compile here first, on a loaded machine
def test_simulate_info_and_eval_run_without_ros(no_ros_env: dict[str, str], tmp_path: Path) -> None:
    bag = tmp_path / "run"
    tir = str(DEFAULT_TIR)
    programme = "lateral_sweeps:rate_scale=4"  # 100 s of session at 20 Hz
    sim = [*TOOL, "simulate", "--tir", tir, "--programme", programme, "--rate", "20"]
    done = _run([*sim, "-o", str(bag), "--omit", "temperature"], no_ros_env, tmp_path)
    assert done.returncode == 0, done.stderr
    done = _run([*TOOL, "info", str(bag)], no_ros_env, tmp_path)
    assert done.returncode == 0, done.stderr
    assert "/rig/wheel" in done.stdout, done.stdout
    src = tmp_path / "in.csv"
    src.write_text("Fz,kappa,alpha,gamma,Vx,p\n4000,0.05,0.02,0,16.6,200000\n")
    done = _run([*TOOL, "eval", "--tir", tir, str(src), "-o", "out.csv"], no_ros_env, tmp_path)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "out.csv").read_text().startswith("Fz,kappa,alpha,gamma,Vx,p")


@pytest.mark.parametrize("command", ["play", "record"])
def test_ros_commands_say_they_need_ros(
    no_ros_env: dict[str, str], tmp_path: Path, command: str
) -> None:
    args = {"play": ["no_such_bag"], "record": ["-o", "out", "--wheels", "/rig/wheel"]}[command]
    done = _run([*TOOL, command, *args], no_ros_env, tmp_path)
    assert done.returncode == 1, done.stderr
    assert f"tire-model {command} needs ROS 2 Jazzy (rclpy)" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr


#: The console scripts that start a node, and the function each runs, as setup.py declares them.
NODE_SCRIPTS = re.findall(
    r'"(tire[-_]model[-_][\w-]*node) = ([\w.]+):(\w+)"', (ROOT / "setup.py").read_text()
)


@pytest.mark.parametrize(("script", "module", "function"), NODE_SCRIPTS)
def test_node_scripts_say_they_need_ros(
    no_ros_env: dict[str, str], tmp_path: Path, script: str, module: str, function: str
) -> None:
    """What the installed script runs (setup.py's entry point) fails in one line, no traceback."""
    run = f"import sys, {module} as m; sys.exit(m.{function}())"
    done = _run([sys.executable, "-c", run], no_ros_env, tmp_path)
    assert done.returncode == 1, done.stderr
    assert "needs ROS 2 Jazzy (rclpy), which cannot be imported here" in done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr, done.stderr


def test_every_node_script_is_checked() -> None:
    names = {s for s, _, _ in NODE_SCRIPTS}
    assert names == {
        "tire_model_node",
        "tire-model-node",
        "tire_model_lifecycle_node",
        "tire-model-lifecycle-node",
    }
