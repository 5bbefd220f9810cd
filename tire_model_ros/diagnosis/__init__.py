"""Mismatch diagnosis: locate, name and model the physics that a Magic Formula fit leaves out.

prepare (a recorded wheel -> inputs, drivers, whole sweeps, folds) -> search (the engine:
forward selection over the library of effect models in ``effects/``, on held-out sweeps, with
the evidence tests of ``evidence``) -> result (the improved model refitted, the figures on the
final held-out sweeps, the words) -> summary (per wheel, and across the wheels of a car).
"""

from .result import Effect, WheelDiagnosis
from .summary import Diagnosis, diagnose

__all__ = ["Diagnosis", "Effect", "WheelDiagnosis", "diagnose"]
