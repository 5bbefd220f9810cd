"""Measurement files through fit and diagnosis: a TTC-style cornering session of a heating tyre
recorded on the virtual rig (``tire-model simulate --programme ttc_cornering``), exported as a
TTC ``.mat`` and as TYDEX (``tire-model export``), imported back: the same fit as the bag;
``fit`` on the ``.mat`` itself (imported on the fly) fits the temperature terms on TSTC; and
``import --omit temperature`` then ``diagnose`` runs end to end and names the concealed heat."""

from __future__ import annotations

import json
import os
import subprocess
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import pytest
from conftest import DEFAULT_TIR, TOOL

from tire_model_ros.fit import FitOptions, fit_recording
from tire_model_ros.model import TireModel
from tire_model_ros.recording import open_recording

TIR = DEFAULT_TIR
STAGES = ["Fy0", "Mz0", "temperature"]

pytestmark = pytest.mark.slow


def _tm(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    return subprocess.run([*TOOL, *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=900)  # fmt: skip


def _ttc_session(d: Path, options: str) -> Path:
    """The rig's TTC-style cornering run of a heating tyre as a bag, a TTC .mat and TYDEX."""
    r = _tm("simulate", "--tir", str(TIR), "--programme", f"ttc_cornering:{options}", "--rate",
            "50", "--effect", "heating", "--seed", "7", "-o", "bag", cwd=d)  # fmt: skip
    assert r.returncode == 0, r.stderr
    for name in ("run.mat", "run.tdx"):
        r = _tm("export", "bag", "-o", name, cwd=d)
        assert r.returncode == 0, r.stderr
    return d


@pytest.fixture(scope="module")
def session(tmp_path_factory) -> Path:
    return _ttc_session(tmp_path_factory.mktemp("ttc"), "rate_scale=2")


def _import_without_temperature_and_diagnose(d: Path) -> list[subprocess.CompletedProcess[str]]:
    out = [_tm("import", "run.mat", "-o", "noT", "--omit", "temperature", cwd=d)]
    if out[0].returncode == 0:
        out.append(_tm("diagnose", "noT", "--tir", str(TIR), "--json", "diag.json", cwd=d))
    return out


@pytest.fixture(scope="module", autouse=True)
def diagnosed(session) -> Iterator[Future[list[subprocess.CompletedProcess[str]]]]:
    """``import --omit temperature`` then ``diagnose``, started with the module: they run
    beside the tests before the one that reads them."""
    with ThreadPoolExecutor(1) as pool:
        yield pool.submit(_import_without_temperature_and_diagnose, session)


def _fit(path: Path):
    wheels = list(open_recording(path, say=lambda _line: None).values())
    return fit_recording(
        wheels, TireModel.from_file(TIR), FitOptions(progress=False, stages=STAGES)
    )


def test_exported_and_imported_back_gives_the_same_fit(session):
    want = _fit(session / "bag")
    fitted = [st["stage"] for st in want.report["stages"] if st["status"] == "fitted"]
    assert "Fy0" in fitted and want.report["changed"]
    for name in ("run.mat", "run.tdx"):
        got = _fit(session / name)
        assert got.report["n_samples"] == want.report["n_samples"]
        assert set(got.report["changed"]) == set(want.report["changed"]), name
        for k, (_, value) in want.report["changed"].items():
            assert got.model.params[k] == pytest.approx(value, rel=1e-4, abs=1e-9), (name, k)
        a = want.report["metrics"]["overall"]["heldout"]["after"]
        b = got.report["metrics"]["overall"]["heldout"]["after"]
        for c in ("Fy", "Mz"):
            assert b[c]["rmse"] == pytest.approx(a[c]["rmse"], rel=1e-5), (name, c)


def test_fit_on_the_ttc_file_uses_tstc(session):
    r = _tm("fit", "run.mat", "--tir", str(TIR), "-o", "fit.tir", "--stages", "Fy0,temperature",
            cwd=session)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "import: read run.mat (ttc)" in r.stderr and "T<-TSTC" in r.stderr
    rep = json.loads((session / "fit_fit_report" / "fit_report.json").read_text())
    assert rep["conditions"]["temperature_recorded"] and rep["conditions"]["temperature_varies"]
    stages = {st["stage"]: st for st in rep["stages"]}
    assert stages["temperature"]["status"] in ("fitted", "not significant"), stages["temperature"]
    assert {"TTY1", "TTY3"} <= set(stages["Fy0"]["names"])
    assert {"TTY1", "TTY3"} <= set(rep["changed"])  # fitted on the TSTC channel
    # the report per condition: the levels found in the data, in the report's units
    by = rep["metrics"]["by_condition"]
    assert len(by["load"]) == 4 and len(by["inclination"]) == 3 and len(by["pressure"]) == 3
    assert {row["unit"] for row in by["pressure"]} == {"kPa"}


def test_import_without_temperature_then_diagnose(session, diagnosed):
    runs = diagnosed.result(timeout=1800)
    assert runs[0].returncode == 0, runs[0].stderr
    assert "left out (--omit): T" in runs[0].stdout
    assert runs[1].returncode == 0, runs[1].stderr
    diag = json.loads((session / "diag.json").read_text())
    first = diag["effects"][0]
    assert first["name"] == "temperature" and first["concealed"], diag["effects"]
    held = diag["fit"]
    assert held["heldout_improved"]["Fy"]["rmse"] < 0.6 * held["heldout_baseline"]["Fy"]["rmse"]
