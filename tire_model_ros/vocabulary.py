"""The shared words of ``../shared/INTERFACE.md``: topics, message types, channels, effect names.

One home for the names that the node, the recordings, the rig, the fit, the diagnosis and the
tests must agree on; they import them from here instead of spelling them again. No ROS import
(message types are ``pkg/msg/Name`` strings; :mod:`tire_model_ros.ros.msg_types` turns them
into rclpy classes).
"""

from __future__ import annotations

from typing import Final

# ----------------------------------------------------------------------------- message types

VECTOR3_STAMPED: Final = "geometry_msgs/msg/Vector3Stamped"
WRENCH_STAMPED: Final = "geometry_msgs/msg/WrenchStamped"
FLUID_PRESSURE: Final = "sensor_msgs/msg/FluidPressure"
TEMPERATURE: Final = "sensor_msgs/msg/Temperature"
TWIST_STAMPED: Final = "geometry_msgs/msg/TwistStamped"

# ----------------------------------------------------------------------------- topics

#: Channel (the last part of a wheel's topic name ``P/<channel>``) -> message type
#: (INTERFACE.md "Topics, one set per wheel").
CHANNEL_TYPES: Final[dict[str, str]] = {
    "slip": VECTOR3_STAMPED,
    "load": WRENCH_STAMPED,
    "pressure": FLUID_PRESSURE,
    "temperature": TEMPERATURE,
    "velocity": TWIST_STAMPED,
    "forces": WRENCH_STAMPED,
    "measured_forces": WRENCH_STAMPED,
}
#: The channels that make a prefix a wheel of a recording.
REQUIRED_CHANNELS: Final = ("slip", "load", "measured_forces")
#: Inputs that may be absent: the tyre file's nominal value stands in.
OPTIONAL_CHANNELS: Final = ("pressure", "temperature", "velocity")
#: The node's inputs besides ``slip`` (each slip message triggers one output).
NODE_INPUTS: Final = ("load", *OPTIONAL_CHANNELS)
#: The node's output channel: one ``WrenchStamped`` per slip message, same stamp.
FORCES: Final = "forces"
#: The one float64 field that each of the node's inputs besides slip carries (CDR field path,
#: as in :data:`tire_model_ros.recording.cdr.LAYOUTS`).
INPUT_FIELDS: Final[dict[str, str]] = {
    "load": "wrench.force.z",
    "pressure": "fluid_pressure",
    "temperature": "temperature",
    "velocity": "twist.linear.x",
}
#: The wheel prefix of the virtual rig and of a one-wheel recording by default.
RIG_PREFIX: Final = "/rig/wheel"

# ----------------------------------------------------------------------------- aligned series

#: Every per-sample channel of a ``WheelSeries`` with its unit, in the order they are listed.
SERIES_UNITS: Final[dict[str, str]] = {
    "kappa": "-",
    "alpha": "rad",
    "gamma": "rad",
    "Fz": "N",
    "p": "Pa",
    "T": "degC",
    "Vx": "m/s",
    "Fx": "N",
    "Fy": "N",
    "Fz_meas": "N",
    "Mx": "N m",
    "My": "N m",
    "Mz": "N m",
}
SERIES_CHANNELS: Final = tuple(SERIES_UNITS)
#: Optional topic channel -> the ``WheelSeries`` attribute it fills (its one value).
OPTIONAL_SERIES: Final[dict[str, str]] = {"pressure": "p", "temperature": "T", "velocity": "Vx"}
#: ``WheelSeries`` attributes of the measured wrench, in WrenchStamped field order.
WRENCH_SERIES: Final = ("Fx", "Fy", "Fz_meas", "Mx", "My", "Mz")
#: Model inputs of a sample (``WheelSeries`` attributes); Vx, p and T may be absent (None).
MODEL_INPUTS: Final = ("Fz", "kappa", "alpha", "gamma", "Vx", "p", "T")
#: Force and moment channels of a wheel, as the model gives them and a recording measures them.
FORCE_CHANNELS: Final = ("Fx", "Fy", "Mx", "My", "Mz")
#: The channels the mismatch diagnosis compares and reports, in report order.
DIAGNOSED_CHANNELS: Final = ("Fx", "Fy", "Mz")

# ----------------------------------------------------------------------------- diagnosis

#: The words for missing physics (INTERFACE.md "Mismatch diagnosis"); they keep their meaning.
EFFECT_WORDS: Final = (
    "temperature",
    "pressure",
    "relaxation",
    "camber",
    "combined_slip",
    "speed",
    "offset",
    "time_delay",
    "drift",
    "sidewall_contact",
    "none",
)

#: What in a programme shows each word's physics and not its look-alikes (PHYSICS.md, "tells it
#: apart"): what to record when a diagnosis says a recording does not tell two words apart.
TOLD_APART_BY: Final[dict[str, str]] = {
    "temperature": "a cooling pause (a heated tyre's grip comes back), or a recorded tread "
    "temperature",
    "pressure": "a recorded inflation pressure (a sealed tyre's follows its gas temperature, a "
    "leak's falls with no heat)",
    "relaxation": "sweeps at two speeds (its loop grows with the slip rate over the speed)",
    "camber": "sweeps at two or more cambers (it grows linearly with the camber from the first "
    "sweep)",
    "combined_slip": "pure-slip sweeps beside combined ones (it acts only where both slips are "
    "non-zero)",
    "speed": "one condition at two speeds with the tyre in the same state (friction that "
    "follows the speed changes at once, not with the energy put in)",
    "offset": "sweeps through zero slip at several cambers (an offset stays, whatever the camber)",
    "time_delay": "sweeps at two speeds (a delay's loop grows with the slip rate alone, at any "
    "speed)",
    "drift": "a reference sweep repeated after a cooling pause (wear does not come back, heat "
    "does)",
    "sidewall_contact": "sweeps past the peak at low pressure and high load, and at high "
    "pressure (only the deflected tyre loses)",
}

# ----------------------------------------------------------------------------- constants

NS_PER_S: Final = 1_000_000_000
#: Standard atmosphere [Pa]: gauge <-> absolute inflation pressure.
STANDARD_ATMOSPHERE_PA: Final = 101325.0
