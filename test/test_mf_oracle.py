"""The evaluator against the MFeval 4.3.1 oracle vectors (../shared/reference/mfeval).

Every MF61/MF62 grid of useMode 211 (plain equations, limits off) and 111 (limits on), the turn
slip grids of useMode 212 and 112 and the alpha* = tan(alpha), gamma* = sin(gamma) grids of
221 (pure_lat) are compared row by row: Fx, Fy, Mz, Mx, My and the derived quantities within
max(1e-6, 1e-9 |ref|). The useMode digits map to ``limits``, ``alpha_star``, ``turn_slip``.

Not compared (see the reference README and the report):
- ``iKya`` (a finite difference between rows), ``Rl`` where the oracle has Inf;
- turn-slip ``Mz``, ``Mzr`` where phit = 0: MFeval's zeta7 is 0/0 there (NaN); only the finite
  reference values are compared (the evaluator returns the limit phit -> 0);
- ``omega`` and ``Cz`` on the grids where MFeval's Re/omega loop ran a third pass: MFeval
  stops that loop on a test over the whole batch, so the number of passes depends on which rows
  were evaluated together. We do the two passes MFeval does on most grids (with turn slip:
  per sample until Re changes by at most 1e-9, MFeval's test on one sample, which gives the
  four passes of the turnslip grids); Re itself agrees within the tolerance on every grid
  (checked), omega and Cz = Fz/rho are far more sensitive. They are compared on the grids where
  the pass count agrees (all but pure_lat and combined).
"""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest
from conftest import MF61_TIR, MFEVAL_DIR, TIR_DIR

from tire_model_ros.model import TireModel

MFEVAL = MFEVAL_DIR
TIR = {"MF61": MF61_TIR, "MF62": TIR_DIR / "MagicFormula62_Parameters.tir"}

FORCES = ("Fx", "Fy", "Mz", "Mx", "My")
DERIVED = ("Kya", "Kxk", "mux", "muy", "Re", "t", "sigmax", "sigmay", "Mzr", "Rl", "rho",
           "Cx", "Cy", "two_a", "two_b")  # fmt: skip
# MFeval ran a third Re/omega pass on these grids (batch-wide stopping test, see above)
THREE_PASS_GRIDS = {"pure_lat", "combined"}


FILES = sorted(MFEVAL.glob("MF6[12]__*__mode[12][12][12].csv.gz")) if MFEVAL.is_dir() else []


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
    hundreds, tens, units = mode[len("mode") :]  # MFeval's useMode digits
    ref = load_oracle(path)
    out = models[tir].evaluate(
        ref["Fz"], ref["kappa"], ref["alpha"], ref["gamma"], ref["Vx"], ref["p"],
        phit=ref["phit"], omega=ref["omega_in"], limits=(hundreds == "1"),
        alpha_star=(tens == "2"), turn_slip=(units == "2"),
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
    """All 34 oracle files are there (a missing file would hide a failure): 28 of useMode
    111/211, 4 turn-slip (112/212) and 2 alpha* (221)."""
    if not MFEVAL.is_dir():
        pytest.skip(f"oracle folder {MFEVAL} missing")
    assert len(FILES) == 34, [f.name for f in FILES]
    variants = sorted(f.name for f in FILES if not f.name.endswith("11.csv.gz"))
    assert variants == [
        f"{t}__{g}__mode{m}.csv.gz"
        for t in ("MF61", "MF62")
        for g, m in (("pure_lat", 221), ("turnslip", 112), ("turnslip", 212))
    ]
