"""Write a rosbag2 (MCAP) recording in the INTERFACE.md layout with ``rosbags`` directly.

Shared by the generators so that none of them depends on the package's own bag code.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

TYPES = {
    "slip": "geometry_msgs/msg/Vector3Stamped",  # (N, 3): kappa, alpha [rad], gamma [rad]
    "load": "geometry_msgs/msg/WrenchStamped",  # (N,): Fz [N], positive = compression
    "pressure": "sensor_msgs/msg/FluidPressure",  # (N,): gauge pressure [Pa]
    "temperature": "sensor_msgs/msg/Temperature",  # (N,): tread temperature [degC]
    "velocity": "geometry_msgs/msg/TwistStamped",  # (N,): Vx [m/s]
    "measured_forces": "geometry_msgs/msg/WrenchStamped",  # (N, 6): Fx Fy Fz Mx My Mz
}


def write_bag(path: str | Path, wheels: Mapping[str, Mapping[str, tuple]]) -> None:
    """Write ``wheels`` = {prefix: {channel: (t_s, values)}} as a rosbag2 folder at ``path``.

    ``channel`` is a key of :data:`TYPES`; ``t_s`` the header stamps [s] (also the log
    times), ``values`` shaped as noted there. Channels left out are simply not written.
    ``path`` must not exist.
    """
    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    Header = T["std_msgs/msg/Header"]
    Time = T["builtin_interfaces/msg/Time"]
    V3 = T["geometry_msgs/msg/Vector3"]

    def header(ns: int):
        return Header(stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id="")

    def make(ch: str, ns: int, v):
        if ch == "slip":
            return T[TYPES[ch]](
                header=header(ns), vector=V3(x=float(v[0]), y=float(v[1]), z=float(v[2]))
            )
        if ch in ("load", "measured_forces"):
            f = np.zeros(6)
            if ch == "load":
                f[2] = float(v)
            else:
                f[: len(v)] = v
            W = T["geometry_msgs/msg/Wrench"](
                force=V3(x=f[0], y=f[1], z=f[2]), torque=V3(x=f[3], y=f[4], z=f[5])
            )
            return T[TYPES[ch]](header=header(ns), wrench=W)
        if ch == "pressure":
            return T[TYPES[ch]](header=header(ns), fluid_pressure=float(v), variance=0.0)
        if ch == "temperature":
            return T[TYPES[ch]](header=header(ns), temperature=float(v), variance=0.0)
        if ch == "velocity":
            Tw = T["geometry_msgs/msg/Twist"](
                linear=V3(x=float(v), y=0.0, z=0.0), angular=V3(x=0.0, y=0.0, z=0.0)
            )
            return T[TYPES[ch]](header=header(ns), twist=Tw)
        raise KeyError(ch)

    events = []  # (log ns, topic, channel, value)
    for prefix, chans in wheels.items():
        for ch, (t, vals) in chans.items():
            ns = np.round(np.asarray(t, float) * 1e9).astype(np.int64)
            vals = np.asarray(vals, float)
            for k in range(len(ns)):
                events.append((int(ns[k]), f"{prefix}/{ch}", ch, vals[k]))
    events.sort(key=lambda e: e[0])
    with Writer(Path(path), version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {}
        for prefix, chans in wheels.items():
            for ch in chans:
                topic = f"{prefix}/{ch}"
                conns[topic] = w.add_connection(topic, TYPES[ch], typestore=ts)
        for ns, topic, ch, v in events:
            msg = make(ch, ns, v)
            w.write(conns[topic], ns, ts.serialize_cdr(msg, TYPES[ch]))
