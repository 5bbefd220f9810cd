"""The evaluator against the MFeval 4.3.1 oracle vectors (../shared/reference/mfeval).

Every MF61/MF62 grid of useMode 211 (plain equations, limits off) and 111 (limits on) is
compared row by row: Fx, Fy, Mz, Mx, My and the derived quantities within
max(1e-6, 1e-9 |ref|).

Not compared (see the reference README and the report):
- turn slip (useMode 212/112) and the alpha* = tan(alpha) variant (221): not modelled;
- ``iKya`` (a finite difference between rows), ``Rl`` where the oracle has Inf;
- ``omega`` and ``Cz`` on the grids where MFeval's Re/omega loop ran a third pass: MFeval
  stops that loop on a test over the whole batch, so the number of passes depends on which rows
  were evaluated together. We always do the two passes MFeval does on most grids; Re itself
  agrees within the tolerance on every grid (checked), omega and Cz = Fz/rho are far more
  sensitive. They are compared on the grids where the pass count is two.
"""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from tire_model_ros.model import TireModel

ROOT = Path(__file__).resolve().parents[1]
REF = (ROOT / ".." / "shared" / "reference").resolve()
MFEVAL = REF / "mfeval"
TIR = {"MF61": REF / "tir" / "MagicFormula61_Parameters.tir",
       "MF62": REF / "tir" / "MagicFormula62_Parameters.tir"}  # fmt: skip

FORCES = ("Fx", "Fy", "Mz", "Mx", "My")
DERIVED = ("Kya", "Kxk", "mux", "muy", "Re", "t", "sigmax", "sigmay", "Mzr", "Rl", "rho",
           "Cx", "Cy", "two_a", "two_b")  # fmt: skip
# MFeval ran a third Re/omega pass on these grids (batch-wide stopping test, see above)
THREE_PASS_GRIDS = {"pure_lat", "combined"}


FILES = sorted(MFEVAL.glob("MF6[12]__*__mode[12]11.csv.gz")) if MFEVAL.is_dir() else []


def load_oracle(path: Path) -> dict[str, np.ndarray]:
    with gzip.open(path, "rt") as fh:
        header = fh.readline().strip().split(",")
        data = np.loadtxt(fh, delimiter=",", ndmin=2)
    return {name: data[:, k] for k, name in enumerate(header)}


@pytest.fixture(scope="module")
def models() -> dict[str, TireModel]:
    return {name: TireModel.from_file(path) for name, path in TIR.items()}


def _evaluate(models, path: Path):
    tir, grid, mode = path.name[: -len(".csv.gz")].split("__")
    ref = load_oracle(path)
    out = models[tir].evaluate(
        ref["Fz"], ref["kappa"], ref["alpha"], ref["gamma"], ref["Vx"], ref["p"],
        phit=ref["phit"], omega=ref["omega_in"], limits=(mode == "mode111"),
    )  # fmt: skip
    return grid, ref, out


def _assert_close(name: str, got: np.ndarray, ref: np.ndarray, where: str) -> None:
    finite = np.isfinite(ref)
    err = np.abs(got - ref)
    tol = np.maximum(1e-6, 1e-9 * np.abs(ref))
    bad = finite & ~(err <= tol)
    if bad.any():
        rows = np.flatnonzero(bad)
        k = rows[np.argmax(err[rows])]
        pytest.fail(
            f"{where}: {name} differs on {rows.size}/{finite.sum()} rows; worst row {k}: "
            f"got {got[k]!r}, MFeval {ref[k]!r} (|err| {err[k]:.3g}, tol {tol[k]:.3g})"
        )


@pytest.mark.skipif(not MFEVAL.is_dir(), reason=f"oracle folder {MFEVAL} missing")
@pytest.mark.parametrize("path", FILES, ids=[f.name[: -len(".csv.gz")] for f in FILES])
def test_forces_and_moments_match_mfeval(models, path: Path) -> None:
    _, ref, out = _evaluate(models, path)
    for name in FORCES:
        _assert_close(name, getattr(out, name), ref[name], path.name)
    np.testing.assert_array_equal(out.Fz, ref["Fz_out"])


@pytest.mark.skipif(not MFEVAL.is_dir(), reason=f"oracle folder {MFEVAL} missing")
@pytest.mark.parametrize("path", FILES, ids=[f.name[: -len(".csv.gz")] for f in FILES])
def test_derived_quantities_match_mfeval(models, path: Path) -> None:
    grid, ref, out = _evaluate(models, path)
    for name in DERIVED:
        _assert_close(name, getattr(out, name), ref[name], path.name)
    _assert_close("kappa_used", out.kappa_used, ref["kappa_used"], path.name)
    _assert_close("alpha_used", out.alpha_used, ref["alpha_used"], path.name)
    _assert_close("p_used", out.p_used, ref["p_used"], path.name)
    if grid not in THREE_PASS_GRIDS:
        _assert_close("omega", out.omega, ref["omega_out"], path.name)
        _assert_close("Cz", out.Cz, ref["Cz"], path.name)


def test_oracle_set_is_complete() -> None:
    """All 28 MF61/MF62 mode 111/211 files are there (a missing file would hide a failure)."""
    if not MFEVAL.is_dir():
        pytest.skip(f"oracle folder {MFEVAL} missing")
    assert len(FILES) == 28, [f.name for f in FILES]
