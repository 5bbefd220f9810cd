"""Seeded fuzz of the reference .tir files: a damaged file is refused or gives a tyre.

Mutants of every reference file (cut short, a flipped bit, a duplicated, deleted or swapped
line, two values exchanged, a huge or tiny value, a mistyped section header; one to three of
them) must never raise anything but ``TirError`` (naming the file and the line), and what is
accepted must be a tyre on its grid (``check_model``) and make ``tire-model eval`` either write
finite rows only or refuse and write nothing, with the limits on and off.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import random
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
from conftest import DEFAULT_TIR, TIR_DIR

from tire_model_ros.cli import main
from tire_model_ros.model import TireModel, TirError, read_tir
from tire_model_ros.model.check import check_model

SOURCES = [*sorted(TIR_DIR.glob("*.tir")), DEFAULT_TIR]
SEED = 20261202
N_MUTANTS = 300
_ASSIGN = re.compile(rb"^(\s*[A-Za-z_][A-Za-z0-9_]*\s*=\s*)([^$!\r\n]*?)(\s*(?:[$!].*)?)$")
_HEADER = re.compile(rb"^\s*\[([A-Za-z0-9_ ]+)\]")
HUGE = [b"1e308", b"-1e308", b"1e300", b"-9.9e307", b"1e-300", b"-1e-300", b"1e30", b"-1e30"]


def _lines_where(lines: list[bytes], pattern: re.Pattern[bytes]) -> list[int]:
    return [i for i, line in enumerate(lines) if pattern.match(line)]


def cut(data: bytes, rng: random.Random) -> bytes:
    return data[: rng.randrange(len(data))]


def flip(data: bytes, rng: random.Random) -> bytes:
    i = rng.randrange(len(data))
    return data[:i] + bytes([data[i] ^ (1 << rng.randrange(8))]) + data[i + 1 :]


def _line_op(op: Callable[[list[bytes], random.Random], None]):
    def mutate(data: bytes, rng: random.Random) -> bytes:
        lines = data.split(b"\n")
        op(lines, rng)
        return b"\n".join(lines)

    mutate.__name__ = op.__name__
    return mutate


@_line_op
def duplicate(lines: list[bytes], rng: random.Random) -> None:
    i = rng.randrange(len(lines))
    lines.insert(i, lines[i])


@_line_op
def delete(lines: list[bytes], rng: random.Random) -> None:
    del lines[rng.randrange(len(lines))]


@_line_op
def swap_lines(lines: list[bytes], rng: random.Random) -> None:
    i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
    lines[i], lines[j] = lines[j], lines[i]


@_line_op
def swap_values(lines: list[bytes], rng: random.Random) -> None:
    where = _lines_where(lines, _ASSIGN)
    i, j = rng.choice(where), rng.choice(where)
    a, b = _ASSIGN.match(lines[i]), _ASSIGN.match(lines[j])
    assert a is not None and b is not None
    lines[i] = a.group(1) + b.group(2) + a.group(3)
    lines[j] = b.group(1) + a.group(2) + b.group(3)


@_line_op
def huge_value(lines: list[bytes], rng: random.Random) -> None:
    i = rng.choice(_lines_where(lines, _ASSIGN))
    m = _ASSIGN.match(lines[i])
    assert m is not None
    lines[i] = m.group(1) + rng.choice(HUGE) + m.group(3)


@_line_op
def mistype_header(lines: list[bytes], rng: random.Random) -> None:
    i = rng.choice(_lines_where(lines, _HEADER))
    name = bytearray(lines[i].strip()[1:-1])
    k = rng.randrange(len(name))
    kind = rng.randrange(4)
    if kind == 0:
        del name[k]
    elif kind == 1:
        name[k] = rng.choice(b"ABCDEFGHIJKLMNOPQRSTUVWXYZ_")
    elif kind == 2:
        name.insert(k, rng.choice(b"ABCDEFGHIJKLMNOPQRSTUVWXYZ"))
    else:
        name = bytearray(bytes(name).replace(b"_", b"-", 1))
    lines[i] = b"[" + bytes(name) + b"]"


OPERATORS = [cut, flip, duplicate, delete, swap_lines, swap_values, huge_value, mistype_header]


def _inputs_csv(path: Path, rng: np.random.Generator) -> None:
    """Rows over and beyond any file's ranges (loads to 20 kN, |alpha| to 1 rad, reversing)."""
    n = 40
    cols = {
        "Fz": rng.uniform(0.0, 2e4, n),
        "kappa": rng.uniform(-1.5, 1.5, n),
        "alpha": rng.uniform(-1.0, 1.0, n),
        "gamma": rng.uniform(-0.2, 0.2, n),
        "Vx": rng.uniform(-30.0, 60.0, n),
        "p": rng.uniform(1e5, 5e5, n),
        "T": rng.uniform(-10.0, 120.0, n),
    }
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(cols)
        writer.writerows(zip(*(v.tolist() for v in cols.values()), strict=True))


def _eval(tir: Path, inputs: Path, out: Path, *flags: str) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(["eval", "--tir", str(tir), str(inputs), "-o", str(out), *flags])
    return code, err.getvalue()


def _all_finite(path: Path) -> bool:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))[1:]
    return bool(rows) and all(math.isfinite(float(cell)) for row in rows for cell in row)


def test_mutants_are_refused_or_are_tyres(tmp_path):
    rng = random.Random(SEED)
    inputs = tmp_path / "in.csv"
    _inputs_csv(inputs, np.random.default_rng(SEED))
    sources = [p.read_bytes() for p in SOURCES]
    problems: list[str] = []
    refused = accepted = 0
    for i in range(N_MUTANTS):
        k = rng.randrange(len(sources))
        ops = [rng.choice(OPERATORS) for _ in range(rng.randint(1, 3))]
        data = sources[k]
        for op in ops:
            data = op(data, rng)
        label = f"mutant {i} of {SOURCES[k].name} by {[op.__name__ for op in ops]}"
        path = tmp_path / f"m{i}.tir"
        path.write_bytes(data)
        try:
            tir = read_tir(path)
        except TirError as exc:
            refused += 1
            if str(path) not in str(exc) or exc.line is None:
                problems.append(f"{label}: refusal without file and line: {exc}")
            continue
        except Exception as exc:  # a traceback: the thing this test is for
            problems.append(f"{label}: {type(exc).__name__}: {exc}")
            continue
        accepted += 1
        if (fault := check_model(TireModel(tir))) is not None:
            problems.append(f"{label}: accepted but not a tyre: {fault}")
        for flags in ((), ("--no-limits",)):
            out = tmp_path / f"m{i}{len(flags)}.csv"
            code, err = _eval(path, inputs, out, *flags)
            if code == 0 and not _all_finite(out):
                problems.append(f"{label}: eval {flags} wrote non-finite rows")
            elif code == 1 and (out.exists() or "non-finite" not in err):
                problems.append(f"{label}: eval {flags} failed without saying why: {err}")
            elif code not in (0, 1):
                problems.append(f"{label}: eval {flags} exit {code}: {err}")
    assert not problems, "\n".join(problems[:20])
    # the fuzz reaches both outcomes: damage is caught, and harmless edits still load
    assert refused >= N_MUTANTS // 3 and accepted >= N_MUTANTS // 10, (refused, accepted)
