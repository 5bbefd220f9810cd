"""Measurement files in (``tire-model import``, ``importers``): small TTC (.mat, .dat), TYDEX
and CSV files written here in each format's own layout, units and axes, imported by the real
command into real bags; the bag must hold what was written, converted to SI and ISO-W. Bad
files give one line naming the file, the line or channel, and what is wrong."""

from __future__ import annotations

import math
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import DEFAULT_TIR, TOOL
from scipy.io import savemat

from tire_model_ros.importers import MeasurementError, import_file
from tire_model_ros.importers.units import LBF_N, PSI_PA
from tire_model_ros.recording import read_recording

DEG = math.pi / 180.0
N_ROWS = 400
# the TTC's 24 channels in the order of a run file, with the SI/metric units it ships
TTC_NAMES = ("ET", "V", "N", "SA", "IA", "RL", "RE", "P", "FX", "FY", "FZ", "MX", "MZ", "NFX",
             "NFY", "RST", "TSTI", "TSTC", "TSTO", "AMBTMP", "SR", "SL", "RUN")  # fmt: skip
TTC_METRIC = {"ET": "s", "V": "kph", "N": "rpm", "SA": "deg", "IA": "deg", "RL": "cm",
              "RE": "cm", "P": "kPa", "FX": "N", "FY": "N", "FZ": "N", "MX": "N-m",
              "MZ": "N-m", "NFX": "none", "NFY": "none", "RST": "deg C", "TSTI": "deg C",
              "TSTC": "deg C", "TSTO": "deg C", "AMBTMP": "deg C", "SR": "none", "SL": "none",
              "RUN": "none"}  # fmt: skip
TTC_USCS = {**TTC_METRIC, "V": "mph", "RL": "in", "RE": "in", "P": "psi", "FX": "lb",
            "FY": "lb", "FZ": "lb", "MX": "ft-lb", "MZ": "ft-lb", "TSTC": "deg F"}  # fmt: skip


