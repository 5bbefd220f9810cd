"""Refit Magic Formula coefficients from recordings (``tire-model fit``).

- :func:`split_sweeps` (``fit.sweeps``): the sweeps/segments of a wheel, the validation unit.
- :func:`fit_coefficients` (``fit.core``): bounded robust least squares of named coefficients.
- :func:`fit_recording` (``fit.stages``): the staged field fit, returning a :class:`FitResult`.
- :func:`write_fit_report` (``fit.report``): markdown, JSON and PNG report of a fit.
"""

from .core import fit_coefficients
from .report import write_fit_report
from .stages import FitOptions, FitResult, fit_recording
from .sweeps import split_sweeps

__all__ = [
    "FitOptions",
    "FitResult",
    "fit_coefficients",
    "fit_recording",
    "split_sweeps",
    "write_fit_report",
]
