"""TYDEX measurement files (``.tdx``; TYDEX-Format Release 1.3, Unrau & Zamow 1997).

Blocks start with ``**NAME`` (``**HEADER``, ``**COMMENTS``, ``**CONSTANTS``,
``**MEASURCHANNELS``, ``**MEASURDATA``, ``**MODEL...``, ``**END``); ``!`` starts a comment
line. A channel line is ``NAME  description  unit  factor  [meas. offset  phys. offset]``
(physical value = (value - meas. offset) * factor + phys. offset, in the unit); a constant
line is ``NAME  description  unit  value``. Data rows hold one number per channel,
``NOTAVAIL`` where none was measured.

Channels are mapped by their TYDEX names, in the W axis system (the contact-point axes of
ISO-W / MF-Tyre, so no sign changes): RUNTIME [s], LONGSLIP, SLIPANGL, INCLANGL, FZW (load,
positive), FX or FXW, FYW, MXW, MYW, MZW, INFLPRES (gauge), LONGVEL, TRDTEMP (tread
temperature). A channel given as a constant (e.g. ``INFLPRES`` of a fixed-pressure test) is
used as a constant column. Hub (H) or wheel-centre (C) axis channels are not converted: a file
with FYH but no FYW is refused with that said.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np

from tire_model_ros.atomic import write_atomic
from tire_model_ros.recording.series import WheelSeries

from .base import Columns, Floats, MeasurementError, columns_by_name, parse_rows
from .units import from_si

#: TYDEX channel -> (channel of the recording, quantity, sign W axes -> ISO-W).
CHANNELS: dict[str, tuple[str, str, float]] = {
    "RUNTIME": ("t", "time", 1.0),
    "LONGSLIP": ("kappa", "slip", 1.0),
    "SLIPANGL": ("alpha", "angle", 1.0),
    "INCLANGL": ("gamma", "angle", 1.0),
    "FZW": ("Fz", "force", 1.0),
    "FX": ("Fx", "force", 1.0),
    "FXW": ("Fx", "force", 1.0),
    "FYW": ("Fy", "force", 1.0),
    "MXW": ("Mx", "moment", 1.0),
    "MYW": ("My", "moment", 1.0),
    "MZW": ("Mz", "moment", 1.0),
    "INFLPRES": ("p", "pressure", 1.0),
    "LONGVEL": ("Vx", "speed", 1.0),
    "TRDTEMP": ("T", "temperature", 1.0),
}
# Each entry: the channels of which one must be in the file (a measured force is needed).
REQUIRED = (("RUNTIME",), ("LONGSLIP",), ("SLIPANGL",), ("INCLANGL",), ("FZW",),
            ("FX", "FXW", "FYW", "MZW"))  # fmt: skip
WRITE_UNITS = {"RUNTIME": "s", "LONGSLIP": "-", "SLIPANGL": "deg", "INCLANGL": "deg",
               "FZW": "N", "FX": "N", "FYW": "N", "MXW": "Nm", "MYW": "Nm", "MZW": "Nm",
               "INFLPRES": "kPa", "LONGVEL": "m/s", "TRDTEMP": "degC"}  # fmt: skip
DESCRIPTIONS = {"RUNTIME": "running time", "LONGSLIP": "longitudinal slip",
                "SLIPANGL": "slip angle", "INCLANGL": "inclination angle",
                "FZW": "vertical force", "FX": "longitudinal force", "FYW": "lateral force",
                "MXW": "overturning moment", "MYW": "rolling resistance moment",
                "MZW": "aligning moment", "INFLPRES": "inflation pressure",
                "LONGVEL": "longitudinal velocity", "TRDTEMP": "tread temperature"}  # fmt: skip


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _blocks(path: Path) -> dict[str, list[tuple[int, str]]]:
    """Lines of each ``**`` block (comment and blank lines dropped), with line numbers."""
    try:
        text = path.read_text(encoding="utf-8-sig", errors="strict")
    except UnicodeDecodeError:
        text = path.read_text(encoding="latin-1")  # old rig software writes 8-bit text
    blocks: dict[str, list[tuple[int, str]]] = {}
    current: list[tuple[int, str]] | None = None
    for no, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if s.startswith("**"):
            current = blocks.setdefault(s[2:].split()[0].upper() if s[2:].split() else "", [])
            continue
        if current is not None and s and not s.startswith("!"):
            current.append((no, s))
    return blocks


def _channel_line(path: Path, no: int, line: str) -> tuple[str, str, tuple[float, float, float]]:
    """(name, unit, (factor, meas. offset, phys. offset)) of a MEASURCHANNELS line."""
    fields = line.split()
    nums: list[float] = []
    while len(fields) > 2 and len(nums) < 3 and _is_number(fields[-1]):
        nums.insert(0, float(fields.pop()))
    if len(fields) < 2:
        raise MeasurementError(
            f"{path}: line {no}: a channel line is NAME description unit [factor offsets]: {line!r}"
        )
    factor, meas_off, phys_off = (*nums, *(1.0, 0.0, 0.0)[len(nums) :])
    return fields[0], fields[-1], (factor, meas_off, phys_off)


def _constants(path: Path, lines: list[tuple[int, str]]) -> dict[str, tuple[float, str]]:
    """CONSTANTS name -> (value, unit); non-numeric constants (ids, text) are skipped."""
    out = {}
    for _no, line in lines:
        fields = line.split()
        if len(fields) >= 3 and _is_number(fields[-1]):
            out[fields[0]] = (float(fields[-1]), fields[-2])
    return out


class TydexFormat:
    """The TYDEX measurement file format (see the module text)."""

    name: str = "tydex"
    suffixes: tuple[str, ...] = (".tdx",)
    description: str = "TYDEX measurement file (.tdx), W axes"

    def read(self, path: Path) -> Columns:
        """The file's channels in SI units and ISO-W axes."""
        blocks = _blocks(path)
        for b in ("MEASURCHANNELS", "MEASURDATA"):
            if b not in blocks:
                raise MeasurementError(f"{path}: no **{b} block (not a TYDEX measurement file?)")
        chans = [_channel_line(path, no, ln) for no, ln in blocks["MEASURCHANNELS"]]
        names = [c[0] for c in chans]
        data = parse_rows(path, [(no, ln.split()) for no, ln in blocks["MEASURDATA"]], len(names))
        raw = {}
        for j, (name, _unit, (factor, meas_off, phys_off)) in enumerate(chans):
            raw[name] = (data[:, j] - meas_off) * factor + phys_off
        units = {c[0]: c[1] for c in chans}
        notes = []
        for name, (value, unit) in _constants(path, blocks.get("CONSTANTS", [])).items():
            if name in CHANNELS and name not in raw:
                raw[name], units[name] = np.full(len(data), value), unit
                notes.append(f"{name} from **CONSTANTS: {value:g} {unit}")
        self._check_required(path, raw)
        lines = np.array([no for no, _ in blocks["MEASURDATA"]], np.int64)
        cols = columns_by_name(path, self.name, raw, units, CHANNELS, lines=lines, time="RUNTIME")
        cols.notes += notes
        return cols

    @staticmethod
    def _check_required(path: Path, raw: dict[str, Floats]) -> None:
        for wanted in REQUIRED:
            if any(w in raw for w in wanted):
                continue
            other = [f"{w[:-1]}{a}" for w in wanted for a in "HC" if f"{w[:-1]}{a}" in raw]
            hint = f" ({', '.join(other)} in hub/centre axes is not converted)" if other else ""
            raise MeasurementError(f"{path}: missing channel {'/'.join(wanted)}{hint}")

    def write(self, series: WheelSeries, path: Path, *, overwrite: bool = False) -> list[str]:
        """Write ``series`` as a TYDEX file (W axes, the units of ``WRITE_UNITS``); RUNTIME is
        the time since the first sample. Returns notes (none: every channel has a name)."""
        values = {"RUNTIME": series.t - series.t[0]}
        for name, (channel, _q, _s) in CHANNELS.items():
            v = getattr(series, channel, None) if channel != "t" else None
            if v is not None and name != "FXW":
                values[name] = v
        now = dt.datetime.now(dt.UTC)
        out = ["**HEADER", "RELEASE   Release of TYDEX-format          1.3",
               f"MEASID    measurement id.                 {series.prefix}",
               "SUPPLIER  Data supplier                   tire-model export",
               f"DATE      Date                            {now:%d-%m-%Y}",
               f"CLCKTIME  Clocktime                       {now:%H:%M:%S}",
               "**COMMENTS", f"exported from {series.meta.get('source', 'a recording')}",
               "**MEASURCHANNELS"]  # fmt: skip
        cols = []
        for name, v in values.items():
            unit, quantity = WRITE_UNITS[name], CHANNELS[name][1]
            out.append(f"{name:<10}{DESCRIPTIONS[name]:<30}{unit:<10}1 0 0")
            cols.append(from_si(v, unit, quantity))
        out.append("**MEASURDATA")
        out += [" ".join(repr(float(x)) for x in row) for row in np.column_stack(cols)]
        out.append("**END")
        write_atomic(path, "\n".join(out) + "\n", overwrite=overwrite)
        return []
