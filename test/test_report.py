"""write_report on a real diagnosis of a real rig recording: content, plots, clobber rule."""

from __future__ import annotations

from pathlib import Path

import pytest

from tire_model_ros.diagnosis import diagnose
from tire_model_ros.diagnosis.report import effect_sentence, fmt_param, write_report
from tire_model_ros.model import TireModel
from tire_model_ros.rig import simulate_session
from tire_model_ros.wheel.params import default_tir_path

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def diagnosed():
    """A short lateral-sweep session, heating with no temperature topic, diagnosed for real."""
    tir = default_tir_path()
    assert tir, "config/default.tir must be found"
    wheels, _truth = simulate_session(
        tir, "lateral_sweeps", effects={"heating": True}, omit=["temperature"], seed=5
    )
    diag = diagnose(wheels, TireModel.from_file(tir))
    return diag, wheels


def _png_ok(path: Path) -> bool:
    data = path.read_bytes()
    return len(data) > 2000 and data[:8] == PNG_MAGIC


def test_report_has_every_effect_table_and_plots(diagnosed, tmp_path):
    diag, wheels = diagnosed
    out = tmp_path / "rep"
    md_path = write_report(diag, wheels, out, source="session")
    assert md_path == out.absolute() / "report.md"
    md = md_path.read_text()
    assert diag.effects, "a diagnosis always lists at least one effect (or none)"
    for e in diag.effects:
        assert f"**{e.name}**" in md
        for k in e.parameters:  # each fitted parameter is printed with its value
            assert k in md
        if e.where:
            assert e.where.strip().rstrip(".")[:40] in md
    # The fit table: one row per channel of the diagnosis, with the held-out figures.
    for ch, block in diag.fit["heldout_baseline"].items():
        row = next(line for line in md.splitlines() if line.startswith(f"| {ch} ["))
        if block.get("rmse") is not None:
            assert f"{block['rmse']:.3g}"[:3] in row.replace(",", "")
    prefix = wheels[0].prefix
    slug = prefix.strip("/").replace("/", "_")
    for name in ("residual_time", "residual_slip", "fit"):
        png = out / f"{name}_{slug}.png"
        assert _png_ok(png), png
        assert png.name in md  # the report links it
    inferred = out / f"inferred_{slug}.png"
    has_T = "T" in (diag.inferred.get(prefix) or {})
    assert inferred.exists() == has_T  # the inferred temperature is plotted exactly when inferred
    if has_T:
        assert _png_ok(inferred)
    # Nothing else left beside the report dir (temp dirs renamed or removed).
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rep"]


def test_refuses_to_clobber_unless_asked(diagnosed, tmp_path):
    diag, wheels = diagnosed
    out = tmp_path / "rep"
    out.mkdir()
    keep = out / "notes.txt"
    keep.write_text("an engineer's notes")
    with pytest.raises(FileExistsError, match="not empty"):
        write_report(diag, wheels, out)
    assert keep.read_text() == "an engineer's notes"  # untouched
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rep"]  # no temp dir left behind

    write_report(diag, wheels, out, overwrite=True)  # replaces the directory as a whole
    assert not keep.exists()
    assert (out / "report.md").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rep"]


def test_empty_dir_is_used_and_file_target_refused(diagnosed, tmp_path):
    diag, wheels = diagnosed
    empty = tmp_path / "empty"
    empty.mkdir()
    assert write_report(diag, wheels, empty).is_file()
    a_file = tmp_path / "file"
    a_file.write_text("x")
    with pytest.raises(FileExistsError, match="not a directory"):
        write_report(diag, {w.prefix: w for w in wheels}, a_file, overwrite=True)
    assert a_file.read_text() == "x"


def test_parameter_and_sentence_formatting():
    assert fmt_param("TTY3", -0.12345, 0.0123) == "TTY3 = -0.123 ± 0.012"
    assert fmt_param("tau_s", 0.02, None) == "tau_s = 0.0200"
    assert fmt_param("x", 12345.6, 250.0) == "x = 12346 ± 250"

    class E:  # the Effect shape: attributes only
        name, concealed, channel = "temperature", True, "Fy"
        where, evidence = "t = 10-90 s, above 4 deg", "beats a time trend on held-out sweeps."
        parameters, uncertainty = {"TTY3": -0.2}, {"TTY3": 0.05}

    text = effect_sentence(E())
    assert text.startswith("**temperature** (concealed")
    assert "TTY3 = -0.200 ± 0.050" in text and "where: t = 10-90 s" in text
    assert "\n   - evidence: beats a time trend" in text


def test_a_worse_final_heldout_is_said_in_words():
    """An improved model that predicts a channel worse on the final held-out sweeps (which
    chose nothing) gets a warning naming the channel and both figures; within 5 %, none."""
    from tire_model_ros.diagnosis.report import heldout_warnings

    def fit(before: float, after: float) -> dict:
        return {"heldout_baseline": {"Fx": {"rmse": 13.6}, "Fy": {"rmse": before}},
                "heldout_improved": {"Fx": {"rmse": 13.6}, "Fy": {"rmse": after}}}  # fmt: skip

    (warning,) = heldout_warnings(fit(32.0, 55.0))
    assert "Fy worse" in warning and "32.0" in warning and "55.0" in warning
    assert heldout_warnings(fit(32.0, 33.0)) == []
    assert heldout_warnings({"heldout_baseline": {}}) == []


def test_look_alikes_are_said_from_a_diagnosis_or_its_json():
    """The words a recording does not tell from the named effects read the same from the
    diagnosis' dict and from its JSON list, strongest first as given, each with what would
    tell it from the named (and what would show the named); none: no paragraph."""
    from tire_model_ros.diagnosis.report import look_alike_lines, look_alike_summary
    from tire_model_ros.vocabulary import EFFECT_WORDS, TOLD_APART_BY

    as_dict = look_alike_lines({"time_delay": 0.884, "temperature": 0.146}, ["relaxation"])
    as_json = look_alike_lines(
        [
            {"name": "time_delay", "explained_alone": 0.884},
            {"name": "temperature", "explained_alone": 0.146},
        ],
        ["relaxation"],
    )
    assert as_dict == as_json
    text = "\n".join(as_dict)
    assert "`time_delay` (88% of" in text and text.index("time_delay") < text.index("temperature")
    assert as_dict[-3:] == [
        f"- `time_delay`: {TOLD_APART_BY['time_delay']}.",
        f"- `temperature`: {TOLD_APART_BY['temperature']}.",
        f"- `relaxation` (named): {TOLD_APART_BY['relaxation']}.",
    ]
    assert look_alike_lines({}) == look_alike_lines([]) == [] and look_alike_summary({}) == ""
    # a hand-edited JSON entry without its share still names the word, without a number
    assert "Look-alikes: `drift`. Each" in "\n".join(look_alike_lines([{"name": "drift"}]))
    assert look_alike_summary({"time_delay": 0.884}).endswith(": time_delay (88% alone)")
    # every word for a physics says what shows it
    assert set(TOLD_APART_BY) == set(EFFECT_WORDS) - {"none"}
