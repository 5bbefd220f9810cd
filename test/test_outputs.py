"""Outputs written whole or not at all: ``atomic.OutputSet`` and ``tire-model fit -o``.

A real process is killed with SIGKILL at every file-system step of its output (a driver wraps
``os.mkdir/link/replace/rename/unlink/rmdir/chmod`` and kills itself before the K-th call on a
path under the output folder), and at moments seen from outside; what it leaves must be nothing
or everything (or, inside the commit, the .tir before its report with the journal that the
next run finishes), and the next run must recover from it.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import MF61_TIR, TOOL

from tire_model_ros.atomic import JOURNAL, OutputSet

REPORT = {"r.md": "report\n", "r.json": "{}\n", "p.png": "png\n"}

# Run as: python driver.py ROOT MODE ARG PAYLOAD...; MODE "log" writes ROOT/calls.log, "nth"
# kills before the ARG-th call, "before" before the first call NAME on a path ending in SUFFIX
# (ARG = "NAME:SUFFIX"). PAYLOAD: "demo" (a .tir and a report folder) or a tire-model command.
DRIVER = r"""
import os, signal, sys
from pathlib import Path

root, mode, arg, payload = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
log = open(os.path.join(root, "calls.log"), "w") if mode == "log" else None
count = 0


def wrap(name, fn):
    def inner(*args, **kwargs):
        global count
        paths = [os.fspath(a) for a in args[:2] if isinstance(a, (str, os.PathLike))]
        if paths and os.path.abspath(paths[0]).startswith(root):
            count += 1
            call = " ".join([name, *paths])
            if log:
                log.write(f"{call}\n")
                log.flush()
            target = arg.split(":", 1)
            if (mode == "nth" and count == int(arg)) or (
                mode == "before" and name == target[0] and paths[0].endswith(target[-1])
            ):
                os.kill(os.getpid(), signal.SIGKILL)
        return fn(*args, **kwargs)
    return inner


for name in ("mkdir", "link", "replace", "rename", "unlink", "rmdir", "chmod"):
    setattr(os, name, wrap(name, getattr(os, name)))

if payload[0] == "fit":
    from tire_model_ros.cli import main
    sys.exit(main(payload))

from tire_model_ros.atomic import OutputSet, write_atomic

tir, report = Path(root) / "out.tir", Path(root) / "out_report"
outputs = OutputSet([tir, report])
for note in outputs.recover():
    print(note)
with outputs:
    write_atomic(outputs.path(tir), "tir\n")
    staged = outputs.path(report)
    staged.mkdir()
    for name, text in REPORT_ITEMS.items():
        write_atomic(staged / name, text)
    outputs.commit()
""".replace("REPORT_ITEMS", repr(REPORT))


def _driver(tmp_path: Path) -> Path:
    path = tmp_path / "driver.py"
    if not path.exists():
        path.write_text(DRIVER)
    return path


def _run(driver: Path, root: Path, mode: str, arg: str, *payload: str, timeout: float = 300):
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "MPLBACKEND": "Agg"}
    return subprocess.run(
        [sys.executable, str(driver), str(root), mode, arg, *payload],
        capture_output=True, text=True, timeout=timeout, env=env, cwd=root,
    )  # fmt: skip


def _state(tir: Path, report: Path, names: set[str], keep: set[str]) -> str:
    """'nothing', 'everything', or 'committing' (the .tir, part of its report, the journal)."""
    have = {p.name for p in report.iterdir()} - keep if report.is_dir() else set()
    staging = tir.parent / f".{tir.name}.partial"
    assert have <= names, have
    if not tir.exists():
        assert not have, f"a report without its .tir: {sorted(have)}"
        return "nothing"
    if have == names:
        return "everything"
    assert (staging / JOURNAL).exists(), f".tir and {sorted(have)} without a journal"
    return "committing"


def _fresh(root: Path, existing_report_folder: bool) -> set[str]:
    """An output folder; with a report folder of the user's that must keep its file."""
    root.mkdir()
    if not existing_report_folder:
        return set()
    (root / "out_report").mkdir()
    (root / "out_report" / "keep.txt").write_text("mine")
    return {"keep.txt"}


