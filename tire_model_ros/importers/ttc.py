"""FSAE Tire Test Consortium (TTC, Calspan) run files: MATLAB ``.mat`` and ASCII ``.dat``.

The layout as the consortium distributes it:

- ``.mat``: one column variable per channel (``ET``, ``V``, ``N``, ``SA``, ``IA``, ``RL``,
  ``RE``, ``P``, ``FX``, ``FY``, ``FZ``, ``MX``, ``MZ``, ``NFX``, ``NFY``, ``RST``, ``TSTI``,
  ``TSTC``, ``TSTO``, ``AMBTMP``, ``SR``, ``SL``, ...) and a ``channel`` struct whose ``name``
  and ``units`` fields are cell arrays of the channel names and their units;
- ``.dat``: title line(s), a line of channel names, a line of their units, then one row per
  sample (tab separated; units such as ``deg C`` hold a blank).

Units are read from the file (the consortium ships SI/metric and USCS sets: N or lb, N-m or
ft-lb, kPa or psi, kph or mph, deg C or deg F) and converted to SI. The TTC's axes are SAE;
they become the ISO-W axes of the ``.tir`` files (INTERFACE.md): alpha = -SA, gamma = IA,
kappa = SL (SR, the rig's control slip, only when SL is absent), Fz = -FZ, Fx = FX,
Fy = -FY, Mx = MX, Mz = -MZ. P is gauge pressure, V the road speed, and the temperature is
the centre tread surface TSTC. The same table, read backwards, writes such files
(:meth:`TtcFormat.write`).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from tire_model_ros.atomic import write_atomic
from tire_model_ros.recording.series import WheelSeries

from .base import Columns, Floats, MeasurementError, columns_by_name, parse_rows
from .units import from_si

#: TTC channel -> (channel of the recording, quantity, sign SAE -> ISO-W), in reading priority.
CHANNELS: dict[str, tuple[str, str, float]] = {
    "ET": ("t", "time", 1.0),
    "SA": ("alpha", "angle", -1.0),
    "IA": ("gamma", "angle", 1.0),
    "SL": ("kappa", "slip", 1.0),
    "SR": ("kappa", "slip", 1.0),
    "FZ": ("Fz", "force", -1.0),
    "FX": ("Fx", "force", 1.0),
    "FY": ("Fy", "force", -1.0),
    "MX": ("Mx", "moment", 1.0),
    "MZ": ("Mz", "moment", -1.0),
    "P": ("p", "pressure", 1.0),
    "V": ("Vx", "speed", 1.0),
    "TSTC": ("T", "temperature", 1.0),
}
REQUIRED = ("ET", "SA", "IA", "FZ", "FX", "FY")
MIN_NAMES_KNOWN = 3  # TTC names beside ET that make a .dat line the line of channel names
#: Units the exporter writes (the consortium's SI/metric set).
WRITE_UNITS = {"ET": "s", "V": "kph", "SA": "deg", "IA": "deg", "P": "kPa", "FX": "N", "FY": "N",
               "FZ": "N", "MX": "N-m", "MZ": "N-m", "TSTC": "deg C", "SL": "none"}  # fmt: skip


def _strings(obj: object) -> list[str]:
    """The strings of a MATLAB cell array / char array as scipy.io.loadmat returns it."""
    if isinstance(obj, str):
        return [obj]
    arr = np.asarray(obj)
    if arr.dtype.kind in "US":
        return [str(x) for x in arr.ravel()]
    out: list[str] = []
    for item in arr.ravel():
        got = _strings(item)
        out.append(got[0] if len(got) == 1 else "".join(got))
    return out


def _read_mat(path: Path) -> tuple[dict[str, Floats], dict[str, str]]:
    from scipy.io import loadmat

    try:
        mat = loadmat(str(path))
    except NotImplementedError:
        raise MeasurementError(
            f"{path}: a MATLAB v7.3 (HDF5) file; save it as -v7 or use the TTC .dat file"
        ) from None
    except Exception as exc:  # scipy raises several types on damaged or foreign files
        raise MeasurementError(f"{path}: not a readable MATLAB .mat file ({exc})") from None
    if "channel" not in mat:
        raise MeasurementError(
            f"{path}: no 'channel' struct (names and units of the channels): "
            "not a TTC run file, the units cannot be known"
        )
    ch = np.asarray(mat["channel"]).ravel()[0]
    fields = ch.dtype.names or ()
    if "name" not in fields or "units" not in fields:
        raise MeasurementError(f"{path}: channel struct without 'name' and 'units' fields")
    names, units = _strings(ch["name"]), _strings(ch["units"])
    if len(names) != len(units):
        raise MeasurementError(f"{path}: channel struct: {len(names)} names, {len(units)} units")
    raw: dict[str, Floats] = {}
    for name in names:
        if name in mat:
            try:
                raw[name] = np.asarray(mat[name], dtype=np.float64).ravel()
            except (TypeError, ValueError):
                raise MeasurementError(f"{path}: channel {name}: not numeric") from None
    return raw, dict(zip(names, units, strict=True))


def _split(line: str) -> list[str]:
    """Fields of a .dat line: tab separated (units hold blanks), else blank separated."""
    return line.rstrip("\r\n").split("\t") if "\t" in line else line.split()


def _is_names_line(line: str) -> bool:
    """A .dat line of channel names: ET and at least ``MIN_NAMES_KNOWN`` other TTC names (a
    file missing one required channel is still found, and that channel named)."""
    fields = {f.strip() for f in _split(line)}
    return "ET" in fields and len(fields & set(CHANNELS)) > MIN_NAMES_KNOWN


def _read_dat(path: Path) -> tuple[dict[str, Floats], dict[str, str], np.ndarray, int]:
    """Channels, units, each row's line number and the line number of the names."""
    try:
        text = path.read_text(encoding="utf-8-sig", errors="strict")
    except UnicodeDecodeError as exc:
        raise MeasurementError(f"{path}: not a text file ({exc.reason})") from None
    lines = text.splitlines()
    head = next((i for i, ln in enumerate(lines[:20]) if _is_names_line(ln)), None)
    if head is None or head + 1 >= len(lines):
        raise MeasurementError(
            f"{path}: no line of TTC channel names (ET, SA, FZ, ...) followed by units "
            "in the first 20 lines"
        )
    names = [f.strip() for f in _split(lines[head])]
    units = [f.strip() for f in _split(lines[head + 1])]
    if len(units) != len(names):
        raise MeasurementError(
            f"{path}: line {head + 2}: {len(units)} units for {len(names)} channels"
        )
    rows = [(i + 1, _split(ln)) for i, ln in enumerate(lines) if i > head + 1 and ln.strip()]
    data = parse_rows(path, rows, len(names))
    raw = {n: data[:, j] for j, n in enumerate(names)}
    rows_at = np.array([r[0] for r in rows], np.int64)
    return raw, dict(zip(names, units, strict=True)), rows_at, head + 1


