"""The Magic Formula tyre model and .tir property files (pure numpy/numba, no ROS import)."""

from .mf import MFOutput, TireModel
from .tir import TirData, TirError, read_tir, write_tir

__all__ = ["MFOutput", "TirData", "TirError", "TireModel", "read_tir", "write_tir"]
