"""The package declares what it imports: every third-party module of ``tire_model_ros`` outside
ROS is installed by setup.py's ``install_requires`` (``pip install .`` alone runs the offline
tool), every ROS package it imports is an ``exec_depend`` of package.xml, and every file the
install names exists. Read from the sources (setup.py, package.xml and the import statements of
every module, those inside functions included), so a new import without its dependency fails
here, not on a user's machine.
"""

from __future__ import annotations

import ast
import importlib.metadata
import re
import sys
import xml.etree.ElementTree as ET
from glob import glob

from conftest import ROOT

from tire_model_ros.vocabulary import CHANNEL_TYPES

PACKAGE = ROOT / "tire_model_ros"
# A ROS 2 package, as test_no_ros.py blocks them: rclpy, ament*, rosidl*, *_msgs, *_srvs, ...
ROS = re.compile(r"^(rclpy|rpyutils|ament\w*|rosidl\w*|rmw\w*|\w+_msgs|\w+_srvs|\w+_interfaces)$")


def _setup_call() -> ast.Call:
    tree = ast.parse((ROOT / "setup.py").read_text())
    return next(
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "setup"
    )


def _keyword(name: str) -> ast.expr | None:
    return next((k.value for k in _setup_call().keywords if k.arg == name), None)


def install_requires() -> set[str]:
    """Distribution names of setup.py's install_requires, normalised (PEP 503)."""
    value = _keyword("install_requires")
    assert isinstance(value, ast.List)
    names = set()
    for item in value.elts:
        assert isinstance(item, ast.Constant) and isinstance(item.value, str)
        names.add(re.split(r"[<>=!~;\[ ]", item.value, maxsplit=1)[0])
    return {_normalise(n) for n in names}


def _normalise(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def imports() -> dict[str, set[str]]:
    """Top-level module -> the package files (relative) that import it, stdlib excluded."""
    found: dict[str, set[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.partition(".")[0]
                if top not in sys.stdlib_module_names and top != "tire_model_ros":
                    found.setdefault(top, set()).add(str(path.relative_to(ROOT)))
    return found


def exec_depends() -> set[str]:
    root = ET.parse(ROOT / "package.xml").getroot()
    return {e.text.strip() for e in root.iter("exec_depend") if e.text}


def test_every_third_party_import_outside_ros_is_installed_by_setup_py() -> None:
    required = install_requires()
    dists = importlib.metadata.packages_distributions()
    missing = []
    for module, files in sorted(imports().items()):
        if ROS.match(module):
            continue
        providers = {_normalise(d) for d in dists.get(module, [])}
        assert providers, f"{module} (imported by {sorted(files)}) is not installed here"
        if not providers & required:
            missing.append(f"{module} ({'/'.join(sorted(providers))}; {sorted(files)[0]})")
    assert not missing, f"imported but not in setup.py install_requires: {missing}"
    # and the list is what is imported: numba's own dependency llvmlite is imported directly
    assert {"numpy", "scipy", "numba", "llvmlite", "mcap", "rosbags", "pyyaml"} <= required


def test_every_ros_package_imported_is_an_exec_depend() -> None:
    depends = exec_depends()
    ros = {m: f for m, f in imports().items() if ROS.match(m)}
    assert "rclpy" in ros  # the scan sees the node's imports
    # the message packages the node imports by name (ros/msg_types.py: "pkg/msg/Name")
    named = {t.partition("/")[0] for t in CHANNEL_TYPES.values()}
    missing = sorted((set(ros) | named) - depends)
    assert not missing, f"imported ROS packages not in package.xml <exec_depend>: {missing}"
    # outside tire_model_ros/ros/ a ROS import is optional (guarded); it is declared all the same
    outside = {m for m, files in ros.items() if any(not f.startswith(("tire_model_ros/ros/",))
                                                    for f in files)}  # fmt: skip
    assert outside <= depends, outside


def test_every_file_the_install_names_exists() -> None:
    package_data = _keyword("package_data")
    if package_data is not None:  # {package: [patterns]}: each matches a file of the package
        data = ast.literal_eval(package_data)
        for package, patterns in data.items():
            base = ROOT / package.replace(".", "/")
            for pattern in patterns:
                assert glob(str(base / pattern)), f"package_data {package}: {pattern} is nothing"
    data_files = _keyword("data_files")
    assert isinstance(data_files, ast.List)
    text = (ROOT / "setup.py").read_text()
    for entry in data_files.elts:
        assert isinstance(entry, ast.Tuple)
        sources = entry.elts[1]
        if isinstance(sources, ast.List):  # literal paths (f-strings with the package name)
            for item in sources.elts:
                path = ast.get_source_segment(text, item)
                assert path is not None
                name = path.strip("f\"'").replace("{PACKAGE}", "tire_model_ros")
                assert (ROOT / name).is_file(), f"setup.py data_files names {name}: missing"
        else:  # glob("config/*")
            pattern = ast.get_source_segment(text, sources)
            assert pattern is not None and pattern.startswith("glob(")
            folder = pattern[len("glob(") :].strip(")\"'")
            assert glob(str(ROOT / folder)), f"setup.py data_files glob {folder}: matches nothing"
    assert (ROOT / "resource" / "tire_model_ros").is_file()  # the ament index marker
