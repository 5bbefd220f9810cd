"""ament_python package tire_model_ros.

``setup.py install`` (what ``colcon build`` runs) and ``setup.py develop`` (``colcon build
--symlink-install``) end by making the Magic Formula kernels ready in numba's cache beside the
installed modules, so the installed node starts in a second instead of compiling for a minute:
a cache the source tree already holds for the very same sources is copied (with the sources'
times, numba's key), anything else is compiled (~35 s of CPU). A pip wheel has no install hook;
there the node compiles on its first start and says so (``tire_model_ros.model.startup``).
"""

import os
import shutil
import subprocess
import sys
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup
from setuptools.command.develop import develop
from setuptools.command.install import install

PACKAGE = "tire_model_ros"
HERE = Path(__file__).resolve().parent
CACHE_FILES = (".nbi", ".nbc", ".sha256")  # numba's index and code, the cache guard's stamp


def seed_kernel_cache(site: Path) -> int:
    """Copy the source tree's numba cache beside the installed modules; files copied.

    numba keys its cache on a source's mtime and size, so an installed module identical to its
    source first gets the source's exact mtime back.
    """
    n = 0
    for installed in (site / PACKAGE).rglob("*.py"):
        src = HERE / installed.relative_to(site)
        if src.is_file() and src.read_bytes() == installed.read_bytes():
            st = src.stat()
            os.utime(installed, ns=(st.st_atime_ns, st.st_mtime_ns))
    for cached in (HERE / PACKAGE).rglob("__pycache__/*"):
        dest = site / cached.relative_to(HERE)
        if cached.suffix in CACHE_FILES and dest.parent.parent.is_dir() and dest != cached:
            dest.parent.mkdir(exist_ok=True)
            shutil.copy2(cached, dest)
            n += 1
    return n


def compile_kernels(site: Path) -> None:
    """Load or compile the kernels with ``site`` first on the path (a failure only warns: the
    node then compiles on its first start, saying so)."""
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])
    )
    code = "from tire_model_ros.model.startup import warm_up_announced; warm_up_announced()"
    print(f"{PACKAGE}: making the Magic Formula kernels ready in numba's cache under {site}")
    done = subprocess.run([sys.executable, "-c", code], env=env, check=False)
    if done.returncode:
        print(f"{PACKAGE}: warning: the kernels were not compiled now ({done.returncode}); "
              "the node compiles them on its first start")  # fmt: skip


class InstallWithKernels(install):
    def run(self) -> None:
        super().run()
        if "bdist_wheel" not in self.distribution.commands:  # a wheel's files move afterwards
            site = Path(self.install_lib)
            seed_kernel_cache(site)
            compile_kernels(site)


class DevelopWithKernels(develop):
    def run(self) -> None:
        super().run()
        if not self.uninstall:
            compile_kernels(Path(self.egg_path).resolve())


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*", "realities", "realities.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*")),
    ],
    # Every third-party module the offline tool imports: ``pip install .`` alone gives a
    # working ``tire-model`` (eval, simulate, fit, diagnose, info). The node, play and record
    # need ROS 2 (rclpy and the message packages: package.xml), which pip does not provide.
    install_requires=[
        "setuptools",
        "numpy>=1.24",
        "scipy>=1.10",
        "numba>=0.59",
        "llvmlite>=0.42",  # imported directly by the kernels (model/jit.py, model/vmath.py)
        "mcap>=1.1",
        "rosbags>=0.10",
        "matplotlib>=3.6",
        "PyYAML>=6.0",
        "threadpoolctl>=3.1",
    ],
    zip_safe=True,
    maintainer="tire_model_ros developers",
    maintainer_email="dev@tire-model-ros.invalid",
    description=(
        "Extended Magic Formula tyre model: wheel-force node, refit tool, mismatch diagnosis."
    ),
    license="BSD-3-Clause",
    python_requires=">=3.11",
    entry_points={
        "console_scripts": [
            # through tire_model_ros.ros: without ROS they say so instead of a traceback
            "tire_model_node = tire_model_ros.ros:node_main",
            "tire-model-node = tire_model_ros.ros:node_main",
            "tire_model_lifecycle_node = tire_model_ros.ros:lifecycle_main",
            "tire-model-lifecycle-node = tire_model_ros.ros:lifecycle_main",
            "tire-model = tire_model_ros.cli:main",
        ],
    },
    cmdclass={"install": InstallWithKernels, "develop": DevelopWithKernels},
)
