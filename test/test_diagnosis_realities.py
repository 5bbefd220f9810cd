"""The diagnosis on recordings of an independent generator (``realities/flattrac``, written
blind from PHYSICS.md and a spec in words; the proof's other generators are kept for
``make proof``): concealed heating below and above the grip optimum, a concealed pressure, a
null with real-world imperfections, a two-effect recording. Real bags, the real command line."""

from __future__ import annotations

import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from conftest import ROOT, TOOL

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]  # the module fixture runs all

MINUTES = "6"  # shorter than the proof's 8 minutes; long enough for the heating to show


def _generate(case: str, seed: int, out: Path) -> Path:
    cmd = [sys.executable, "-m", "realities.flattrac", "--case", case, "--seed", str(seed)]
    subprocess.run([*cmd, "-o", str(out), "--minutes", MINUTES, "--quiet"], cwd=ROOT,
                   check=True, capture_output=True, timeout=600)  # fmt: skip
    return out


def _diagnose(d: Path) -> dict:
    out = d / "diagnosis.json"
    subprocess.run([*TOOL, "diagnose", str(d / "recording"), "--tir", str(d / "model.tir"),
                    "--json", str(out)], check=True, capture_output=True, timeout=1200)  # fmt: skip
    return json.loads(out.read_text())


# Longest first (CPU seconds of their diagnosis here: 52, 49, 39, 21, 8), so that the two
# workers end together.
CASES = ("multi2_b", "heat_above", "heat_below", "pressure_sealed", "null_6")


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, tuple[Path, dict]]:
    """Every case generated and diagnosed once, two at a time (each a real subprocess on its
    own core): case -> (its folder, the diagnosis JSON)."""
    base = tmp_path_factory.mktemp("realities")

    def one(case: str) -> tuple[Path, dict]:
        d = _generate(case, 1, base / case)
        return d, _diagnose(d)

    with ThreadPoolExecutor(max_workers=2) as pool:
        return dict(zip(CASES, pool.map(one, CASES), strict=True))


def _rss(fit: dict, block: str) -> float:
    return sum(fit[block][c]["rmse"] ** 2 for c in ("Fx", "Fy")) ** 0.5


@pytest.mark.parametrize(
    ("case", "truth", "heldout_ratio"),
    [
        # The final held-out fold of this 6-minute session is 12 % of it, mostly short low-slip
        # blocks (its heated sweeps run at a rare camber or pressure and stay in the selection
        # folds): the heating explains 74 % on the selection folds, 3 % there. Not worse, then.
        ("heat_below", ["temperature"], 1.0),
        ("heat_above", ["temperature"], 0.7),
        ("pressure_sealed", ["pressure"], 0.9),
    ],
)
def test_concealed_effect_is_named_first_and_lowers_heldout_error(runs, case, truth, heldout_ratio):
    _, doc = runs[case]
    named = [e["name"] for e in doc["effects"]]
    assert named[0] == truth[0], named
    assert doc["effects"][0]["concealed"] is True
    assert 0.3 <= doc["effects"][0]["explained"] <= 1.0
    before, after = _rss(doc["fit"], "heldout_baseline"), _rss(doc["fit"], "heldout_improved")
    assert after <= heldout_ratio * before, (after, before)


def test_null_with_imperfections_names_nothing(runs):
    """Gain error, spikes, dropouts and a wandering zero together: none of it is physics."""
    _, doc = runs["null_6"]
    assert [e["name"] for e in doc["effects"]] == ["none"]


def test_two_effects_are_both_named_strongest_first(runs):
    d, doc = runs["multi2_b"]
    truth = [e["name"] for e in json.loads((d / "truth.json").read_text())["effects"]]
    named = [e["name"] for e in doc["effects"]]
    assert set(truth) <= set(named), (truth, named)
    assert named[0] == truth[0]
    shares = [e["explained"] for e in doc["effects"]]
    assert shares == sorted(shares, reverse=True)  # strongest first (INTERFACE.md)
