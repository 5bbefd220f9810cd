"""ament_python package tire_model_ros."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "tire_model_ros"

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
            "tire_model_node = tire_model_ros.ros.node:main",
            "tire-model-node = tire_model_ros.ros.node:main",
            "tire-model = tire_model_ros.cli:main",
        ],
    },
)
