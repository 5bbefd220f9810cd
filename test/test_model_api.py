"""TireModel API: broadcasting, single-sample path, immutability, errors, NaN, eval CLI."""

from __future__ import annotations

import csv
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import MF61_TIR, ROOT, TIR_DIR, TOOL, requires_reference

from tire_model_ros.model import MFOutput, TireModel, read_tir
from tire_model_ros.model import coef as c

TIR52 = TIR_DIR / "MagicFormula52_Parameters.tir"
pytestmark = requires_reference


def _random_inputs(n: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    return (
        rng.uniform(0.0, 14000.0, n),  # Fz
        rng.uniform(-1.2, 1.2, n),  # kappa
        rng.uniform(-0.5, 0.5, n),  # alpha
        rng.uniform(-0.12, 0.12, n),  # gamma
        rng.uniform(-3.0, 40.0, n),  # Vx, low speed and reverse included
        rng.uniform(1.5e5, 4.2e5, n),  # p
        rng.uniform(-10.0, 100.0, n),  # T
    )


def test_coefficient_index_matches_names() -> None:
    assert len(set(c.NAMES)) == len(c.NAMES) == c.N_COEF
    for k, name in enumerate(c.NAMES):
        assert getattr(c, name) == k, name


def test_broadcasting(model) -> None:
    Fz = np.array([[2000.0], [6752.0], [9000.0]])
    kappa = np.array([-0.1, 0.0, 0.02, 0.3])
    out = model.evaluate(Fz, kappa, 0.05, gamma=0.02)
    assert isinstance(out, MFOutput)
    assert out.Fx.shape == out.Mz.shape == out.Re.shape == (3, 4)
    for i in range(3):
        for j in range(4):
            one = model.evaluate(Fz[i, 0], kappa[j], 0.05, 0.02)
            assert one.Fx.shape == ()
            assert out.Fx[i, j] == one.Fx and out.Mz[i, j] == one.Mz and out.Re[i, j] == one.Re
    # defaults: Vx -> LONGVL, p -> INFLPRES, T -> NOMTEMP
    P = model.params
    explicit = model.evaluate(Fz, kappa, 0.05, 0.02, P["LONGVL"], P["INFLPRES"], P["NOMTEMP"])
    np.testing.assert_array_equal(explicit.Fy, out.Fy)
    forces_only = model.evaluate(Fz, kappa, 0.05, gamma=0.02, full=False)
    np.testing.assert_array_equal(forces_only.Fy, out.Fy)
    assert forces_only.Re is None


def test_input_layouts_give_the_same_result_and_are_left_as_they_were(model) -> None:
    # Full-shape C-contiguous float64 inputs go to the kernels as they are; strided, read-only,
    # unaligned and integer ones are copied first: every layout gives the same values, and no
    # input changes.
    Fz, kappa, alpha, gamma, Vx, p, T = _random_inputs(2000, seed=3)
    ref = model.evaluate(Fz, kappa, alpha, gamma, Vx, p, T)
    kept = [a.copy() for a in (Fz, kappa, alpha, gamma, Vx, p, T)]
    strided = np.repeat(Fz, 2)[::2]
    readonly = kappa.copy()
    readonly.setflags(write=False)
    two_d = alpha.reshape(40, 50)
    unaligned = np.frombuffer(bytearray(b"\0" + gamma.tobytes()), dtype=np.float64, offset=1)
    out = model.evaluate(strided, readonly, two_d.reshape(-1), unaligned, Vx, p, T)
    for name in ("Fx", "Fy", "Mz", "Mx", "My", "Re", "Cz"):
        np.testing.assert_array_equal(getattr(out, name), getattr(ref, name), err_msg=name)
    for a, b in zip((Fz, kappa, alpha, gamma, Vx, p, T), kept, strict=True):
        np.testing.assert_array_equal(a, b)
    whole = model.evaluate(np.full(3, 4000), 0, np.zeros(3))  # integers, scalars
    np.testing.assert_array_equal(whole.Fy, model.evaluate(np.full(3, 4000.0), 0.0, 0.0).Fy)


@pytest.mark.parametrize("limits", [True, False])
def test_evaluate_one_equals_evaluate(model, limits) -> None:
    Fz, kappa, alpha, gamma, Vx, p, T = _random_inputs(300)
    warm = model.with_params({"TTX1": 0.2, "TTY3": -0.1, "TTY2": 0.3})
    batch = warm.evaluate(Fz, kappa, alpha, gamma, Vx, p, T, limits=limits)
    for i in range(Fz.size):
        one = warm.evaluate_one(Fz[i], kappa[i], alpha[i], gamma[i], Vx[i], p[i], T[i], limits)
        assert isinstance(one, tuple) and len(one) == 6
        expected = tuple(getattr(batch, k)[i] for k in ("Fx", "Fy", "Fz", "Mx", "My", "Mz"))
        assert one == expected, i


@pytest.mark.parametrize("modes", [{}, {"turn_slip": True, "alpha_star": True}])
def test_the_forces_alone_are_the_forces_of_the_whole_evaluation(model, modes) -> None:
    # moments=False skips the aligning and moment stages: every force output is bit-equal to
    # the whole evaluation's (plain loop and the turn-slip / alpha* one), the moments are NaN.
    Fz, kappa, alpha, gamma, Vx, p, T = _random_inputs(1500, seed=7)
    whole = model.evaluate(Fz, kappa, alpha, gamma, Vx, p, T, full=False, **modes)
    forces = model.evaluate(Fz, kappa, alpha, gamma, Vx, p, T, full=False, moments=False, **modes)
    for k in ("Fx", "Fy", "Fz", "Kxk", "Kya", "mux", "muy"):
        np.testing.assert_array_equal(getattr(forces, k), getattr(whole, k), err_msg=k)
    for k in ("Mx", "My", "Mz", "t", "Mzr"):
        assert np.isnan(getattr(forces, k)).all(), k
    assert np.isfinite(whole.Mz).all()


def test_the_forces_loop_keeps_the_call_a_jitted_caller_outside_the_package_makes(model) -> None:
    # realities/car calls kernel.forces_loop from its own numba code with the arguments up to
    # ``out``: ``moments`` came later, with a default, so that call still compiles and runs.
    from numba import njit

    from tire_model_ros.model.kernel import N_FORCES, forces_loop

    @njit
    def outside(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, out):
        forces_loop(P, Fz, kappa, alpha, gamma, Vx, p, T, phit, True, out)

    Fz, kappa, alpha, gamma, Vx, p, T = _random_inputs(600, seed=11)
    out = np.empty((N_FORCES, Fz.size))
    outside(model.coefficient_vector, Fz, kappa, alpha, gamma, Vx, p, T, np.zeros(Fz.size), out)
    ref = model.evaluate(Fz, kappa, alpha, gamma, Vx, p, T, full=False)
    np.testing.assert_array_equal(out[0], ref.Fx)
    np.testing.assert_array_equal(out[5], ref.Mz)


@pytest.mark.parametrize("limits", [True, False])
def test_zero_camber_block_shortcut_is_exact(model, limits) -> None:
    # Blocks of zero camber take the shortcut (Fy0 at zero camber = Fy0); a tiny camber on
    # sample 0 makes its block run the zero-camber stage: the other samples must be bit-equal.
    Fz, kappa, alpha, _, Vx, p, T = _random_inputs(1024, seed=5)
    gamma = np.zeros(1024)
    short = model.evaluate(Fz, kappa, alpha, gamma, Vx, p, T, limits=limits, full=False)
    gamma[0] = 1e-300
    full = model.evaluate(Fz, kappa, alpha, gamma, Vx, p, T, limits=limits, full=False)
    for k in ("Fx", "Fy", "Fz", "Mx", "My", "Mz"):
        np.testing.assert_array_equal(getattr(short, k)[1:], getattr(full, k)[1:], err_msg=k)


def test_with_params_is_a_new_model(model) -> None:
    before = model.evaluate(5000.0, 0.05, 0.05)
    other = model.with_params({"PDX1": 1.5, "lmuy": 0.8})  # names are case-insensitive
    assert other is not model
    assert other.params["PDX1"] == 1.5 and other.params["LMUY"] == 0.8
    assert model.params["PDX1"] == pytest.approx(1.1632)
    assert other.tir.params["PDX1"] == 1.5 and model.tir.params["PDX1"] == pytest.approx(1.1632)
    after = model.evaluate(5000.0, 0.05, 0.05)
    assert after.Fx == before.Fx and after.Fy == before.Fy
    changed = other.evaluate(5000.0, 0.05, 0.05)
    assert changed.Fx != before.Fx and changed.Fy != before.Fy
    with pytest.raises(TypeError):
        model.params["PDX1"] = 2.0  # type: ignore[index]
    with pytest.raises(ValueError):
        model.coefficient_vector[c.PDX1] = 2.0
    with pytest.raises(AttributeError):
        model.tir = other.tir  # type: ignore[misc]


@pytest.mark.parametrize(
    ("updates", "key"),
    [
        ({"NOT_A_COEFFICIENT": 1.0}, "NOT_A_COEFFICIENT"),
        ({"PDY1": math.nan}, "PDY1"),
        ({"PKX1": math.inf}, "PKX1"),
        ({"PCX1": 0.0}, "PCX1"),
        ({"PCY1": -1.0}, "PCY1"),
        ({"FNOMIN": -100.0}, "FNOMIN"),
        ({"NOMPRES": 0.0}, "NOMPRES"),
        ({"NOMTEMP": 0.0}, "NOMTEMP"),
        ({"UNLOADED_RADIUS": 0.0}, "UNLOADED_RADIUS"),
        ({"PDX1": "abc"}, "PDX1"),
        ({"FITTYP": 62}, "FITTYP"),
    ],
)
def test_with_params_rejects_bad_values(model, updates, key) -> None:
    with pytest.raises(ValueError, match=key):
        model.with_params(updates)
    assert model.params["PCX1"] > 0  # unchanged


def test_nan_and_inf_inputs_do_not_crash(model) -> None:
    nan, inf = math.nan, math.inf
    Fz = np.array([5000.0, nan, 5000.0, 5000.0, 5000.0, inf, 5000.0])
    kappa = np.array([0.05, 0.05, nan, 0.05, 0.05, 0.05, inf])
    alpha = np.array([0.05, 0.05, 0.05, nan, 0.05, 0.05, 0.05])
    p = np.array([2.6e5, 2.6e5, 2.6e5, 2.6e5, nan, 2.6e5, 2.6e5])
    for limits in (True, False):
        out = model.evaluate(Fz, kappa, alpha, 0.0, 16.6, p, limits=limits)
        assert np.isfinite(out.Fx[0]) and np.isfinite(out.Fy[0]) and np.isfinite(out.Mz[0])
        assert np.isnan(out.Fx[1]) and np.isnan(out.Fy[1])  # NaN load: NaN forces
        assert np.isnan(out.Fx[2]) and np.isnan(out.Fy[2])  # NaN kappa reaches Fy (combined)
        assert np.isnan(out.Fy[3]) and np.isnan(out.Mz[3])  # NaN alpha
        assert np.isnan(out.Fx[4]) or not limits  # NaN pressure (limits: clip keeps NaN)
        one = model.evaluate_one(nan, 0.0, 0.0, 0.0, 16.6, 2.6e5, 25.0, limits)
        assert all(math.isnan(v) for v in (one[0], one[1], one[5]))
    # limits on: an infinite load or slip is saturated to the file's range -> finite force
    sat = model.evaluate(Fz[5:], kappa[5:], alpha[5:], 0.0, 16.6, 2.6e5, limits=True)
    assert np.all(np.isfinite(sat.Fx)) and np.all(np.isfinite(sat.Fy))


def test_mf52_file_has_no_pressure_effect() -> None:
    if not TIR52.is_file():
        pytest.skip(f"{TIR52} missing")
    m52 = TireModel.from_file(TIR52)
    assert m52.coefficient_vector[c.FITTYP] == 6
    Fz, kappa, alpha, gamma, Vx, _, T = _random_inputs(200, seed=3)
    nominal = m52.evaluate(Fz, kappa, alpha, gamma, Vx, None, T, limits=False)
    high = m52.evaluate(Fz, kappa, alpha, gamma, Vx, 1.5 * m52.params["NOMPRES"], T,
                        limits=False)  # fmt: skip
    for name in ("Fx", "Fy", "Mx", "My", "Mz"):
        np.testing.assert_array_equal(getattr(high, name), getattr(nominal, name), err_msg=name)
        assert np.all(np.isfinite(getattr(nominal, name)[Fz > 0])), name


def test_from_file_equals_constructor(model) -> None:
    again = TireModel(read_tir(MF61_TIR))
    np.testing.assert_array_equal(again.coefficient_vector, model.coefficient_vector)


# --- tire-model eval ------------------------------------------------------------------------


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*TOOL, "eval", *args], capture_output=True, text=True, timeout=240)


