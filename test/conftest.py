"""Shared test set-up: where the project and the reference data are, and the model fixtures.

The reference data (MFeval oracles and the reference .tir files) are the ``reference`` folder
of the ``shared`` checkout beside the project root (``../shared/reference``). Without it, the
tests that need it are skipped with a message saying where it was looked for; there is no
other place it is looked for.

Test modules import the paths from here (``from conftest import MF61_TIR``) where they need
them at import time (parametrisation, module marks).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from tire_model_ros.model import TireModel

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT.parent / "shared" / "reference"
TIR_DIR = REFERENCE / "tir"
MFEVAL_DIR = REFERENCE / "mfeval"
MF61_TIR = TIR_DIR / "MagicFormula61_Parameters.tir"
DEFAULT_TIR = ROOT / "config" / "default.tir"
_SCRIPT = Path(sys.executable).with_name("tire-model")
#: The ``tire-model`` command of this environment (its console script, else ``python -m``).
TOOL = [str(_SCRIPT)] if _SCRIPT.is_file() else [sys.executable, "-m", "tire_model_ros.cli"]

REFERENCE_MISSING = (
    f"reference data not found: {REFERENCE} (check out the shared folder, with its reference/, "
    f"beside the project root {ROOT})"
)
#: Mark for a test module or test that reads ``../shared/reference``.
requires_reference = pytest.mark.skipif(not MF61_TIR.is_file(), reason=REFERENCE_MISSING)


def pytest_report_header() -> str:
    found = "found" if MF61_TIR.is_file() else "MISSING: tests that need it are skipped"
    return f"reference data: {REFERENCE} ({found})"


@pytest.fixture(scope="session")
def reference_dir() -> Path:
    """``../shared/reference``; skips the test with the place looked at when it is absent."""
    if not MF61_TIR.is_file():
        pytest.skip(REFERENCE_MISSING)
    return REFERENCE


@pytest.fixture(scope="session")
def model(reference_dir: Path) -> TireModel:
    """The MF 6.1 reference tyre (``MagicFormula61_Parameters.tir``; immutable, so shared)."""
    return TireModel.from_file(reference_dir / "tir" / MF61_TIR.name)
