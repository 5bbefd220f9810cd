"""What every measurement format shares: the columns a reader returns, the one-line errors,
and the one pipeline from columns to the aligned arrays of a recording.

A format module (``ttc``, ``tydex``, ``csvfile``) reads its file into :class:`Columns`: one
row per sample, the channels already in the project's SI units and ISO-W axes under the
names of :class:`~tire_model_ros.recording.series.WheelSeries` (``t`` [s], ``kappa`` [-],
``alpha``, ``gamma`` [rad], ``Fz``, ``Fx``, ``Fy`` [N], ``Mx``, ``My``, ``Mz`` [N m], ``p`` [Pa
gauge], ``T`` [degC], ``Vx`` [m/s]), each with the file's own name for messages.
:func:`to_series` then does what no format may do differently: leave out the ``--omit``
channels, refuse a channel that is all NaN, drop (and count) the rows with NaN, refuse time
that does not increase and values no tyre can have (a unit the file mislabels), and check the
signs the conversion gave.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from tire_model_ros.recording.series import WheelSeries
from tire_model_ros.vocabulary import (
    DIAGNOSED_CHANNELS,
    FORCE_CHANNELS,
    OPTIONAL_SERIES,
    RIG_PREFIX,
)

Floats = npt.NDArray[np.float64]

DEFAULT_PREFIX = RIG_PREFIX
#: ``--omit`` words (those of ``tire-model simulate``) -> the channels they leave out.
OMITTABLE: dict[str, tuple[str, ...]] = {
    **{word: (channel,) for word, channel in OPTIONAL_SERIES.items()},
    "moments": ("Mx", "My", "Mz"),
}
INPUTS = ("kappa", "alpha", "gamma", "Fz")  # every recording needs them (INTERFACE.md wheel)
FORCES = DIAGNOSED_CHANNELS  # at least one measured
CHANNELS = (*INPUTS, *FORCE_CHANNELS, *OPTIONAL_SERIES.values())
# Sign check windows: near-zero slip, where every tyre's slope has the sign of its axes.
SIGN_ALPHA_RAD = (math.radians(0.3), math.radians(4.0))
SIGN_KAPPA = (0.005, 0.05)
MIN_SIGN_SAMPLES = 20
MIN_SIGN_T = 5.0  # the slope's t statistic below which a sign is not judged


@dataclass(frozen=True)
class Bound:
    """The values a channel can physically hold [SI], shown to the user in ``unit``
    (``shown = SI * factor``); a value outside was read in a unit the file does not use."""

    what: str
    low: float
    high: float
    unit: str
    factor: float = 1.0


DEG = 180.0 / math.pi
#: Beyond these no measured tyre goes: a value outside means the file's unit is wrong (slip
#: angle in rad labelled deg, pressure in Pa labelled kPa, a load in N labelled kN, ...).
PHYSICAL: dict[str, Bound] = {
    "alpha": Bound("a slip angle", -math.pi / 2, math.pi / 2, "deg", DEG),
    "gamma": Bound("an inclination angle", -math.pi / 2, math.pi / 2, "deg", DEG),
    "Fz": Bound("a wheel load", -1e6, 1e6, "N"),
    "Fx": Bound("a tyre force", -1e6, 1e6, "N"),
    "Fy": Bound("a tyre force", -1e6, 1e6, "N"),
    "p": Bound("a gauge inflation pressure", -101325.0, 1e7, "kPa", 1e-3),
    "T": Bound("a tyre temperature", -273.15, 1000.0, "degC"),
    "Vx": Bound("a test speed", -350.0, 350.0, "m/s"),
}


class MeasurementError(ValueError):
    """A measurement file that cannot be imported; the text is one line naming the file, the
    line, row or channel, and what is wrong."""


@dataclass
class Columns:
    """A measurement file's samples in SI units and ISO-W axes (see the module text).

    ``names[c]`` is the file's name of channel ``c`` (for messages), ``notes`` what the reader
    decided (e.g. a constant used for a missing channel), ``lines[i]`` the file line of row
    ``i`` (text formats) or None (binary: rows are counted from 1).
    """

    path: Path
    format: str
    t: Floats
    channels: dict[str, Floats]
    names: dict[str, str]
    lines: npt.NDArray[np.int64] | None = None
    notes: list[str] = field(default_factory=list)

    def where(self, row: int) -> str:
        """``line N`` of row ``row`` in a text file, else ``row N`` (1-based)."""
        if self.lines is not None:
            return f"line {int(self.lines[row])}"
        return f"row {row + 1}"

    def error(self, text: str) -> MeasurementError:
        return MeasurementError(f"{self.path}: {text}")


@dataclass
class ImportReport:
    """What an import read, dropped and checked: printed lines and warnings."""

    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


@dataclass
class Imported:
    """One imported measurement: the wheel's aligned samples and the report."""

    series: WheelSeries
    report: ImportReport