def _write_inputs(path: Path, with_T: bool) -> dict[str, np.ndarray]:
    Fz, kappa, alpha, gamma, Vx, p, T = _random_inputs(25, seed=7)
    cols = {"Fz": Fz, "kappa": kappa, "alpha": alpha, "gamma": gamma, "Vx": Vx, "p": p}
    if with_T:
        cols["T"] = T
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["note", *cols])  # an extra column is ignored
        for i in range(Fz.size):
            w.writerow(["x", *(repr(float(cols[k][i])) for k in cols)])
    return cols


def _read_csv(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return {h: np.array([float(r[k]) for r in rows[1:]]) for k, h in enumerate(rows[0])}


@pytest.mark.parametrize("no_limits", [False, True])
def test_eval_cli_round_trip(model, tmp_path, no_limits) -> None:
    src = tmp_path / "in.csv"
    dst = tmp_path / "out.csv"
    cols = _write_inputs(src, with_T=not no_limits)
    res = _run("--tir", str(MF61_TIR), str(src), "-o", str(dst), *(["--no-limits"] if no_limits
                                                                else []))  # fmt: skip
    assert res.returncode == 0, res.stderr
    out = _read_csv(dst)
    assert list(out)[: len(cols)] == list(cols) and list(out)[len(cols) :] == [
        "Fx", "Fy", "Mx", "My", "Mz"]  # fmt: skip
    ref = model.evaluate(cols["Fz"], cols["kappa"], cols["alpha"], cols["gamma"], cols["Vx"],
                         cols["p"], cols.get("T"), limits=not no_limits)  # fmt: skip
    for name in ("Fx", "Fy", "Mx", "My", "Mz"):
        np.testing.assert_array_equal(out[name], getattr(ref, name), err_msg=name)
    for name in cols:
        np.testing.assert_array_equal(out[name], cols[name])
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_eval_cli_variants(model, tmp_path) -> None:
    """--turn-slip (with a phit column) and --alpha-star reach TireModel.evaluate."""
    src = tmp_path / "in.csv"
    cols = _write_inputs(src, with_T=False)
    phit = np.linspace(-0.3, 0.3, cols["Fz"].size)
    lines = src.read_text().splitlines()
    rows = [f"{line},{float(v)!r}" for line, v in zip(lines[1:], phit, strict=True)]
    src.write_text("\n".join([lines[0] + ",phit", *rows]) + "\n")
    for flags in (["--turn-slip"], ["--alpha-star"], ["--turn-slip", "--alpha-star"]):
        dst = tmp_path / f"out{len(flags)}{flags[0]}.csv"
        res = _run("--tir", str(MF61_TIR), str(src), "-o", str(dst), *flags)
        assert res.returncode == 0, res.stderr
        out = _read_csv(dst)
        ref = model.evaluate(cols["Fz"], cols["kappa"], cols["alpha"], cols["gamma"], cols["Vx"],
                             cols["p"], phit=phit, turn_slip="--turn-slip" in flags,
                             alpha_star="--alpha-star" in flags)  # fmt: skip
        for name in ("Fx", "Fy", "Mx", "My", "Mz"):
            np.testing.assert_array_equal(out[name], getattr(ref, name), err_msg=name)


def test_eval_cli_refuses_overwrite_and_bad_rows(tmp_path) -> None:
    src = tmp_path / "in.csv"
    dst = tmp_path / "out.csv"
    _write_inputs(src, with_T=True)
    dst.write_text("keep me\n")
    res = _run("--tir", str(MF61_TIR), str(src), "-o", str(dst))
    assert res.returncode == 1 and "--force" in res.stderr and str(dst) in res.stderr
    assert dst.read_text() == "keep me\n"
    res = _run("--tir", str(MF61_TIR), str(src), "-o", str(dst), "--force")
    assert res.returncode == 0, res.stderr
    assert dst.read_text().startswith("Fz,")

    bad = tmp_path / "bad.csv"
    lines = src.read_text().splitlines()
    fields = lines[3].split(",")
    fields[3] = "zero"  # column alpha (after the note, Fz, kappa)
    lines[3] = ",".join(fields)
    bad.write_text("\n".join(lines) + "\n")
    res = _run("--tir", str(MF61_TIR), str(bad), "-o", str(tmp_path / "o2.csv"))
    assert res.returncode == 1
    assert "bad.csv" in res.stderr and "line 4" in res.stderr and "'alpha'" in res.stderr
    assert not (tmp_path / "o2.csv").exists()

    nocol = tmp_path / "nocol.csv"
    nocol.write_text("Fz,kappa,alpha\n1,0,0\n")
    res = _run("--tir", str(MF61_TIR), str(nocol), "-o", str(tmp_path / "o3.csv"))
    assert res.returncode == 1 and "gamma" in res.stderr and "Vx" in res.stderr


def test_eval_cli_writes_finite_rows_or_nothing(tmp_path) -> None:
    head = "Fz,kappa,alpha,gamma,Vx,p\n"
    ok = "4000,0.05,0.02,0,16,260000\n"
    src = tmp_path / "in.csv"
    src.write_text(head + ok + "4000,nan,0,0,16,260000\n")
    res = _run("--tir", str(MF61_TIR), str(src), "-o", str(tmp_path / "o1.csv"))
    assert res.returncode == 1
    assert "in.csv: line 3: column 'kappa': 'nan' is not finite" in res.stderr
    # the plain equations at 1e300 N overflow: refused, naming the CSV line, nothing written
    src.write_text(head + ok + ok + "1e300,0.1,0.1,0,16,260000\n")
    res = _run("--tir", str(MF61_TIR), str(src), "-o", str(tmp_path / "o2.csv"), "--no-limits")
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert "1 of 3 rows give non-finite outputs" in res.stderr and "line(s) 4;" in res.stderr
    assert not (tmp_path / "o2.csv").exists()
    # with the limits the same rows are saturated, counted, and written
    src.write_text(head + ok + "20000,0.05,1.2,0,16,260000\n" + "1e300,0.1,-1.3,0,0.5,260000\n")
    res = _run("--tir", str(MF61_TIR), str(src), "-o", str(tmp_path / "o3.csv"))
    assert res.returncode == 0, res.stderr
    assert "saturated to the file's ranges: Fz on 2 rows, alpha on 2 rows" in res.stdout
    assert "Vx (low-speed model) on 1 row" in res.stdout
    out = _read_csv(tmp_path / "o3.csv")
    assert all(np.isfinite(out[name]).all() for name in ("Fx", "Fy", "Mx", "My", "Mz"))
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + (head + ok).encode())
    assert _run("--tir", str(MF61_TIR), str(bom), "-o", str(tmp_path / "o4.csv")).returncode == 0
    assert "every row written is finite, or nothing is written" in _run("--help").stdout


