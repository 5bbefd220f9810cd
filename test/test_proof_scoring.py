"""The proof's scoring (bench/proof.py): what counts as named first, halved, near the floor,
and the pooled totals of several seeds."""

from __future__ import annotations

import importlib.util
import json
import math
import sys
from dataclasses import asdict
from pathlib import Path
from types import ModuleType

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "proof.py"


@pytest.fixture(scope="module")
def proof() -> ModuleType:
    spec = importlib.util.spec_from_file_location("proof_under_test", BENCH)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses resolve their module
    spec.loader.exec_module(mod)
    return mod


def _outcome(proof: ModuleType, **kw: object) -> object:
    base = dict(generator="brush", case="heat_below", seed=7, truth=["temperature"], sizes=[4.0])
    base.update(named=["temperature"], before=40.0, after=19.0, floor=18.0)
    base.update(kw)
    return proof.Outcome(**base)


def test_halved_and_the_excess_over_the_floor(proof: ModuleType) -> None:
    o = _outcome(proof)
    assert o.first_right and o.attainable and o.halved
    # 1 - (19^2 - 18^2) / (40^2 - 18^2)
    assert o.excess_removed == pytest.approx(1 - 37 / 1276)
    near = _outcome(proof, after=20.2)  # 0.505 of before: not halved, yet near the floor
    assert not near.halved and near.excess_removed > 0.9
    null = _outcome(proof, truth=[], sizes=[], named=["none"])
    assert null.first_right and null.halved is None and math.isnan(null.excess_removed)
    wrong = _outcome(proof, named=["speed", "temperature"])
    assert not wrong.first_right and wrong.found == 1 and wrong.extra == ["speed"]


def test_totals_report_the_median_and_least_excess_removed(proof: ModuleType) -> None:
    outs = [_outcome(proof, after=a) for a in (19.0, 20.2, 30.0)]
    tot = proof.totals(outs)
    assert tot["halved_where_floor_allows"] == "1/3"
    assert tot["excess_over_floor_removed_min"] == pytest.approx(1 - (900 - 324) / 1276)
    assert tot["excess_over_floor_removed_median"] == pytest.approx(outs[1].excess_removed)


def test_wilson_interval(proof: ModuleType) -> None:
    lo, hi = proof.wilson(0, 10)
    assert lo == pytest.approx(0.0, abs=1e-12) and hi == pytest.approx(0.2775, abs=1e-3)
    lo, hi = proof.wilson(35, 36)
    assert lo < 35 / 36 < hi <= 1.0
    assert all(math.isnan(x) for x in proof.wilson(0, 0))


def test_pooled_counts_a_recording_once_from_the_last_file(
    proof: ModuleType, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def write(name: str, outs: list[object]) -> Path:
        doc = {"generators": {"brush": {"outcomes": [asdict(o) for o in outs]}}}  # type: ignore[call-overload]
        p = tmp_path / name
        p.write_text(json.dumps(doc))
        return p

    failed = _outcome(proof, truth=[], named=[], error="RuntimeError: generator failed")
    rerun = _outcome(proof)
    other = _outcome(proof, seed=8, named=["none"])
    a, b = write("a.json", [failed, other]), write("b.json", [rerun])
    assert proof.pooled([a, b]) == 0
    out = capsys.readouterr().out
    pooled = json.loads(out.split("pooled, 2 recordings: ")[1].splitlines()[0])
    assert pooled["strongest_first"] == "1/2" and pooled["errors"] == 0
    assert "strongest_first: 1/2 = 50.0%" in out
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    assert proof.pooled([bad]) == 1
    assert "not a proof.json" in capsys.readouterr().err
