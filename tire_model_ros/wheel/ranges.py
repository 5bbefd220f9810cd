"""The valid range of every input of the node, and their saturation (no ROS import).

From the model's file: load FZMIN..FZMAX, slip ratio KPUMIN..KPUMAX, slip angle ALPMIN..ALPMAX,
inclination CAMMIN..CAMMAX, gauge pressure PRESMIN..PRESMAX, temperature TEMPMIN..TEMPMAX (the
file's ``[TEMPERATURE_RANGE]``, else the table's physical sanity range). A .tir gives no speed
range: |Vx| <= :data:`SPEED_SANITY_M_S` stands in (the model's finiteness check covers it).

With ``limits`` on, every input outside its range is saturated to the range's edge: the slips,
the pressure and the temperature by the model itself (``evaluate(limits=True)``, MFeval's rule,
which also keeps the slip ratio before saturation for the fade of My near standstill, so the
node gives what ``tire-model eval`` gives); the load above FZMAX and the speed by the node
(:data:`NODE_SATURATES`), since the model keeps the load as given in force.z and in My, and has
no speed range. Decisions:

- A load between 0 and FZMIN is not raised to FZMIN: the model has its own rule there (MFeval's:
  FZMIN enters the aligning torque only), so it counts as out of range without being changed.
  A load <= 0 is a wheel off the ground, not an out-of-range load (see :mod:`.state`).
- With ``limits`` off nothing is changed, but values outside still count as out of range.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from tire_model_ros.model.check import SPEED_SANITY_M_S

#: The inputs of one sample in the order :meth:`InputRanges.saturate` takes and returns them.
SAMPLE_INPUTS = ("load", "kappa", "alpha", "gamma", "pressure", "temperature", "velocity")
_RANGE_KEYS = {
    "load": ("FZMIN", "FZMAX"),
    "kappa": ("KPUMIN", "KPUMAX"),
    "alpha": ("ALPMIN", "ALPMAX"),
    "gamma": ("CAMMIN", "CAMMAX"),
    "pressure": ("PRESMIN", "PRESMAX"),
    "temperature": ("TEMPMIN", "TEMPMAX"),
}

Sample = tuple[float, float, float, float, float, float, float]
#: Indices into a :data:`Sample` of the inputs the node saturates itself (load, speed).
NODE_SATURATES = (0, 6)


@dataclass(frozen=True)
class InputRanges:
    """(lo, hi) per input of :data:`SAMPLE_INPUTS`, SI units (Pa gauge, degC, m/s)."""

    bounds: tuple[tuple[float, float], ...]

    @classmethod
    def from_params(cls, params: Mapping[str, float]) -> InputRanges:
        bounds = [
            (float(params[_RANGE_KEYS[n][0]]), float(params[_RANGE_KEYS[n][1]]))
            for n in SAMPLE_INPUTS[:-1]
        ]
        bounds.append((-SPEED_SANITY_M_S, SPEED_SANITY_M_S))
        return cls(tuple(bounds))

    def saturate(self, sample: Sample, limits: bool) -> tuple[Sample, tuple[str, ...]]:
        """The sample as the model is to get it, and the names of the inputs out of range.

        ``sample`` is (Fz [N] > 0, kappa, alpha [rad], gamma [rad], p [Pa], T [degC], Vx [m/s]).
        """
        out = list(sample)
        outside = []
        for k, (x, (lo, hi)) in enumerate(zip(sample, self.bounds, strict=True)):
            if lo <= x <= hi:
                continue
            outside.append(SAMPLE_INPUTS[k])
            if limits and k in NODE_SATURATES and not (k == 0 and x < lo):
                out[k] = min(max(x, lo), hi)
        return (out[0], out[1], out[2], out[3], out[4], out[5], out[6]), tuple(outside)
