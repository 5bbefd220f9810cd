"""The fit report as an engineer reads it: every axis named with its unit, measured against
model per condition (the levels found in the data), residuals measured - model, and a fit whose
start model already explains the data written with a note (exit 0) instead of refused."""

from __future__ import annotations

import dataclasses
import os
import re
import subprocess

import numpy as np
import pytest
from conftest import DEFAULT_TIR, TOOL

from tire_model_ros.fit import FitOptions, fit_recording
from tire_model_ros.fit.report import figures, fit_metrics, markdown
from tire_model_ros.model import TireModel
from tire_model_ros.rig import simulate_session, write_session

TIR = DEFAULT_TIR


@pytest.fixture(scope="module")
def heated():
    """A short TTC-style cornering run of a heating tyre, fitted from the plain file."""
    wheels, _ = simulate_session(
        TIR, "ttc_cornering", effects=["heating"], rate_hz=25.0, seed=2,
        programme_options={"rate_scale": 2.0, "vary_pressure": False},
    )  # fmt: skip
    start = TireModel.from_file(TIR)
    return fit_recording(wheels, start, FitOptions(progress=False, stages=["Fy0", "Mz0"]))


def test_every_axis_has_its_unit(heated):
    import matplotlib.pyplot as plt

    figs = figures(heated)
    assert {"fit_Fy.png", "fit_Mz.png", "fit_sweeps.png", "fit_residual_time.png"} <= set(figs)
    for name, fig in figs.items():
        drawn = [ax for ax in fig.axes if ax.axison]
        if not drawn:  # nothing to draw (a cornering run has no slip-ratio sweep): said so
            assert any("no " in t.get_text() for ax in fig.axes for t in ax.texts), name
        for ax in drawn:
            for label in (ax.get_xlabel(), ax.get_ylabel()):
                assert "[" in label and label.endswith("]"), (name, label)
        plt.close(fig)


def test_measured_against_model_per_condition(heated):
    import matplotlib.pyplot as plt

    fig = figures(heated)["fit_Fy.png"]
    titles = sorted(ax.get_title().split("\n") for ax in fig.axes if ax.axison)
    # one panel per inclination block (one pressure), one curve per load level
    assert [t[0] for t in titles] == [f"p 260 kPa, gamma {g} deg" for g in ("0.0", "2.0", "4.0")]
    for t in titles:  # each panel's own figure: the fit improves every condition
        m = re.fullmatch(r"Fy rmse ([\d.e+]+) -> ([\d.e+]+) N \(start -> fitted\)", t[1])
        assert m and float(m[2]) < float(m[1]), t
    for ax in fig.axes:
        if ax.axison:
            labels = [t.get_text() for t in ax.get_legend().get_texts()]
            assert len(labels) == 4 and all(
                t.startswith("Fz ") and t.endswith(" N") for t in labels
            )
    plt.close("all")
    by = heated.report["metrics"]["by_condition"]
    assert [round(r["level"], 1) for r in by["inclination"]] == [0.0, 2.0, 4.0]
    assert {r["unit"] for r in by["inclination"]} == {"deg"}


def test_a_channel_not_measured_has_no_rows_or_panels(heated):
    """A bag imported from a TTC file carries My as NaN (the TTC measures none): the report
    leaves it out instead of drawing an empty panel; levels at the tables' resolution."""
    import matplotlib.pyplot as plt

    wheels = [dataclasses.replace(s, My=np.full(len(s), np.nan)) for s in heated.wheels]
    result = dataclasses.replace(heated, wheels=wheels, report=dict(heated.report))
    result.report["metrics"] = fit_metrics(result)
    assert "My" not in result.report["metrics"]["channels"], result.report["metrics"]["channels"]
    figs = figures(result)
    assert "fit_My.png" not in figs
    residual = figs["fit_residual_time.png"]
    assert [ax.get_ylabel().split()[0] for ax in residual.axes] == ["Fx", "Fy", "Mx", "Mz"]
    plt.close("all")
    text = markdown(result)
    assert "| My |" not in text and "My [N m]" not in text
    for g in ("0.00", "2.00", "4.00"):
        assert f"| {g} deg | Fy |" in text, text


def test_residuals_are_measured_minus_model(heated):
    s = heated.wheels[0]
    m = heated.train_masks[0]
    model = heated.start_model
    out = model.evaluate(s.Fz[m], s.kappa[m], s.alpha[m], s.gamma[m], s.Vx[m], s.p[m], s.T[m])
    bias = float(np.mean(s.Fy[m] - out.Fy))
    rep = heated.report["metrics"]["overall"]["fitted"]["before"]["Fy"]
    assert rep["bias"] == pytest.approx(bias, rel=1e-9)
    assert abs(bias) > 1.0  # the heated tyre's grip differs: a sign that could be wrong


def test_start_model_that_explains_the_data_is_written_with_a_note(tmp_path):
    wheels, info = simulate_session(
        TIR, "lateral_sweeps", rate_hz=25.0, seed=4, omit=["temperature"],
        programme_options={"rate_scale": 2.0},
    )  # fmt: skip
    write_session(tmp_path / "same", wheels, info)
    r = subprocess.run(
        [*TOOL, "fit", "same", "--tir", str(TIR), "-o", "out.tir", "--stages", "Fy0"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
        env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"},
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "note: no stage improved on the start model" in r.stdout
    text = (tmp_path / "out.tir").read_text()
    assert "! tire-model fit: no stage improved" in text
    got, want = TireModel.from_file(tmp_path / "out.tir").params, TireModel.from_file(TIR).params
    assert all(got[k] == want[k] for k in ("PDY1", "PKY1", "PEY1", "PCY1"))
    report = (tmp_path / "out_fit_report" / "fit_report.md").read_text()
    assert "**Note:** no stage improved" in report


def test_fit_and_diagnosis_share_the_residual_sign():
    """Measured Fy 300 N above the model: +300 in the fit report's bias and in the diagnosis'
    residual at zero slip (measured - model in both)."""
    from tire_model_ros.diagnosis import diagnose

    wheels, _ = simulate_session(
        TIR, "lateral_sweeps", rate_hz=25.0, seed=4, omit=["temperature"],
        programme_options={"rate_scale": 2.0},
    )  # fmt: skip
    wheels = [dataclasses.replace(s, Fy=s.Fy + 300.0) for s in wheels]
    start = TireModel.from_file(TIR)
    fit = fit_recording(wheels, start, FitOptions(progress=False, stages=["Fy0"]))
    assert fit.report["metrics"]["overall"]["fitted"]["before"]["Fy"]["bias"] == pytest.approx(
        300.0, abs=30.0
    )
    diag = diagnose(wheels, start)
    summary = diag.wheels[wheels[0].prefix].summary["Fy"]
    assert summary["zero_slip_mean"] == pytest.approx(300.0, abs=30.0), summary
