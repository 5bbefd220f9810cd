"""The operating envelope a fit's data covered, carried inside the .tir it wrote.

A fitted model is data where its recordings reached and extrapolation elsewhere. ``tire-model
fit`` (and ``fit --extend``) write, beside the coefficients, which conditions the fitted data
covered and which source informed them; ``tire-model eval`` and the node count the inputs that
leave it. The envelope is a set of cells over load Fz [N], gauge pressure p [Pa] and tyre
temperature T [degC], each cell ``FZ_STEP x P_STEP x T_STEP`` centred on multiples of the steps
(cell index = round(x / step)). A cell is covered where the fit had slip samples in it; the
gaps between covered cells along one axis (a load between two fitted loads, a temperature
between two fitted temperatures) are filled, so interpolation stays inside and extrapolation
leaves. ``T_STEP = 0``: the fitted data had no temperature (the envelope is in load and
pressure only).

In the .tir it is the section ``[FIT_ENVELOPE]``, a table in the ``[SHAPE]`` style that other
tools skip (the reader keeps unknown sections verbatim; MFeval reads only ``KEY = value``
lines)::

    [FIT_ENVELOPE]
    $ ...comment lines...
    FZ_STEP = 675.2
    P_STEP = 20000
    T_STEP = 10
    {fz_from fz_to p t source}
     2701 6752 220000 30 1

Each row is a run of cells in load, from the cell centred on ``fz_from`` to the one centred on
``fz_to`` [N], at the pressure and temperature cells centred on ``p`` [Pa] and ``t`` [degC];
``source`` says which data informed it: 1 a rig (measurements), 2 a simulation, 3 both (where
both reach the rig's data are fitted, the simulation only compared).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from .tir import RawSection, TirData

__all__ = ["RIG", "SECTION", "SIMULATION", "SOURCE_NAMES", "Envelope"]

F64 = npt.NDArray[np.float64]
Cell = tuple[int, int, int]

SECTION = "FIT_ENVELOPE"
RIG = 1  # source bits
SIMULATION = 2
SOURCE_NAMES = {RIG: "rig", SIMULATION: "simulation", RIG | SIMULATION: "rig and simulation"}
_HEADER = "{fz_from fz_to p t source}"
_NO_CELL = 2**40  # the index of a value that is not finite
_STEPS = ("FZ_STEP", "P_STEP", "T_STEP")
_COMMENT = (
    "$ tire_model_ros: the operating conditions the fitted data covered (other tools skip it).",
    "$ Cells FZ_STEP [N] x P_STEP [Pa gauge] x T_STEP [degC] centred on multiples of the steps;",
    "$ a row: the load cells fz_from..fz_to [N] at the cells of pressure p and temperature t;",
    "$ source 1 = rig, 2 = simulation, 3 = both. T_STEP = 0: no temperature in the data.",
)


@dataclass(frozen=True)
class Envelope:
    """Covered cells: ``cells[(i_Fz, i_p, i_T)]`` is the source bits (RIG, SIMULATION)."""

    fz_step_N: float
    p_step_Pa: float
    T_step_K: float  # 0: temperature not tracked
    cells: Mapping[Cell, int] = field(default_factory=dict)

    # -- queries ---------------------------------------------------------------------------
    def index(self, Fz: F64, p: F64, T: F64) -> npt.NDArray[np.int64]:
        """Cell indices, one row (i_Fz, i_p, i_T) per sample."""
        cols = [
            np.rint(np.asarray(Fz, dtype=np.float64) / self.fz_step_N),
            np.rint(np.asarray(p, dtype=np.float64) / self.p_step_Pa),
            np.rint(np.asarray(T, dtype=np.float64) / self.T_step_K)
            if self.T_step_K > 0
            else np.zeros(np.shape(Fz)),
        ]
        finite = np.all(np.isfinite(cols), axis=0)
        out = np.where(finite, cols, _NO_CELL).astype(np.int64)  # not finite: in no cell
        return np.asarray(out.T, dtype=np.int64)

    def contains(self, Fz: F64, p: F64, T: F64) -> npt.NDArray[np.bool_]:
        """Whether each sample (Fz [N], p [Pa gauge], T [degC]; arrays of one shape) lies in
        a covered cell."""
        idx = self.index(Fz, p, T)
        return np.fromiter((tuple(r) in self.cells for r in idx.tolist()), bool, len(idx))

    def contains_one(self, Fz: float, p: float, T: float) -> bool:
        """One sample (the node's path: no arrays)."""
        try:
            k = round(T / self.T_step_K) if self.T_step_K > 0 else 0
            return (round(Fz / self.fz_step_N), round(p / self.p_step_Pa), k) in self.cells
        except (ValueError, OverflowError):  # NaN or inf: in no cell
            return False

    def share(self, source: int) -> float:
        """Fraction of the covered cells that ``source`` informed."""
        if not self.cells:
            return 0.0
        return sum(1 for s in self.cells.values() if s & source) / len(self.cells)

    def bounds(self, axis: int) -> tuple[float, float]:
        """(lowest, highest) cell centre along an axis (0 Fz [N], 1 p [Pa], 2 T [degC])."""
        step = (self.fz_step_N, self.p_step_Pa, self.T_step_K)[axis]
        values = [c[axis] for c in self.cells]
        return min(values) * step, max(values) * step

    # -- construction ----------------------------------------------------------------------
    @classmethod
    def from_samples(
        cls,
        Fz: F64,
        p: F64,
        T: F64 | None,
        source: int,
        steps: tuple[float, float, float],
        min_samples: int = 50,
    ) -> Envelope:
        """Cells holding at least ``min_samples`` of the samples (Fz [N], p [Pa], T [degC] or
        None: no temperature), all marked ``source``."""
        fz_step, p_step, T_step = steps
        env = cls(fz_step, p_step, T_step if T is not None else 0.0)
        idx = env.index(Fz, p, np.zeros(np.shape(Fz)) if T is None else T)
        if len(idx) == 0:
            return env
        cells, counts = np.unique(idx, axis=0, return_counts=True)
        kept = {
            (int(c[0]), int(c[1]), int(c[2])): source
            for c, n in zip(cells.tolist(), counts.tolist(), strict=True)
            if n >= min_samples and max(c) < _NO_CELL
        }
        return cls(fz_step, p_step, env.T_step_K, kept)

    def union(self, other: Envelope) -> Envelope:
        """Both envelopes' cells, sources or-ed (same steps needed)."""
        if (self.fz_step_N, self.p_step_Pa) != (other.fz_step_N, other.p_step_Pa):
            raise ValueError("envelopes on different grids cannot be joined")
        if self.T_step_K != other.T_step_K and self.cells and other.cells:
            raise ValueError("envelopes on different temperature grids cannot be joined")
        cells = dict(self.cells)
        for c, s in other.cells.items():
            cells[c] = cells.get(c, 0) | s
        T_step = self.T_step_K if self.cells else other.T_step_K
        return Envelope(self.fz_step_N, self.p_step_Pa, T_step, cells)

    def filled(self) -> Envelope:
        """Gaps between covered cells along each axis filled: what the fit interpolates is
        inside, what it extrapolates is not. A filled cell's source is what informed both
        sides (a rig-and-simulation cell and a simulated one: simulation between them), else
        either side's."""
        cells = dict(self.cells)
        for axis in range(3):
            lines: dict[tuple[int, int], list[int]] = {}
            for c in cells:
                rest = tuple(v for i, v in enumerate(c) if i != axis)
                lines.setdefault((rest[0], rest[1]), []).append(c[axis])
            for rest, values in lines.items():
                values.sort()
                for a, b in itertools.pairwise(values):
                    lo, hi = cells[_put(rest, axis, a)], cells[_put(rest, axis, b)]
                    src = (lo & hi) or (lo | hi)
                    for v in range(a + 1, b):
                        cells[_put(rest, axis, v)] = src
        return Envelope(self.fz_step_N, self.p_step_Pa, self.T_step_K, cells)

    # -- the .tir section ------------------------------------------------------------------
    def rows(self) -> list[tuple[float, float, float, float, int]]:
        """Runs of cells in load: (fz_from, fz_to [N], p [Pa], t [degC], source)."""
        out = []
        by_line: dict[tuple[int, int, int], list[int]] = {}
        for (i, j, k), s in self.cells.items():
            by_line.setdefault((j, k, s), []).append(i)
        for (j, k, s), loads in sorted(by_line.items()):
            for lo, hi in _runs(sorted(loads)):
                out.append(
                    (lo * self.fz_step_N, hi * self.fz_step_N, j * self.p_step_Pa,
                     k * self.T_step_K, s)
                )  # fmt: skip
        return out

    def section(self, after: str = "TEMPERATURE_RANGE") -> RawSection:
        """The ``[FIT_ENVELOPE]`` section of a .tir."""
        steps = (self.fz_step_N, self.p_step_Pa, self.T_step_K)
        lines = [*_COMMENT, *(f"{k:<24} = {_num(v)}" for k, v in zip(_STEPS, steps, strict=True))]
        lines.append(_HEADER)
        lines += [" " + " ".join(_num(v) for v in row) for row in self.rows()]
        return RawSection(SECTION, after, tuple(lines))

    def into(self, tir: TirData) -> TirData:
        """``tir`` with this envelope as its only ``[FIT_ENVELOPE]`` section."""
        import dataclasses

        raw = tuple(r for r in tir.raw_sections if r.name != SECTION)
        return dataclasses.replace(tir, raw_sections=(*raw, self.section()))

    @classmethod
    def from_tir(cls, tir: TirData) -> Envelope | None:
        """The envelope of a .tir (None when it has no ``[FIT_ENVELOPE]``).

        Raises
        ------
        ValueError
            naming the file, the section and the row for a malformed table.
        """
        raw = next((r for r in tir.raw_sections if r.name == SECTION), None)
        if raw is None:
            return None
        where = f"{tir.path or '<tir>'}: [{SECTION}]"
        steps: dict[str, float] = {}
        cells: dict[Cell, int] = {}
        table = False
        for n, line in enumerate(raw.lines, start=1):
            text = line.split("$", 1)[0].strip()
            if not text:
                continue
            if text.startswith("{"):
                table = True
                continue
            if not table:
                key, _, value = text.partition("=")
                steps[key.strip().upper()] = _number(value, f"{where} line {n} of the section")
                continue
            _read_row(text, f"{where} row at line {n} of the section", steps, cells)
        missing = [k for k in _STEPS if k not in steps]
        if missing:
            raise ValueError(f"{where}: {', '.join(missing)} missing")
        if steps["FZ_STEP"] <= 0 or steps["P_STEP"] <= 0 or steps["T_STEP"] < 0:
            raise ValueError(f"{where}: FZ_STEP, P_STEP must be > 0 and T_STEP >= 0")
        return cls(steps["FZ_STEP"], steps["P_STEP"], steps["T_STEP"], cells)


def _runs(values: list[int]) -> list[tuple[int, int]]:
    """Runs of consecutive integers in a sorted list: (first, last) of each."""
    out: list[tuple[int, int]] = []
    for v in values:
        if out and v == out[-1][1] + 1:
            out[-1] = (out[-1][0], v)
        else:
            out.append((v, v))
    return out


def _put(rest: tuple[int, int], axis: int, value: int) -> Cell:
    a, b = rest
    return ((value, a, b), (a, value, b), (a, b, value))[axis]


def _num(v: float) -> str:
    v = float(v)
    return str(int(v)) if v.is_integer() else f"{v:.10g}"


def _number(text: str, where: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"{where}: {text.strip()!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{where}: {text.strip()!r} is not finite")
    return v


def _read_row(text: str, where: str, steps: Mapping[str, float], cells: dict[Cell, int]) -> None:
    """One table row into ``cells``."""
    parts = text.split()
    if len(parts) != 5:
        raise ValueError(f"{where}: expected 5 numbers (fz_from fz_to p t source), got {text!r}")
    if "FZ_STEP" not in steps or "P_STEP" not in steps or "T_STEP" not in steps:
        raise ValueError(f"{where}: the steps must come before the table")
    fz0, fz1, p, t, s = (_number(x, where) for x in parts)
    if int(s) not in SOURCE_NAMES or s != int(s):
        raise ValueError(f"{where}: source {parts[4]!r} is not 1, 2 or 3")
    i0, i1 = round(fz0 / steps["FZ_STEP"]), round(fz1 / steps["FZ_STEP"])
    j = round(p / steps["P_STEP"])
    k = round(t / steps["T_STEP"]) if steps["T_STEP"] > 0 else 0
    if i1 < i0:
        raise ValueError(f"{where}: fz_to {fz1:g} below fz_from {fz0:g}")
    for i in range(i0, i1 + 1):
        cells[(i, j, k)] = cells.get((i, j, k), 0) | int(s)