@pytest.mark.parametrize("existing_report_folder", [False, True])
def test_output_set_killed_at_every_step(tmp_path, existing_report_folder):
    driver = _driver(tmp_path)
    _fresh(tmp_path / "base", existing_report_folder)
    assert _run(driver, tmp_path / "base", "log", "0", "demo").returncode == 0
    calls = (tmp_path / "base" / "calls.log").read_text().splitlines()
    assert any(c.startswith("link ") and c.endswith(f"/{JOURNAL}") for c in calls)
    seen = set()
    for k in range(1, len(calls) + 1):
        root = tmp_path / f"k{k}"
        keep = _fresh(root, existing_report_folder)
        tir, report = root / "out.tir", root / "out_report"
        res = _run(driver, root, "nth", str(k), "demo")
        assert res.returncode == -signal.SIGKILL, (k, calls[k - 1], res.stderr)
        state = _state(tir, report, set(REPORT), keep)
        seen.add(state)
        notes = OutputSet([tir, report]).recover()  # what the next run does first
        after = _state(tir, report, set(REPORT), keep)
        assert after in ("nothing", "everything"), (k, calls[k - 1], after)
        assert not (root / ".out.tir.partial").exists()
        if state == "committing":
            assert after == "everything" and "finished the output" in notes[0]
        if after == "everything":
            assert tir.read_text() == "tir\n"
            assert all((report / n).read_text() == t for n, t in REPORT.items())
        else:
            res = _run(driver, root, "nth", "0", "demo")  # the next run proceeds
            assert res.returncode == 0, res.stderr
            assert _state(tir, report, set(REPORT), keep) == "everything"
        if keep:
            assert (report / "keep.txt").read_text() == "mine"
    assert seen == {"nothing", "committing", "everything"}


def test_output_set_refuses_to_replace_and_to_race(tmp_path):
    tir, report = tmp_path / "a.tir", tmp_path / "a_report"
    tir.write_text("old")
    outputs = OutputSet([tir, report])
    with pytest.raises(FileExistsError, match=r"a\.tir: exists"), outputs:
        outputs.path(tir).write_text("new")
        outputs.path(report).mkdir()
        outputs.commit()
    assert tir.read_text() == "old" and not report.exists()
    assert not (tmp_path / ".a.tir.partial").exists()  # nothing of the refused run stays
    staging = tmp_path / ".a.tir.partial"
    staging.mkdir()
    (staging / "owner").write_text("1")  # pid 1 is alive: another run is staging
    with pytest.raises(FileExistsError, match="another run"):
        OutputSet([tir, report]).recover()
    assert staging.exists()


# --- tire-model fit -o -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory) -> Path:
    from tire_model_ros.model import TireModel
    from tire_model_ros.rig import simulate_session, write_session

    model = TireModel.from_file(MF61_TIR)
    truth = model.with_params({"PDY1": model.params["PDY1"] * 1.08})
    wheels, info = simulate_session(
        truth, "lateral_sweeps", seed=2, omit=["temperature"], rate_hz=20.0,
        programme_options={"rate_scale": 3.0},
    )  # fmt: skip
    bag = tmp_path_factory.mktemp("bag") / "lat.mcap"
    write_session(bag, wheels, info)
    return bag


def _fit_args(bag: Path) -> list[str]:
    return ["fit", str(bag), "--tir", str(MF61_TIR), "-o", "out.tir", "--stages", "Fy0", "--quiet"]


def test_fit_killed_while_staging_leaves_nothing_and_the_next_run_proceeds(tmp_path, small_bag):
    tir, report = tmp_path / "out.tir", tmp_path / "out_fit_report"
    staged = tmp_path / ".out.tir.partial" / "items" / "1"
    proc = subprocess.Popen([*TOOL, *_fit_args(small_bag)], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    deadline = time.monotonic() + 300
    try:  # kill once the report is being staged: some of its files are written
        while not (staged.is_dir() and len(list(staged.iterdir())) >= 2):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the fit never staged its report"
            time.sleep(0.005)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    assert _state(tir, report, set(), set()) == "nothing"
    res = _run(_driver(tmp_path), tmp_path, "nth", "0", *_fit_args(small_bag))
    assert res.returncode == 0, res.stderr
    assert "removed the unfinished output of an interrupted run" in res.stderr
    assert tir.exists() and (report / "fit_report.json").exists()
    assert not (tmp_path / ".out.tir.partial").exists()


def test_fit_killed_between_its_renames_is_finished_by_the_next_run(tmp_path, small_bag):
    tir, report = tmp_path / "out.tir", tmp_path / "out_fit_report"
    driver = _driver(tmp_path)
    # killed after the .tir is in place, before the report folder is renamed
    between = "replace:.out.tir.partial/items/1"
    res = _run(driver, tmp_path, "before", between, *_fit_args(small_bag))
    assert res.returncode == -signal.SIGKILL, res.stderr
    assert tir.exists() and not report.exists()
    journal = json.loads((tmp_path / ".out.tir.partial" / JOURNAL).read_text())
    assert [Path(t).name for _, t in journal["moves"]] == ["out.tir", "out_fit_report"]
    fitted = tir.read_bytes()
    res = _run(driver, tmp_path, "nth", "0", *_fit_args(small_bag))  # the same command again
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert "finished the output of an interrupted run" in res.stderr
    assert "out.tir: exists" in res.stderr  # complete now: replaced only with --force
    assert tir.read_bytes() == fitted and json.loads((report / "fit_report.json").read_text())
    assert not (tmp_path / ".out.tir.partial").exists()