def omitted_channels(omit: Sequence[str]) -> set[str]:
    """The channels ``--omit`` words leave out; ValueError naming an unknown word."""
    out: set[str] = set()
    for word in omit:
        if word not in OMITTABLE:
            raise MeasurementError(
                f"cannot omit {word!r}: omittable channels are {', '.join(OMITTABLE)}"
            )
        out.update(OMITTABLE[word])
    return out


def _check_present(cols: Columns, used: Sequence[str]) -> None:
    for c in ("t", *INPUTS):
        if c != "t" and c not in cols.channels:
            raise cols.error(f"missing channel {cols.names.get(c, c)}")
    if not any(c in used for c in FORCES):
        raise cols.error(f"no measured force: none of {', '.join(FORCES)} in the file")
    for c in ("t", *used):
        x = cols.t if c == "t" else cols.channels[c]
        if len(x) != len(cols.t):
            raise cols.error(
                f"channel {cols.names.get(c, c)}: {len(x)} rows, time has {len(cols.t)}"
            )
        if len(x) and not np.isfinite(x).any():
            hint = [w for w, chans in OMITTABLE.items() if c in chans]
            extra = f" (leave it out with --omit {hint[0]})" if hint else ""
            raise cols.error(f"channel {cols.names.get(c, c)}: every value is NaN{extra}")


def _drop_nan_rows(cols: Columns, used: Sequence[str]) -> tuple[npt.NDArray[np.bool_], str]:
    """Rows whose time and used channels are all finite, and the dropped count by channel."""
    keep = np.isfinite(cols.t)
    counts = {"t": int(np.sum(~keep))}
    for c in used:
        bad = ~np.isfinite(cols.channels[c])
        counts[c] = int(np.sum(bad))
        keep &= ~bad
    dropped = int(np.sum(~keep))
    if dropped == 0:
        return keep, "no rows with NaN"
    by = ", ".join(f"{cols.names.get(c, c)} {n}" for c, n in counts.items() if n)
    return keep, f"dropped {dropped} of {len(keep)} rows with NaN (NaN in {by})"


def _check_time(cols: Columns, keep: npt.NDArray[np.bool_]) -> None:
    rows = np.flatnonzero(keep)
    t = cols.t[rows]
    bad = np.flatnonzero(np.diff(t) <= 0)
    if len(bad):
        i = int(bad[0])
        raise cols.error(
            f"{cols.where(int(rows[i + 1]))}: time {cols.names.get('t', 't')} = "
            f"{t[i + 1]:.9g} s does not increase (previous row {t[i]:.9g} s)"
        )


def _check_physical(cols: Columns, keep: npt.NDArray[np.bool_], used: Sequence[str]) -> None:
    """Refuse the first value (in file order) no tyre can have: its unit must be wrong."""
    rows = np.flatnonzero(keep)
    for c in used:
        bound = PHYSICAL.get(c)
        if bound is None:
            continue
        x = cols.channels[c][rows]
        bad = np.flatnonzero((x < bound.low) | (x > bound.high))
        if len(bad):
            i = int(bad[0])
            name = cols.names.get(c, c)
            raise cols.error(
                f"{cols.where(int(rows[i]))}: channel {name}: {bound.what} of "
                f"{x[i] * bound.factor:.6g} {bound.unit} (ISO-W, converted) is outside "
                f"{bound.low * bound.factor:.6g}..{bound.high * bound.factor:.6g} {bound.unit}: "
                f"is the file's unit of {name} right?"
            )


