"""The virtual test rig: test programmes, the rig's own physics and the sample recordings.

``simulate_session(tir_or_model, programme, effects=..., omit=..., seed=...)`` returns the
recorded wheels (WheelSeries) and the truth (a JSON-ready dict).
"""

from .effects import DEFAULTS as EFFECT_DEFAULTS
from .effects import DIAGNOSIS_WORD, EFFECTS
from .programmes import PROGRAMMES
from .session import OMITTABLE, simulate_session, truth_path, write_session

__all__ = [
    "DIAGNOSIS_WORD",
    "EFFECTS",
    "EFFECT_DEFAULTS",
    "OMITTABLE",
    "PROGRAMMES",
    "simulate_session",
    "truth_path",
    "write_session",
]
