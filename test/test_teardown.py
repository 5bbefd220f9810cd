"""The teardown deadline (tire_model_ros.ros.teardown) ends a process stuck in C code holding the
GIL, as Fast DDS can be in teardown, and does nothing to a block that finishes in time."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest
from ros_util import exited_cleanly, ros_env

STUCK = """
import ctypes
from tire_model_ros.ros.teardown import deadline
with deadline({seconds}):
    ctypes.PyDLL(None).sleep({block})  # a C call that keeps the GIL, as a DDS deadlock would
print("after the block")
"""


def run(seconds: float, block: int) -> tuple[subprocess.CompletedProcess, float]:
    t0 = time.monotonic()
    done = subprocess.run([sys.executable, "-c", STUCK.format(seconds=seconds, block=block)],
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    return done, time.monotonic() - t0


def test_stuck_block_exits_1_with_stacks():
    done, wall = run(0.5, 30)
    assert done.returncode == 1 and wall < 20, (done, wall)
    assert "Timeout (0:00:00.500000)!" in done.stderr and "line 5" in done.stderr, done.stderr
    assert "after the block" not in done.stdout
    with pytest.warns(UserWarning, match="teardown deadline hit"):  # tolerated, not hidden
        assert exited_cleanly(done.returncode, done.stderr)


def test_block_in_time_is_left_alone():
    done, _ = run(2.0, 0)
    assert done.returncode == 0 and "after the block" in done.stdout, done
    assert not exited_cleanly(1, "Traceback (most recent call last):\n")


SIGNAL_WHILE_MADE = """
import rclpy
from rclpy.node import Node
from std_msgs.msg import String
from tire_model_ros.ros.node import run

def make():
    node = Node("made_when_signalled")
    rclpy.shutdown()  # what SIGTERM does to the context while a node is still being made
    node.create_publisher(String, "/x", 10)  # fails on the shut context
    return node

rclpy.init()
print("exit", run(make))
"""


def test_a_signal_while_the_node_is_made_is_a_clean_exit():
    """SIGTERM under load can land while the node's constructor still creates publishers:
    the next create_* fails on the shut context (a traceback and status 1 on a loaded
    machine, test_signal_clean_exit); that is a shutdown, exit 0, no traceback. Any other
    ROS error, with the context still up, still propagates."""
    env = ros_env()
    done = subprocess.run([sys.executable, "-c", SIGNAL_WHILE_MADE], capture_output=True,
                          text=True, timeout=60, env=env)  # fmt: skip
    assert done.returncode == 0 and "exit 0" in done.stdout, done
    assert "Traceback" not in done.stderr, done.stderr
    broken = SIGNAL_WHILE_MADE.replace(
        "rclpy.shutdown()",
        "from rclpy.impl.implementation_singleton import rclpy_implementation as r\n"
        "    raise r.RCLError('not a shutdown')",
    )
    done = subprocess.run([sys.executable, "-c", broken], capture_output=True, text=True,
                          timeout=60, env=env)  # fmt: skip
    assert done.returncode != 0 and "RCLError: not a shutdown" in done.stderr, done