def test_eval_cli_lenient_fills_and_lists(tmp_path) -> None:
    lines = MF61_TIR.read_text().splitlines(keepends=True)
    damaged = tmp_path / "nopdy2.tir"
    damaged.write_text("".join(ln for ln in lines if not ln.startswith("PDY2")))
    src = tmp_path / "in.csv"
    src.write_text("Fz,kappa,alpha,gamma,Vx,p\n4000,0.05,0.02,0,16,260000\n")
    res = _run("--tir", str(damaged), str(src), "-o", str(tmp_path / "o.csv"))
    assert res.returncode == 1 and "nopdy2.tir: line" in res.stderr and "PDY2" in res.stderr
    assert "--lenient" in res.stderr and not (tmp_path / "o.csv").exists()
    res = _run("--tir", str(damaged), str(src), "-o", str(tmp_path / "o.csv"), "--lenient")
    assert res.returncode == 0, res.stderr
    assert "note: " in res.stderr and "filled with defaults PDY2=-0.15" in res.stderr


def test_cache_guard_clears_a_stale_user_cache_dir(tmp_path) -> None:
    """With NUMBA_CACHE_DIR set, kernels cached from other sources are dropped at import (numba
    keys a cache on its own file only, not on the inlined equations of the other modules)."""
    from numba.core.caching import _CacheLocator

    sub = _CacheLocator.get_suitable_cache_subpath(str(ROOT / "tire_model_ros/model/kernel.py"))
    cache = tmp_path / sub
    cache.mkdir()
    stale = cache / "kernel.forces_loop-215.py311.nbi"
    stale.write_bytes(b"built from older sources")
    (cache / "mf_kernels.sha256").write_text("0" * 64)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    code = "import tire_model_ros.model.jit as j; print(j._sources_digest())"
    out = subprocess.run(
        [sys.executable, "-c", code],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    assert not stale.exists()
    assert (cache / "mf_kernels.sha256").read_text() == out.stdout.strip()
