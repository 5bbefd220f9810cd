"""ROS message classes from type names (``pkg/msg/Name``), without rosidl_runtime_py."""

from __future__ import annotations

import importlib
from typing import Any


def msg_class(msgtype: str) -> Any:
    """The rclpy message class of ``pkg/msg/Name``; ValueError naming the type if unknown.

    ``Any``: generated message classes carry no type information.
    """
    parts = msgtype.split("/")
    if len(parts) != 3 or parts[1] != "msg" or not all(parts):
        raise ValueError(f"message type {msgtype!r}: expected pkg/msg/Name")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.msg"), parts[2])
    except (ImportError, AttributeError):
        raise ValueError(f"message type {msgtype} is not installed") from None
