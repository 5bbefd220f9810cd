"""Mismatch diagnosis: locate, name and model the physics that a Magic Formula fit leaves out."""

from .core import Diagnosis, Effect, diagnose

__all__ = ["Diagnosis", "Effect", "diagnose"]
