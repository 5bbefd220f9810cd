"""The library of effect models the selection engine loops over (one class per model).

Adding a physics is adding a class here; the engine never names one.
"""

from __future__ import annotations

from ..prepare import Context
from .base import EffectModel, Param
from .baseline import Scaling
from .friction import FrictionStep, SpeedLaw, SpeedTable, Trend, Wear
from .pressure import PressureTrend, RecordedPressure, SealedGas
from .sidewall import SidewallContact
from .static import Camber, CombinedSlip, Offset
from .thermal import HiddenThermal, RecordedThermal
from .transient import Delay, Relaxation

LIBRARY: tuple[type[EffectModel], ...] = (
    RecordedThermal,
    HiddenThermal,
    RecordedPressure,
    SealedGas,
    PressureTrend,
    Relaxation,
    Delay,
    Offset,
    Camber,
    CombinedSlip,
    SidewallContact,
    SpeedLaw,
    SpeedTable,
    Wear,
    Trend,
    FrictionStep,
)


def candidates(ctx: Context) -> list[EffectModel]:
    """Every model of the library that this recording can tell anything about."""
    return [m for cls in LIBRARY for m in cls.propose(ctx)]


__all__ = ["LIBRARY", "EffectModel", "Param", "Scaling", "candidates"]