def _slope(x: Floats, y: Floats) -> tuple[float, float]:
    """Least-squares slope of y on x (with intercept) and its t statistic (slope / its
    standard error; about N(0, 1) when y does not follow x)."""
    xc, yc = x - x.mean(), y - y.mean()
    sxx, syy = float(np.dot(xc, xc)), float(np.dot(yc, yc))
    slope = float(np.dot(xc, yc)) / sxx
    r2 = min(slope * slope * sxx / syy, 1.0) if syy > 0 else 1.0
    t = math.inf if r2 >= 1.0 else abs(slope) * math.sqrt(sxx * (len(x) - 2) / (syy * (1 - r2)))
    return slope, t


@dataclass(frozen=True)
class SignCheck:
    """Near zero slip every tyre's force rises or falls with the slip as its axes say."""

    name: str  # e.g. "Fy against alpha"
    force: str  # channel of the WheelSeries
    slip: str  # "alpha" or "kappa"
    expect: int  # sign of the slope in ISO-W
    what: str  # the rule in words


SIGN_CHECKS = (
    SignCheck("Fy against alpha", "Fy", "alpha", -1, "positive slip angle, negative Fy"),
    SignCheck("Mz against alpha", "Mz", "alpha", 1, "positive slip angle, positive aligning Mz"),
    SignCheck("Fx against kappa", "Fx", "kappa", 1, "positive slip ratio, positive Fx"),
)


def _sign_check(check: SignCheck, s: WheelSeries) -> tuple[str, str | None]:
    """One slope-sign check on the pure-slip samples near zero: (line, warning or None)."""
    y = getattr(s, check.force)
    if check.slip == "alpha":
        x, window, pure = s.alpha, SIGN_ALPHA_RAD, np.abs(s.kappa) < SIGN_KAPPA[0]
    else:
        x, window, pure = s.kappa, SIGN_KAPPA, np.abs(s.alpha) < SIGN_ALPHA_RAD[0]
    near = pure & (np.abs(x) > window[0]) & (np.abs(x) < window[1]) & np.isfinite(y)
    if near.sum() < MIN_SIGN_SAMPLES or not (np.any(x[near] > 0) and np.any(x[near] < 0)):
        return f"sign check {check.name}: not checked (no sweep through zero slip)", None
    slope, t = _slope(x[near], y[near])
    if t < MIN_SIGN_T:  # slip noise around zero (a cornering run's SL): no slope to judge
        return (
            f"sign check {check.name}: not checked ({check.force} does not follow {check.slip} "
            f"near zero slip: slope t = {t:.1f} on {int(near.sum())} samples)"
        ), None
    word = "falls" if slope < 0 else "rises"
    line = f"sign check {check.name}: {word} near zero slip on {int(near.sum())} samples"
    if np.sign(slope) == check.expect:
        return line + f", as ISO-W has it ({check.what})", None
    return line + " -- NOT as ISO-W has it", (
        f"{check.name.split()[0]} {word} with {check.slip} near zero slip, but ISO-W has "
        f"{check.what}: the file's axes or signs are not those the importer assumed; "
        "check the file before fitting"
    )


def sign_checks(s: WheelSeries) -> tuple[list[str], list[str]]:
    """Lines and warnings of the sign checks on the imported (ISO-W) data: positive slip angle
    gives negative Fy and positive Mz, positive slip ratio positive Fx, load positive."""
    lines, warnings = [], []
    for check in SIGN_CHECKS:
        if getattr(s, check.force) is None:
            continue
        line, warn = _sign_check(check, s)
        lines.append(line)
        if warn:
            warnings.append(warn)
    share = float(np.mean(s.Fz > 0)) if len(s) else 1.0
    lines.append(f"sign check Fz: positive (load) on {100 * share:.1f} % of the rows")
    if share < 0.5:
        warnings.append(
            "Fz is negative on most rows: ISO-W load is positive; the file's vertical axis or "
            "sign is not the one the importer assumed"
        )
    return lines, warnings