def _tm(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    return subprocess.run([*TOOL, *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)  # fmt: skip


def ttc_run(n: int = N_ROWS, seed: int = 0) -> dict[str, np.ndarray]:
    """A TTC cornering run in the consortium's SAE axes and metric units: SA swept through
    zero, FY falling and MZ rising with SA, FZ negative (z down)."""
    rng = np.random.default_rng(seed)
    et = 0.01 * np.arange(n) + 3.0
    sa = 8.0 * np.sin(2 * np.pi * et / 2.0)  # deg
    fz = -1100.0 + rng.normal(0, 5, n)
    data = {
        "ET": et, "V": np.full(n, 40.23), "N": np.full(n, 350.0), "SA": sa,
        "IA": np.full(n, 2.0) + rng.normal(0, 0.02, n), "RL": np.full(n, 22.0),
        "RE": np.full(n, 22.5), "P": np.full(n, 82.7) + rng.normal(0, 0.2, n),
        "FX": rng.normal(0, 10, n), "FY": -2.2 * 1100 * np.tanh(sa / 5.0),
        "FZ": fz, "MX": rng.normal(0, 3, n), "MZ": 40 * np.sin(sa * DEG * 6),
        "NFX": np.zeros(n), "NFY": np.zeros(n), "RST": np.full(n, 30.0),
        "TSTI": np.full(n, 45.0), "TSTC": 50.0 + 0.01 * np.arange(n), "TSTO": np.full(n, 44.0),
        "AMBTMP": np.full(n, 24.0), "SR": rng.normal(0, 0.002, n),
        "SL": rng.normal(0, 0.002, n), "RUN": np.full(n, 23.0),
    }  # fmt: skip
    return {k: data[k] for k in TTC_NAMES}


def write_ttc_mat(path: Path, data: dict[str, np.ndarray], units: dict[str, str]) -> None:
    """The consortium's .mat layout: column variables and a channel struct (cell arrays)."""
    names = np.empty((1, len(data)), dtype=object)
    names[0, :] = list(data)
    unit_cells = np.empty((1, len(data)), dtype=object)
    unit_cells[0, :] = [units[k] for k in data]
    mat: dict[str, object] = {k: v.reshape(-1, 1) for k, v in data.items()}
    mat.update(channel={"name": names, "units": unit_cells}, tireid="Hoosier 43075 16x7.5-10",
               testid="Cornering")  # fmt: skip
    savemat(str(path), mat)


def write_ttc_dat(path: Path, data: dict[str, np.ndarray], units: dict[str, str]) -> None:
    """The consortium's ASCII layout: a title line, names, units (with blanks), rows."""
    lines = ["TTC Round 8 run 23: Cornering", "\t".join(data), "\t".join(units[k] for k in data)]
    lines += ["\t".join(f"{v:.10g}" for v in row) for row in np.column_stack(list(data.values()))]
    path.write_text("\n".join(lines) + "\n")


def _expect_iso(data: dict[str, np.ndarray], scale: dict[str, float]) -> dict[str, np.ndarray]:
    """What the bag must hold: SAE -> ISO-W, units -> SI (``scale`` of the non-SI units)."""
    s = lambda k: data[k] * scale.get(k, 1.0)  # noqa: E731
    return {
        "t": data["ET"], "alpha": -data["SA"] * DEG, "gamma": data["IA"] * DEG,
        "kappa": data["SL"], "Fz": -s("FZ"), "Fx": s("FX"), "Fy": -s("FY"), "Mx": s("MX"),
        "Mz": -s("MZ"), "p": s("P"), "Vx": s("V"),
    }  # fmt: skip


def _assert_bag(bag: Path, want: dict[str, np.ndarray], rows=slice(None)) -> None:
    s = read_recording(bag)["/rig/wheel"]
    for k, v in want.items():
        np.testing.assert_allclose(getattr(s, k), v[rows], rtol=1e-9, atol=1e-9, err_msg=k)


@pytest.mark.parametrize("suffix", [".mat", ".dat"])
def test_ttc_metric_file_imports_converted(tmp_path, suffix):
    data = ttc_run()
    src = tmp_path / f"B1965run23{suffix}"
    (write_ttc_mat if suffix == ".mat" else write_ttc_dat)(src, data, TTC_METRIC)
    r = _tm("import", str(src), "-o", "bag", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    want = _expect_iso(data, {"P": 1e3, "V": 1 / 3.6})
    want["T"] = data["TSTC"]
    _assert_bag(tmp_path / "bag", want)
    s = read_recording(tmp_path / "bag")["/rig/wheel"]
    assert s.My is None or not np.isfinite(s.My).any()  # the TTC measures no My
    # the signs, checked on the data and said
    assert "sign check Fy against alpha: falls" in r.stdout and "as ISO-W has it" in r.stdout
    assert "sign check Mz against alpha: rises" in r.stdout
    assert "no rows with NaN" in r.stdout and "warning" not in r.stderr


def test_ttc_uscs_units_and_sr_fallback(tmp_path):
    data = ttc_run(seed=1)
    del data["SL"]  # an older round: SR only
    src = tmp_path / "run.mat"
    write_ttc_mat(src, data, TTC_USCS)
    r = _tm("import", str(src), "-o", "bag", "--prefix", "/ttc/lf", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    ftlb = LBF_N * 0.3048
    scale = {"P": PSI_PA, "V": 0.44704, "FX": LBF_N, "FY": LBF_N, "FZ": LBF_N, "MX": ftlb,
             "MZ": ftlb}  # fmt: skip
    s = read_recording(tmp_path / "bag")["/ttc/lf"]
    want = _expect_iso({**data, "SL": data["SR"]}, scale)
    for k, v in want.items():
        np.testing.assert_allclose(getattr(s, k), v, rtol=1e-9, atol=1e-9, err_msg=k)
    np.testing.assert_allclose(s.T, (data["TSTC"] - 32) * 5 / 9, rtol=1e-12)
    assert "slip ratio kappa from SR" in r.stdout


def test_nan_rows_dropped_and_counted(tmp_path):
    data = ttc_run()
    data["FY"][[5, 6]] = np.nan
    data["TSTC"][9] = np.nan
    src = tmp_path / "run.dat"
    write_ttc_dat(src, data, TTC_METRIC)
    r = _tm("import", str(src), "-o", "bag", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert f"dropped 3 of {N_ROWS} rows with NaN (NaN in FY 2, TSTC 1)" in r.stdout
    keep = np.ones(N_ROWS, bool)
    keep[[5, 6, 9]] = False
    want = _expect_iso(data, {"P": 1e3, "V": 1 / 3.6})
    _assert_bag(tmp_path / "bag", want, keep)
    assert np.all(np.isfinite(read_recording(tmp_path / "bag")["/rig/wheel"].Fy))
    # the temperature left out: its NaN no longer costs a row
    r = _tm("import", str(src), "-o", "bag2", "--omit", "temperature", cwd=tmp_path)
    assert r.returncode == 0 and "dropped 2 of" in r.stdout, r.stdout + r.stderr
    assert read_recording(tmp_path / "bag2")["/rig/wheel"].T is None


def _first(bad: np.ndarray) -> int:
    """The 1-based row of the first True."""
    return int(np.flatnonzero(bad)[0]) + 1


def _one_line_error(r: subprocess.CompletedProcess[str], *parts: str) -> None:
    assert r.returncode == 1, r.stdout + r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    for p in parts:
        assert p in lines[0], (p, lines[0])


def _error_of(path: Path) -> str:
    with pytest.raises(MeasurementError) as info:
        import_file(path)
    text = str(info.value)
    assert "\n" not in text and text.startswith(f"{path}: "), text
    return text


def test_bad_ttc_files_are_one_line_errors(tmp_path):
    good = ttc_run()
    back = {**good, "ET": good["ET"].copy()}
    back["ET"][10] = back["ET"][9]
    nosa = {k: v for k, v in good.items() if k != "SA"}
    cases = [
        ("unit.mat", good, {**TTC_METRIC, "FZ": "furlong"},
         ("channel FZ", "unknown unit 'furlong' for the force")),
        ("kind.dat", good, {**TTC_METRIC, "SA": "N"},
         ("channel SA: unknown unit 'N' for the angle",)),
        ("nosa.mat", nosa, TTC_METRIC, ("missing channel SA",)),
        ("time.dat", back, TTC_METRIC, ("line 14: time ET = 3.09 s does not increase",)),
        ("time.mat", back, TTC_METRIC, ("row 11: time ET",)),
        ("nan.mat", {**good, "TSTC": np.full(N_ROWS, np.nan)}, TTC_METRIC,
         ("channel TSTC: every value is NaN (leave it out with --omit temperature)",)),
        ("nofz.dat", {k: v for k, v in good.items() if k != "FZ"}, TTC_METRIC,
         ("nofz.dat: line 2: missing channel FZ",)),
        # a wrong unit that is a unit: values no tyre can have, the first one named
        ("rad.mat", good, {**TTC_METRIC, "SA": "rad"},
         (f"row {_first(np.abs(good['SA']) > math.pi / 2)}: channel SA: a slip angle of ",
          "deg (ISO-W, converted) is outside -90..90 deg: is the file's unit of SA right?")),
        ("pa.dat", {**good, "P": good["P"] * 1e3}, TTC_METRIC,
         ("line 4: channel P: a gauge inflation pressure of 8", "is the file's unit of P right?")),
    ]  # fmt: skip
    for name, data, units, parts in cases:
        src = tmp_path / name
        (write_ttc_mat if name.endswith(".mat") else write_ttc_dat)(src, data, units)
        text = _error_of(src)
        for p in parts:
            assert p in text, (p, text)
    # a text cell that is not a number, named with its line and column
    src = tmp_path / "cell.dat"
    write_ttc_dat(src, good, TTC_METRIC)
    text = src.read_text().splitlines()
    fields = text[7].split("\t")
    fields[3] = "x1"
    text[7] = "\t".join(fields)
    src.write_text("\n".join(text))
    assert "line 8: column 4: 'x1' is not a number" in _error_of(src)
    (tmp_path / "junk.mat").write_bytes(b"not matlab" * 20)
    assert "not a readable MATLAB .mat file" in _error_of(tmp_path / "junk.mat")
    # the command says it in one line, writes nothing, and an unknown suffix asks for --format
    r = _tm("import", "unit.mat", "-o", "bag", cwd=tmp_path)
    _one_line_error(r, "tire-model import: error: unit.mat: channel FZ: unknown unit")
    assert not (tmp_path / "bag").exists()
    (tmp_path / "x.xyz").write_text("1\n")
    _one_line_error(_tm("import", "x.xyz", "-o", "j", cwd=tmp_path), "x.xyz", "--format")


def test_mirrored_file_is_warned_about(tmp_path):
    data = ttc_run()
    data["FY"] = -data["FY"]  # a file already in ISO-W, or a mirrored tyre
    src = tmp_path / "mirrored.mat"
    write_ttc_mat(src, data, TTC_METRIC)
    r = _tm("import", str(src), "-o", "bag", cwd=tmp_path)
    assert r.returncode == 0
    assert "sign check Fy against alpha: rises" in r.stdout and "NOT as ISO-W" in r.stdout
    assert "warning: Fy rises with alpha" in r.stderr


def test_slip_noise_is_no_sign(tmp_path):
    """A cornering run's slip ratio is noise around zero: Fx does not follow it, and a slope
    fitted through noise must not raise a sign warning."""
    data = ttc_run(n=6000, seed=3)
    data["SA"][:3000] = 0.0  # straight running: pure longitudinal slip noise
    src = tmp_path / "long.mat"
    write_ttc_mat(src, data, TTC_METRIC)
    rep = import_file(src).report
    assert not rep.warnings, rep.warnings
    line = next(ln for ln in rep.lines if ln.startswith("sign check Fx against kappa"))
    assert "not checked (Fx does not follow kappa near zero slip: slope t = " in line, line


TYDEX = """**HEADER
RELEASE   Release of TYDEX-format          1.3
MEASID    measurement id.                  KIT_SIDE_test
**COMMENTS
a lateral sweep at constant pressure
**CONSTANTS
NOMPRES   nominal inflation pressure       kPa       220
INFLPRES  inflation pressure               kPa       230
FNOMIN    nominal load                     N         4000
**MEASURCHANNELS
! name    description                      unit      factor meas.offset phys.offset
RUNTIME   running time                     s         1
LONGSLIP  longitudinal slip                %         1       0       0
SLIPANGL  slip angle                       deg       1       0       0
INCLANGL  inclination angle                deg       1
FZW       vertical force                   kN        0.001   0       4.0
FX        longitudinal force               N         1
FYW       lateral force                    N         2       10      0
MZW       aligning moment                  Nm        1
LONGVEL   longitudinal velocity            km/h      1
TRDTEMP   tread temperature                degC      1
**MEASURDATA
"""


def _tydex_rows(n=300):
    rng = np.random.default_rng(4)
    t = 0.02 * np.arange(n)
    sa = 6 * np.sin(2 * np.pi * t / 3)
    return np.column_stack([t, rng.normal(0, 0.1, n), sa, np.full(n, 1.5),
                            rng.normal(0, 30, n), rng.normal(0, 20, n), -900 * np.tanh(sa / 4),
                            20 * np.tanh(sa / 4), np.full(n, 60.0), 40 + 0.02 * t])  # fmt: skip


def test_tydex_file_imports_by_channel_name(tmp_path):
    rows = _tydex_rows()
    cells = [[f"{v:.9g}" for v in r] for r in rows]
    cells[7][8] = "NOTAVAIL"  # a speed not measured: the row is dropped
    text = TYDEX + "\n".join(" ".join(r) for r in cells) + "\n**END\n"
    rows = np.array([[float(x) if x != "NOTAVAIL" else np.nan for x in r] for r in cells])
    (tmp_path / "KIT_SIDE_test.tdx").write_text(text)
    r = _tm("import", "KIT_SIDE_test.tdx", "-o", "bag", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "INFLPRES from **CONSTANTS: 230 kPa" in r.stdout and "dropped 1 of 300" in r.stdout
    s = read_recording(tmp_path / "bag")["/rig/wheel"]
    keep = np.arange(300) != 7
    rows = rows[keep]
    np.testing.assert_allclose(s.t, rows[:, 0], atol=1e-9)
    np.testing.assert_allclose(s.kappa, rows[:, 1] / 100, atol=1e-12)
    np.testing.assert_allclose(s.alpha, rows[:, 2] * DEG, atol=1e-12)
    np.testing.assert_allclose(s.gamma, rows[:, 3] * DEG, atol=1e-12)
    np.testing.assert_allclose(s.Fz, (rows[:, 4] * 0.001 + 4.0) * 1000, rtol=1e-12)
    np.testing.assert_allclose(s.Fy, (rows[:, 6] - 10) * 2, rtol=1e-12)  # factor, offset
    np.testing.assert_allclose(s.Mz, rows[:, 7], rtol=1e-12)
    np.testing.assert_allclose(s.Vx, rows[:, 8] / 3.6, rtol=1e-12)
    np.testing.assert_allclose(s.T, rows[:, 9], rtol=1e-12)
    np.testing.assert_allclose(s.p, 230e3, rtol=1e-12)
    assert "sign check Fy against alpha: falls" in r.stdout  # W axes are ISO-W: no flip


def test_bad_tydex_files(tmp_path):
    body = "\n".join(" ".join(f"{v:.9g}" for v in r) for r in _tydex_rows(50))
    hub = TYDEX
    for w, h in (("FYW ", "FYH "), ("FX  ", "FXH "), ("MZW ", "MZH ")):
        hub = hub.replace(w, h)
    cases = {
        "hub.tdx": (hub + body, "missing channel FX/FXW/FYW/MZW (FXH, FYH, MZH in hub/centre"),
        "unit.tdx": (TYDEX.replace("kN ", "mN ") + body, "channel FZW: unknown unit 'mN'"),
        "short.tdx": (TYDEX + body + "\n1 2 3\n", f"line {TYDEX.count(chr(10)) + 51}: 3 values"),
        "none.tdx": ("**HEADER\nRELEASE x 1.3\n", "no **MEASURCHANNELS block"),
    }
    for name, (text, part) in cases.items():
        (tmp_path / name).write_text(text)
        error = _error_of(tmp_path / name)
        assert part in error, (part, error)


def test_csv_with_byte_order_mark(tmp_path):
    n = 200
    t = 0.01 * np.arange(n)
    alpha = 0.1 * np.sin(t * 3)
    cols = {"t": t, "Fz": np.full(n, 4000.0), "kappa": np.zeros(n), "alpha": alpha,
            "gamma": np.zeros(n), "Vx": np.full(n, 16.7), "p": np.full(n, 2.2e5),
            "Fx": np.zeros(n), "Fy": -50000 * alpha, "Mz": 800 * alpha}  # fmt: skip
    rows = np.column_stack(list(cols.values()))
    text = ",".join(cols) + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows)
    (tmp_path / "fe.csv").write_text(text, encoding="utf-8-sig")
    r = _tm("import", "fe.csv", "-o", "bag", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    s = read_recording(tmp_path / "bag")["/rig/wheel"]
    for k, v in cols.items():
        np.testing.assert_allclose(getattr(s, k), v, rtol=1e-12, err_msg=k)
    assert s.T is None and (s.Mx is None or not np.isfinite(s.Mx).any())
    # the eval reader takes the same byte-order mark
    (tmp_path / "in.csv").write_text("Fz,kappa,alpha,gamma,Vx,p\n4000,0.01,0.02,0,16.7,2.2e5\n",
                                     encoding="utf-8-sig")  # fmt: skip
    tir = DEFAULT_TIR
    r = _tm("eval", "--tir", str(tir), "in.csv", "-o", "out.csv", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "out.csv").read_text().startswith("Fz,kappa,alpha,gamma,Vx,p,Fx,Fy")
    # a cell that is not a number: its line and column name
    (tmp_path / "bad.csv").write_text(text.replace(repr(float(alpha[3])), "oops", 1))
    with pytest.raises(MeasurementError, match=r"bad.csv: line 5: column 'alpha': 'oops'"):
        import_file(tmp_path / "bad.csv")


def test_bad_csv_files(tmp_path):
    head = "t,Fz,kappa,alpha,gamma,Vx,p,Fx,Fy\n"
    row = "{t},4000,0,{a},0,16.7,2.2e5,0,{fy}\n"
    rows = [row.format(t=0.01 * i, a=0.001 * i, fy=-50 * i) for i in range(20)]
    cases = {
        "noalpha.csv": (head.replace("alpha", "beta") + "".join(rows),
                        "line 1: missing column(s) alpha"),
        "time.csv": (head + "".join(rows[:5] + rows[4:]), "line 7: time t = 0.04 s does not"),
        "nan.csv": (head + "".join(r.rsplit(",", 1)[0] + ",nan\n" for r in rows),
                    "channel Fy: every value is NaN"),
        "short.csv": (head + "".join(rows[:3]) + "0.5,4000,0\n", "line 5: column 'alpha' missing"),
        "deg.csv": (head + "".join(row.format(t=0.01 * i, a=2.0 * i, fy=0) for i in range(5)),
                    "line 3: channel alpha: a slip angle of 114.592 deg (ISO-W, converted) is "
                    "outside -90..90 deg"),
    }  # fmt: skip
    for name, (text, part) in cases.items():
        (tmp_path / name).write_text(text)
        error = _error_of(tmp_path / name)
        assert part in error, (part, error)


def test_info_reads_a_measurement_file(tmp_path):
    """info on a TTC file: the bag import would write, named by the file; its report on stderr."""
    write_ttc_dat(tmp_path / "run.dat", ttc_run(), TTC_METRIC)
    r = _tm("info", "run.dat", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("bag:       run.dat (ttc file, imported)\n"), r.stdout
    assert f"/rig/wheel: {N_ROWS} samples" in r.stdout and "/rig/wheel/temperature" in r.stdout
    assert "import: read run.dat (ttc)" in r.stderr
    _one_line_error(_tm("info", "run.dat", "--salvage", cwd=tmp_path), "run.dat: a measurement")
