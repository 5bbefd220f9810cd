"""Aligned per-wheel sample arrays: the one shape that flows from a recording to the model.

Every array is 1-D float64 of the same length (one entry per ``slip`` message). Optional
channels that were not recorded are ``None`` (never filled with NaN), so a consumer can tell
"not recorded" from "recorded as nominal".
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np


@dataclass
class WheelSeries:
    """One wheel's samples aligned on its ``slip`` stamps.

    Attributes
    ----------
    prefix : str
        Topic namespace of the wheel, e.g. ``/rig/wheel``.
    t : ndarray
        Slip ``header.stamp`` [s] (seconds since the epoch of the recording clock).
    kappa, alpha, gamma : ndarray
        Longitudinal slip ratio [-], slip angle [rad], inclination [rad] (``P/slip``).
    Fz : ndarray
        Vertical load [N], positive in compression (``P/load`` force.z).
    p : ndarray or None
        Inflation pressure, gauge [Pa] (``P/pressure``).
    T : ndarray or None
        Tyre tread temperature [degC] (``P/temperature``).
    Vx : ndarray or None
        Forward speed of the wheel centre [m/s] (``P/velocity`` linear.x).
    Fx, Fy, Mx, My, Mz : ndarray or None
        Measured forces [N] and moments [N m] (``P/measured_forces``), ISO-W axes.
    """

    prefix: str
    t: np.ndarray
    kappa: np.ndarray
    alpha: np.ndarray
    gamma: np.ndarray
    Fz: np.ndarray
    p: np.ndarray | None = None
    T: np.ndarray | None = None
    Vx: np.ndarray | None = None
    Fx: np.ndarray | None = None
    Fy: np.ndarray | None = None
    Fz_meas: np.ndarray | None = None
    Mx: np.ndarray | None = None
    My: np.ndarray | None = None
    Mz: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.t)
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None or f.name in ("prefix", "meta"):
                continue
            arr = np.asarray(value, dtype=np.float64)
            if arr.shape != (n,):
                raise ValueError(
                    f"{self.prefix}: channel {f.name} has shape {arr.shape}, expected ({n},)"
                )
            setattr(self, f.name, arr)

    def __len__(self) -> int:
        return len(self.t)

    def select(self, mask: np.ndarray) -> WheelSeries:
        """The samples where ``mask`` is true (a boolean mask or an index array).

        Per-sample arrays in ``meta`` (same length as ``t``, e.g. exact ``t_ns`` stamps) are
        selected too; other metadata is copied as is.
        """
        n = len(self)
        kwargs = {}
        for f in fields(self):
            value = getattr(self, f.name)
            kwargs[f.name] = value[mask] if isinstance(value, np.ndarray) else value
        kwargs["meta"] = {
            k: v[mask] if isinstance(v, np.ndarray) and v.shape[:1] == (n,) else v
            for k, v in self.meta.items()
        }
        return WheelSeries(**kwargs)