def to_series(cols: Columns, *, omit: Sequence[str] = (), prefix: str = DEFAULT_PREFIX) -> Imported:
    """The recording of one wheel from a file's columns (see the module text).

    Raises
    ------
    MeasurementError
        A missing channel, a channel that is all NaN, time that does not increase, no row left,
        a value outside what a tyre can have (``PHYSICAL``: the file's unit is wrong).
    """
    left_out = omitted_channels(omit)
    used = [c for c in CHANNELS if c in cols.channels and c not in left_out]
    _check_present(cols, used)
    keep, nan_line = _drop_nan_rows(cols, used)
    if not keep.any():
        raise cols.error("no row without NaN left")
    _check_time(cols, keep)
    _check_physical(cols, keep, used)
    t = cols.t[keep]
    report = ImportReport()
    if t[0] < 0:  # stamps of a recording start at or after 0
        report.lines.append(f"time shifted by {-t[0]:.6g} s so that it starts at 0")
        t = t - t[0]
    data = {c: cols.channels[c][keep] for c in used}
    series = WheelSeries(
        prefix,
        t,
        data["kappa"],
        data["alpha"],
        data["gamma"],
        data["Fz"],
        **{c: data.get(c) for c in ("p", "T", "Vx", "Fx", "Fy", "Mx", "My", "Mz")},
        meta={"source": str(cols.path), "format": cols.format, "rows_read": len(keep),
              "rows_dropped_nan": int(np.sum(~keep))},
    )  # fmt: skip
    names = ", ".join(f"{c}<-{cols.names.get(c, c)}" for c in ("t", *used))
    report.lines.insert(0, f"read {cols.path} ({cols.format}): {len(keep)} rows; {names}")
    report.lines += [*cols.notes, nan_line]
    if left_out & set(cols.channels):
        report.lines.append(
            f"left out (--omit): {', '.join(sorted(left_out & set(cols.channels)))}"
        )
    checks, warnings = sign_checks(series)
    report.lines += checks
    report.warnings += warnings
    return Imported(series, report)


def columns_by_name(
    path: Path,
    fmt: str,
    raw: Mapping[str, Floats],
    units: Mapping[str, str],
    mapping: Mapping[str, tuple[str, str, float]],
    *,
    lines: npt.NDArray[np.int64] | None = None,
    time: str,
) -> Columns:
    """Columns from a file's named raw channels: ``mapping[file name] = (channel, quantity,
    sign)``; each converted from its unit (``units``) to SI and multiplied by ``sign``.

    Raises
    ------
    MeasurementError
        The time channel is missing; a mapped channel has an unknown unit.
    """
    from .units import UnitError, to_si

    if time not in raw:
        raise MeasurementError(f"{path}: missing channel {time} (the time)")
    out: dict[str, Floats] = {}
    names: dict[str, str] = {}
    for name, (channel, quantity, sign) in mapping.items():
        if name not in raw or channel in out:
            continue
        try:
            out[channel] = sign * to_si(raw[name], units.get(name, ""), quantity)
        except UnitError as exc:
            raise MeasurementError(f"{path}: channel {name}: {exc}") from None
        names[channel] = name
    t = out.pop("t")
    return Columns(path, fmt, t, out, names, lines)


def parse_rows(
    path: Path,
    rows: Sequence[tuple[int, Sequence[str]]],
    ncols: int,
    missing: frozenset[str] = frozenset({"", "nan", "NaN", "NAN", "NOTAVAIL"}),
) -> Floats:
    """The numbers of text rows ``(line number, fields)``: an (n, ncols) array; a field in
    ``missing`` is NaN.

    Raises
    ------
    MeasurementError
        A row with another number of fields, or a field that is not a number (names the line
        and the column number).
    """
    for line_no, fields in rows:
        if len(fields) != ncols:
            raise MeasurementError(
                f"{path}: line {line_no}: {len(fields)} values, expected {ncols}"
            )
    try:  # fast path: every field a number
        return np.array([f for _, f in rows], dtype=np.float64).reshape(len(rows), ncols)
    except ValueError:
        pass
    out = np.empty((len(rows), ncols))
    for i, (line_no, fields) in enumerate(rows):
        for j, f in enumerate(fields):
            f = f.strip()
            try:
                out[i, j] = math.nan if f in missing else float(f)
            except ValueError:
                raise MeasurementError(
                    f"{path}: line {line_no}: column {j + 1}: {f!r} is not a number"
                ) from None
    return out