class TtcFormat:
    """The TTC run file format (see the module text)."""

    name: str = "ttc"
    suffixes: tuple[str, ...] = (".mat", ".dat")
    description: str = "FSAE Tire Test Consortium run file (.mat or .dat), SAE axes"

    def read(self, path: Path) -> Columns:
        """The file's channels in SI units and ISO-W axes."""
        lines, at = None, ""
        if path.suffix.lower() == ".mat":
            raw, units = _read_mat(path)
        else:
            raw, units, lines, names_line = _read_dat(path)
            at = f"line {names_line}: "
        for name in REQUIRED:
            if name not in raw:
                raise MeasurementError(f"{path}: {at}missing channel {name}")
        notes = []
        if "SL" not in raw:
            if "SR" not in raw:
                raise MeasurementError(f"{path}: {at}missing channel SL (slip ratio; SR neither)")
            notes.append("no SL channel: slip ratio kappa from SR (the rig's control slip)")
        cols = columns_by_name(path, self.name, raw, units, CHANNELS, lines=lines, time="ET")
        cols.notes += notes
        return cols

    def write(self, series: WheelSeries, path: Path, *, overwrite: bool = False) -> list[str]:
        """Write ``series`` as a TTC run file (.mat or .dat by suffix), SAE axes, SI/metric
        units; ET is the time since the first sample. Returns notes on what was left out."""
        data, units, notes = _columns_out(series)
        if path.suffix.lower() == ".mat":
            from scipy.io import savemat

            buf = io.BytesIO()
            cell = np.empty((1, len(data)), dtype=object)
            cell[0, :] = list(data)
            ucell = np.empty((1, len(data)), dtype=object)
            ucell[0, :] = [units[n] for n in data]
            mat: dict[str, object] = {n: v.reshape(-1, 1) for n, v in data.items()}
            mat["channel"] = {"name": cell, "units": ucell}
            mat["tireid"] = series.meta.get("tireid", "exported by tire-model")
            mat["testid"] = series.prefix
            savemat(buf, mat, do_compression=True)
            write_atomic(path, buf.getvalue(), overwrite=overwrite)
        else:
            out = [f"tire-model export of {series.prefix}", "\t".join(data)]
            out.append("\t".join(units[n] for n in data))
            table = np.column_stack(list(data.values()))
            out += ["\t".join(repr(float(v)) for v in row) for row in table]
            write_atomic(path, "\n".join(out) + "\n", overwrite=overwrite)
        return notes


def _columns_out(series: WheelSeries) -> tuple[dict[str, Floats], dict[str, str], list[str]]:
    """TTC columns of ``series`` (ISO-W -> SAE, SI -> the written units)."""
    values: dict[str, Floats | None] = {"t": series.t - series.t[0], "kappa": series.kappa}
    for c in ("alpha", "gamma", "Fz", "Fx", "Fy", "Mx", "Mz", "p", "Vx", "T"):
        values[c] = getattr(series, c)
    data: dict[str, Floats] = {}
    for name, (channel, quantity, sign) in CHANNELS.items():
        v = values.get(channel)
        if v is None or name == "SR":
            continue
        data[name] = from_si(sign * v, WRITE_UNITS[name], quantity)
    notes = [] if series.My is None else ["My left out: TTC files have no MY channel"]
    return data, {n: WRITE_UNITS[n] for n in data}, notes
