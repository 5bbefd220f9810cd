"""Reader and writer of tyre property files (.tir, TNO/ADAMS TeimOrbit format).

Supported: MF-Tyre / Magic Formula 5.x (FITTYP 5, 6, 21), 6.1 (FITTYP 61), 6.2 (FITTYP 62) and
the ADAMS PAC2002 variant (``PROPERTY_FILE_FORMAT='PAC2002'``, usually no FITTYP, pressure as
``[TIRE_CONDITIONS] IP / IP_NOM``, pressure terms named QPZ1, QPZ2, QPX1, QPFZ1). Names are mapped
to MF 6.1 names (``params.ALIASES``); PAC2002 names with no exact MF 6.1 equivalent (LGAX, LGAY,
LGAZ, PHY3, PTX*, PTY*, LCZ, LIP, LKG, ...) keep their names. The temperature extension of
INTERFACE.md: NOMTEMP in ``[OPERATING_CONDITIONS]``, TTX1..4 / TTY1..4 in
``[TEMPERATURE_COEFFICIENTS]``.

Format rules followed: ``[SECTION]`` headers, ``KEY = value`` lines, ``$`` and ``!`` comments
(whole line or after the value), quoted strings, any case of keys and section names, CRLF/LF/CR
line ends, blank lines. Sections this module does not read (tables such as ``[SHAPE]`` and load
curves, vendor blocks such as ``[GOODYEAR]``) are kept verbatim and written back.

Units: ``[UNITS]`` must be SI (meter, newton, radian(s), kg, second, pascal). A file in other
units is refused (TirError): nothing is converted silently. A file without ``[UNITS]`` is SI.

Required keys (``params.REQUIRED``): FNOMIN, UNLOADED_RADIUS, LONGVL in every file; FITTYP unless
the file is PAC2002 (then FITTYP = 6, the MF 5.2 equation family with the MF 6.1 pressure
terms); NOMPRES for FITTYP 61/62 and for any file with a non-zero pressure coefficient. No
default can stand in for these, in any mode.

What is refused, by default (each a ``TirError`` naming the file, the line and the key):

* a coefficient or section the file's version needs and lacks (``versions``: what every file of
  that FITTYP carries), or an incomplete turn-slip or temperature section;
* an unknown section that holds a key the model reads, or whose name is a near miss of a section
  it reads (a mistyped header, e.g. ``[LATERAL_COEFICIENTS]``);
* a last line without a line end that holds content: the file may be cut short;
* a value outside the range of the parameter table (``params``: FNOMIN, R0 <= 0, PCX1 <= 0, ...),
  an input range that is empty or reversed (FZMIN >= FZMAX, PRESMIN >= PRESMAX, KPUMIN >=
  KPUMAX, ...), FNOMIN outside the file's FZMIN..FZMAX or NOMPRES outside its PRESMIN..PRESMAX;
* a model that is not a tyre on the file's own operating range (``check.check_model``: an output
  not finite, or forces beyond 10 times the load), naming the coefficient whose default alone
  would make it one when there is such a coefficient.

``read_tir(path, lenient=True)`` (the CLIs' ``--lenient``) lets the first three through: missing
needed coefficients take the defaults of ``params``, unknown sections are kept verbatim, a last
line without a line end is read as it is; ``TirData.notes`` says each thing it let through and
every key it filled, ``TirData.filled`` lists those keys. Invalid values, contradictory ranges
and a model that is not a tyre are refused in both modes. All other coefficients (those no
version needs) default as documented in ``params``.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

from ..atomic import write_atomic
from .params import (
    ALIASES,
    PARAMETERS,
    PRESSURE_COEFFICIENTS,
    REQUIRED,
    REQUIRED_MF6,
    SECTION_ORDER,
    STRING_KEYS,
    check_limit_pairs,
    check_value,
    default_params,
    limit_pair_violations,
)
from .versions import Version, version_of

__all__ = [
    "FITTYP_FAMILY",
    "OperatingPoint",
    "RawSection",
    "TirData",
    "TirError",
    "nominal_operating_point",
    "read_tir",
    "write_tir",
]

# FITTYP in a file -> the equation family of TirData.fittyp.
FITTYP_FAMILY: dict[int, int] = {5: 6, 6: 6, 21: 6, 61: 61, 62: 62}
# FITTYP given to a PAC2002 file without one: MF 5.2 structure (camber via LGAY, PHY3, ...)
# plus pressure terms, which are MF 6.1's under other names.
PAC2002_FITTYP = 6

# Accepted spellings of the SI units, lower case, per [UNITS] quantity.
_SI_UNITS: dict[str, frozenset[str]] = {
    "LENGTH": frozenset({"meter", "meters", "metre", "metres", "m"}),
    "FORCE": frozenset({"newton", "newtons", "n"}),
    "ANGLE": frozenset({"radian", "radians", "rad"}),
    "MASS": frozenset({"kg", "kilogram", "kilograms"}),
    "TIME": frozenset({"second", "seconds", "sec", "s"}),
    "PRESSURE": frozenset({"pascal", "pascals", "pa"}),
}
_SI_WRITE: dict[str, str] = {
    "LENGTH": "meter",
    "FORCE": "newton",
    "ANGLE": "radians",
    "MASS": "kg",
    "TIME": "second",
}
_HEADER_DEFAULTS: dict[str, str] = {
    "FILE_TYPE": "tir",
    "FILE_VERSION": "3.0",
    "FILE_FORMAT": "ASCII",
}
# Sections parsed as key = value; any other section is kept verbatim.
_KNOWN_SECTIONS: frozenset[str] = frozenset(SECTION_ORDER) | {"TIRE_CONDITIONS"}
# An unknown section this close (difflib ratio) to a known name is taken for a mistyped header.
_NEAR_MISS = 0.8
# Nominal values that must lie in the file's own input range: (value, range min, range max).
_NOMINAL_IN_RANGE: tuple[tuple[str, str, str], ...] = (
    ("FNOMIN", "FZMIN", "FZMAX"),
    ("NOMPRES", "PRESMIN", "PRESMAX"),
)
# The section whose coefficients shape each output of the model (where a refusal points).
_OUTPUT_SECTION: dict[str, str] = {
    "Fx": "LONGITUDINAL_COEFFICIENTS",
    "Kxk": "LONGITUDINAL_COEFFICIENTS",
    "mux": "LONGITUDINAL_COEFFICIENTS",
    "Fy": "LATERAL_COEFFICIENTS",
    "Kya": "LATERAL_COEFFICIENTS",
    "muy": "LATERAL_COEFFICIENTS",
    "Fz": "VERTICAL",
    "Mx": "OVERTURNING_COEFFICIENTS",
    "My": "ROLLING_COEFFICIENTS",
    "Mz": "ALIGNING_COEFFICIENTS",
    "t": "ALIGNING_COEFFICIENTS",
    "Mzr": "ALIGNING_COEFFICIENTS",
}

_SECTION_RE = re.compile(r"\[\s*([A-Za-z][A-Za-z0-9_ ]*?)\s*\]\s*(?:[$!].*)?", re.ASCII)
_KEY_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*", re.ASCII)
_NUMBER_RE = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][+-]?\d+)?", re.ASCII)
_LINE_END_RE = re.compile(r"\r\n|\r|\n")


class TirError(ValueError):
    """A .tir file that cannot be read: the message names the file, the line and the key."""

    def __init__(
        self, path: str | os.PathLike[str] | None, line: int | None, key: str | None, reason: str
    ) -> None:
        self.path = None if path is None else str(path)
        self.line = line
        self.key = key
        self.reason = reason
        where = self.path if self.path is not None else "<tir>"
        if line is not None:
            where += f": line {line}"
        if key:
            where += f": {key}"
        super().__init__(f"{where}: {reason}")


@dataclass(frozen=True)
class RawSection:
    """A section this module does not interpret, kept verbatim for writing.

    ``after`` is the known section it followed ("" = before any known section).
    """

    name: str
    after: str
    lines: tuple[str, ...]


@dataclass(frozen=True)
class TirData:
    """The content of a .tir file.

    Attributes
    ----------
    path : file it was read from (None if built in memory).
    fittyp : equation family: 6 (MF 5.x and PAC2002), 61 (MF 6.1), 62 (MF 6.2).
    params : every numeric coefficient, UPPERCASE MF 6.1 names, defaults filled.
    strings : text-valued keys (TYRESIDE, PROPERTY_FILE_FORMAT, FILE_TYPE, ...).
    units : the ``[UNITS]`` entries as written (all SI).
    given : names of ``params`` that the file gave (the rest are defaults).
    source_format : "MF" or "PAC2002".
    fittyp_in_file : FITTYP as written (5, 6, 21, 61, 62), None when the file had none.
    renamed : original name -> MF 6.1 name for every alias the reader applied.
    extra_sections : section of each key the table does not know (written back there).
    raw_sections : unknown sections kept verbatim.
    preamble : comment lines before the first section.
    filled : coefficients the file's version needs that the file lacked, filled with their
        defaults (only with ``read_tir(..., lenient=True)``).
    notes : one line per thing let through (file, line, key, what was done): what ``lenient``
        filled or accepted, and a vendor's section kept but not read.
    """

    path: str | None
    fittyp: int
    params: dict[str, float]
    strings: dict[str, str] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    given: frozenset[str] = frozenset()
    source_format: str = "MF"
    fittyp_in_file: int | None = None
    renamed: dict[str, str] = field(default_factory=dict)
    extra_sections: dict[str, str] = field(default_factory=dict)
    raw_sections: tuple[RawSection, ...] = ()
    preamble: tuple[str, ...] = ()
    filled: frozenset[str] = frozenset()
    notes: tuple[str, ...] = ()

    def with_params(self, updates: Mapping[str, float]) -> TirData:
        """A copy with some coefficients changed.

        Raises
        ------
        ValueError
            naming the key, for a key this file has no coefficient for (FITTYP included: it is
            not a coefficient), a non-finite value, or a value outside its valid range.
        """
        params = dict(self.params)
        changed: set[str] = set()
        for name, value in updates.items():
            key = ALIASES.get(str(name).upper(), str(name).upper())
            if key == "FITTYP":
                raise ValueError("parameter FITTYP: the model version cannot be changed")
            if key not in params:
                raise ValueError(f"unknown parameter {name!r}")
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"parameter {name}: not a number: {value!r}") from None
            problem = check_value(key, number)
            if problem is not None:
                raise ValueError(f"parameter {name}: {problem}")
            params[key] = number
            changed.add(key)
        pair_problems = check_limit_pairs(params, changed)
        if pair_problems:
            raise ValueError("; ".join(pair_problems))
        return dataclasses.replace(self, params=params, given=self.given | changed)

    def nominal(self) -> OperatingPoint:
        """The nominal operating point, see :func:`nominal_operating_point`."""
        return nominal_operating_point(self)


class OperatingPoint(NamedTuple):
    """Nominal operating conditions of a tyre (SI; p gauge [Pa], T [degC])."""

    Fz: float
    Vx: float
    p: float
    T: float
    kappa: float = 0.0
    alpha: float = 0.0
    gamma: float = 0.0


def nominal_operating_point(tir: TirData) -> OperatingPoint:
    """Fz = FNOMIN, Vx = LONGVL, p = INFLPRES (= NOMPRES unless set), T = NOMTEMP, no slip."""
    P = tir.params
    return OperatingPoint(P["FNOMIN"], P["LONGVL"], P["INFLPRES"], P["NOMTEMP"])


# ============================================================================================
# Reading
# ============================================================================================


@dataclass
class _Entry:
    value: float | str
    line: int
    section: str
    name_in_file: str


@dataclass
class _Parsed:
    path: str
    n_lines: int
    header_lines: dict[str, int] = field(default_factory=dict)  # section -> first header line
    numbers: dict[str, _Entry] = field(default_factory=dict)
    texts: dict[str, _Entry] = field(default_factory=dict)
    units: dict[str, _Entry] = field(default_factory=dict)
    raw_sections: list[RawSection] = field(default_factory=list)
    raw_header_lines: list[int] = field(default_factory=list)  # one per raw section
    preamble: list[str] = field(default_factory=list)
    renamed: dict[str, str] = field(default_factory=dict)


class _Refusals:
    """What ``lenient`` lets through: raised at once when strict, else kept as notes."""

    def __init__(self, lenient: bool) -> None:
        self.lenient = lenient
        self.notes: list[str] = []

    def refuse(self, error: TirError, lenient_action: str) -> None:
        if not self.lenient:
            raise error
        self.notes.append(f"{error}; --lenient: {lenient_action}")


def read_tir(path: str | os.PathLike[str], *, lenient: bool = False) -> TirData:
    """Read a .tir file, refusing what cannot be trusted (see the module docstring).

    Parameters
    ----------
    path : the .tir file.
    lenient : fill the coefficients the file's version needs and lacks with their documented
        defaults, keep unknown sections, read a last line without a line end; every such thing
        is listed in ``TirData.notes`` (print them), the filled keys in ``TirData.filled``.

    Raises
    ------
    TirError
        naming the file, the line and the key, for: a file that is missing or not UTF-8, a line
        that is neither a section header, a comment nor ``KEY = value``, a key outside any
        section, an empty or non-numeric value, a duplicate key with a different value, a
        non-SI ``[UNITS]`` entry, an unknown FITTYP, a missing required key, a value outside
        its valid range, a contradictory input range, a model that is not a tyre on its
        operating range; and when not ``lenient``: a missing needed key or section, an
        unknown section holding model keys or named like a known one, a file cut short.
    """
    name = str(path)
    text = _read_text(name)
    lines = _LINE_END_RE.split(text)
    refusals = _Refusals(lenient)
    cut = _cut_short(name, lines)
    try:
        parsed = _parse_lines(name, lines)
    except TirError as exc:
        if cut is not None and exc.line == cut.line:
            raise cut from None  # the cut explains the unreadable last line
        raise
    if cut is not None:
        refusals.refuse(cut, "read as it is")
    tir = _build(parsed, refusals)
    _check_model(parsed, tir)
    return tir


def _read_text(path: str) -> str:
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise TirError(path, None, None, "file not found") from None
    except IsADirectoryError:
        raise TirError(path, None, None, "is a directory, not a .tir file") from None
    except OSError as exc:
        raise TirError(path, None, None, f"cannot read: {exc.strerror or exc}") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        # Count lines as read_tir does (CR, LF and CRLF all end a line).
        line = len(_LINE_END_RE.split(data[: exc.start].decode("utf-8", "replace")))
        raise TirError(
            path, line, None, f"not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start})"
        ) from None


def _parse_lines(path: str, lines: list[str]) -> _Parsed:
    # A text ending with a line end splits into a last empty string: not a line of the file.
    n_lines = max(1, len(lines) - (1 if lines and not lines[-1] else 0))
    parsed = _Parsed(path=path, n_lines=n_lines)
    section = ""  # current known section ("" = none yet)
    last_known = ""
    raw: RawSection | None = None
    raw_lines: list[str] = []

    def close_raw() -> None:
        nonlocal raw
        if raw is not None:
            # Trailing comments and blanks are the banner of the next section, not table rows.
            while raw_lines and (not raw_lines[-1].strip() or raw_lines[-1].lstrip()[0] in "$!"):
                raw_lines.pop()
            parsed.raw_sections.append(dataclasses.replace(raw, lines=tuple(raw_lines)))
            raw = None

    for number, line in enumerate(lines, start=1):
        stripped = line.strip()
        if stripped.startswith("["):
            match = _SECTION_RE.fullmatch(stripped)
            if match is None:
                raise TirError(path, number, None, _malformed_header(stripped))
            close_raw()
            name = match.group(1).upper()
            parsed.header_lines.setdefault(name, number)
            if name in _KNOWN_SECTIONS:
                section = last_known = name
            else:
                section = ""
                raw, raw_lines = RawSection(name, last_known, ()), []
                parsed.raw_header_lines.append(number)
            continue
        if raw is not None:
            raw_lines.append(line)
            continue
        if not stripped or stripped[0] in "$!":
            if not section and not parsed.header_lines and stripped:
                parsed.preamble.append(stripped)
            continue
        _parse_assignment(parsed, section, number, stripped)
    close_raw()
    # A '$----name' line just before the first section is its banner; the writer makes its own.
    while parsed.preamble and parsed.preamble[-1].startswith("$--"):
        parsed.preamble.pop()
    return parsed


def _malformed_header(stripped: str) -> str:
    """The refusal of a line that opens a section header badly, with the known section it
    may have meant (``[LATERAL-COEFFICIENTS]``: a mistyped [LATERAL_COEFFICIENTS]?)."""
    inner = stripped[1:].split("]", 1)[0].strip().upper()
    guess = re.sub(r"[^A-Z0-9]+", "_", inner).strip("_")
    near = difflib.get_close_matches(guess, _KNOWN_SECTIONS, n=1, cutoff=_NEAR_MISS)
    meant = f": a mistyped [{near[0]}]?" if near else ""
    return f"malformed section header {stripped[:60]!r}{meant}"


def _split_value(path: str, number: int, key: str, rest: str) -> tuple[str, bool]:
    """(value text, quoted?) of the text after '=', without its trailing comment."""
    rest = rest.strip()
    if rest[:1] in ("'", '"'):
        end = rest.find(rest[0], 1)
        if end < 0:
            raise TirError(path, number, key, f"unterminated quoted string {rest[:60]!r}")
        tail = rest[end + 1 :].strip()
        if tail and tail[0] not in "$!":
            raise TirError(path, number, key, f"unexpected text after the value: {tail[:60]!r}")
        return rest[1:end], True
    cut = min((i for i in (rest.find("$"), rest.find("!")) if i >= 0), default=len(rest))
    value = rest[:cut].strip()
    if not value:
        raise TirError(path, number, key, "empty value")
    return value, False


def _parse_number(text: str) -> float | None:
    if _NUMBER_RE.fullmatch(text) is None:
        return None
    # Fortran-style exponents (1.0D+03) occur in old generated files.
    return float(text.replace("d", "e").replace("D", "e"))


def _is_model_key(key: str) -> bool:
    """A key the model reads (a coefficient of the table or FITTYP), under any alias."""
    canonical = ALIASES.get(key.upper(), key.upper())
    return canonical in PARAMETERS or canonical == "FITTYP"


def _parse_assignment(parsed: _Parsed, section: str, number: int, stripped: str) -> None:
    path = parsed.path
    if "=" not in stripped:
        raise TirError(
            path, number, None, f"unreadable line (not 'KEY = value'): {stripped[:60]!r}"
        )
    key_text, rest = stripped.split("=", 1)
    key_text = key_text.strip()
    if _KEY_RE.fullmatch(key_text) is None:
        raise TirError(
            path, number, key_text[:40] or None, f"invalid key in line {stripped[:60]!r}"
        )
    key = key_text.upper()
    if not section:
        raise TirError(path, number, key, "key outside any [SECTION]")
    value_text, quoted = _split_value(path, number, key, rest)
    canonical = ALIASES.get(key, key)
    coefficient = _is_model_key(key)
    if section == "UNITS" and (key == "MASS" or not (coefficient or canonical in STRING_KEYS)):
        _store(parsed, parsed.units, key, _Entry(value_text, number, section, key))
        return
    if section == "MDI_HEADER" and not coefficient:
        _store(parsed, parsed.texts, key, _Entry(value_text, number, section, key))
        return
    if canonical != key:
        parsed.renamed[key] = canonical
    if canonical in STRING_KEYS:  # text, quoted or not (TYRESIDE = LEFT occurs)
        _store(parsed, parsed.texts, canonical, _Entry(value_text, number, section, key))
        return
    value = None if quoted else _parse_number(value_text)
    if value is None:
        if coefficient:
            raise TirError(path, number, key, f"non-numeric value {value_text[:60]!r}")
        # A key this model does not use: kept as text (quoted on writing), whatever it holds.
        _store(parsed, parsed.texts, canonical, _Entry(value_text, number, section, key))
        return
    if not math.isfinite(value):
        raise TirError(path, number, key, f"not a finite number: {value_text[:60]!r}")
    _store(parsed, parsed.numbers, canonical, _Entry(value, number, section, key))


def _store(parsed: _Parsed, target: dict[str, _Entry], key: str, entry: _Entry) -> None:
    old = target.get(key)
    if old is None:
        target[key] = entry
    elif old.value != entry.value:
        raise TirError(
            parsed.path,
            entry.line,
            entry.name_in_file,
            f"duplicate key with a different value ({entry.value!r} here, "
            f"{old.value!r} as {old.name_in_file} on line {old.line})",
        )


def _missing(
    parsed: _Parsed, key: str, section: str, why: str = "required key missing"
) -> TirError:
    line = parsed.header_lines.get(section, parsed.n_lines)
    return TirError(parsed.path, line, key, f"{why} (expected in [{section}])")


def _cut_short(path: str, lines: list[str]) -> TirError | None:
    """The error for a last line without a line end: the file may have been cut in it.

    A whole file ends with a line end (the split then leaves an empty last string); a file
    that does not may have lost the rest of that line and everything after it.
    """
    last = lines[-1].strip() if lines else ""
    if not last:
        return None
    key = last.split("=", 1)[0].strip().upper() if "=" in last else None
    return TirError(
        path,
        len(lines),
        key if key and _KEY_RE.fullmatch(key) else None,
        f"the file ends inside this line ({last[:40]!r}, no line end): it may be cut short",
    )


def _check_units(parsed: _Parsed) -> None:
    for quantity, entry in parsed.units.items():
        allowed = _SI_UNITS.get(quantity)
        if allowed is not None and str(entry.value).strip().lower() not in allowed:
            raise TirError(
                parsed.path,
                entry.line,
                quantity,
                f"unit {entry.value!r} is not SI; only SI files are supported "
                f"({quantity} = '{_SI_WRITE.get(quantity, 'pascal')}'); convert the file first",
            )


def _fittyp(parsed: _Parsed, source_format: str) -> tuple[int, int | None]:
    entry = parsed.numbers.pop("FITTYP", None)
    if entry is None:
        if source_format == "PAC2002":
            return PAC2002_FITTYP, None
        raise _missing(
            parsed, "FITTYP", "MODEL", "required key missing (or PROPERTY_FILE_FORMAT='PAC2002')"
        )
    value = float(entry.value)
    if not value.is_integer() or int(value) not in FITTYP_FAMILY:
        raise TirError(
            parsed.path,
            entry.line,
            "FITTYP",
            f"unknown FITTYP {entry.value!r}; supported: {sorted(FITTYP_FAMILY)}",
        )
    return FITTYP_FAMILY[int(value)], int(value)


def _check_required(parsed: _Parsed, fittyp: int) -> None:
    for key in REQUIRED:
        if key not in parsed.numbers:
            raise _missing(parsed, key, PARAMETERS[key].section)
    if "NOMPRES" in parsed.numbers:
        return
    if fittyp >= 61:
        raise _missing(
            parsed, REQUIRED_MF6[0], "OPERATING_CONDITIONS", "required key missing for MF 6.x"
        )
    for key in PRESSURE_COEFFICIENTS:
        entry = parsed.numbers.get(key)
        if entry is not None and entry.value != 0.0:
            raise _missing(
                parsed, "NOMPRES", "OPERATING_CONDITIONS",
                f"required because {entry.name_in_file} (line {entry.line}) is non-zero",
            )  # fmt: skip


def _check_unknown_sections(parsed: _Parsed, refusals: _Refusals) -> None:
    """Refuse an unknown section that looks like a known one: it holds keys the model reads
    (their values would be lost to defaults) or its name is a near miss of a known name."""
    for raw, header in zip(parsed.raw_sections, parsed.raw_header_lines, strict=True):
        for offset, text in enumerate(raw.lines, start=1):
            key = text.split("=", 1)[0].strip() if "=" in text else ""
            if key and _KEY_RE.fullmatch(key) and _is_model_key(key):
                refusals.refuse(
                    TirError(
                        parsed.path, header + offset, key.upper(),
                        f"in unknown section [{raw.name}] (line {header}), which is not read: "
                        "a mistyped or misplaced section header?",
                    ),
                    "section kept verbatim, not read",
                )  # fmt: skip
                break
        else:
            near = difflib.get_close_matches(raw.name, _KNOWN_SECTIONS, n=1, cutoff=_NEAR_MISS)
            if near:
                refusals.refuse(
                    TirError(
                        parsed.path, header, f"[{raw.name}]",
                        f"unknown section, not read: a mistyped [{near[0]}]?",
                    ),
                    "section kept verbatim, not read",
                )  # fmt: skip
            else:  # a vendor's block ([GOODYEAR], a rig's own): said, kept, not read
                refusals.notes.append(
                    f"{parsed.path}: line {header}: [{raw.name}]: not a Magic Formula section: "
                    "kept verbatim (written back), not read"
                )


def _needed_missing(parsed: _Parsed, version: Version) -> dict[str, list[str]]:
    """Section -> the keys the version needs there that the file lacks, in table order.

    The keys of a ``complete_if_present`` section count once its header is in the file.
    """
    wanted = dict(version.needed)
    for section, keys in version.complete_if_present.items():
        if section in parsed.header_lines:
            wanted[section] = wanted.get(section, ()) + keys
    missing: dict[str, list[str]] = {}
    for keys in wanted.values():
        for key in keys:
            if key not in parsed.numbers:
                missing.setdefault(PARAMETERS[key].section, []).append(key)
    return {section: missing[section] for section in SECTION_ORDER if section in missing}


def _needer(version: Version, section: str, key: str) -> str:
    """Who needs ``key``: the version, or an optional section that is in the file."""
    if key in version.needed.get(section, ()):
        return version.name
    owner = next(s for s, keys in version.complete_if_present.items() if key in keys)
    return f"the [{owner}] section the file has (all or nothing)"


def _check_needed(parsed: _Parsed, version: Version, refusals: _Refusals) -> frozenset[str]:
    """Refuse (or, lenient, fill with defaults) what the file's version needs and lacks."""
    missing = _needed_missing(parsed, version)
    if not missing:
        return frozenset()
    every = [key for keys in missing.values() for key in keys]
    if not refusals.lenient:
        section, keys = next(iter(missing.items()))
        where = "" if section in parsed.header_lines else ", a section the file lacks"
        listed = ", ".join(every[:8]) + (", ..." if len(every) > 8 else "")
        raise TirError(
            parsed.path, parsed.header_lines.get(section, parsed.n_lines), keys[0],
            f"missing from [{section}]{where}, needed by {_needer(version, section, keys[0])};"
            f" {len(every)} missing in all ({listed}): the file may be cut short or a section "
            "header mistyped (--lenient fills the defaults)",
        )  # fmt: skip
    for section, keys in missing.items():
        filled = ", ".join(f"{key}={_format_number(PARAMETERS[key].default)}" for key in keys)
        line = parsed.header_lines.get(section, parsed.n_lines)
        refusals.notes.append(
            f"{parsed.path}: line {line}: [{section}]: {len(keys)} needed coefficient(s) "
            f"missing; --lenient: filled with defaults {filled}"
        )
    return frozenset(every)


def _check_values(parsed: _Parsed) -> None:
    """Every value within the parameter table's range (an unknown key: finite, checked)."""
    bad = [
        (entry, problem)
        for key, entry in parsed.numbers.items()
        if (problem := check_value(key, float(entry.value))) is not None
    ]
    if bad:
        entry, problem = min(bad, key=lambda item: item[0].line)
        others = ", ".join(
            f"{e.name_in_file} (line {e.line})" for e, _ in sorted(bad, key=lambda b: b[0].line)[1:]
        )
        more = f"; also out of range: {others}" if others else ""
        raise TirError(parsed.path, entry.line, entry.name_in_file, problem + more)


def _line_of(parsed: _Parsed, key: str) -> tuple[int, str]:
    """(line, name in the file) of a key; a default is placed at its section's header."""
    entry = parsed.numbers.get(key)
    if entry is not None:
        return entry.line, entry.name_in_file
    return parsed.header_lines.get(PARAMETERS[key].section, parsed.n_lines), key


def _check_ranges(parsed: _Parsed, params: Mapping[str, float]) -> None:
    """Input ranges that are empty or reversed, and nominal values outside them."""
    for lo, hi in limit_pair_violations(params, parsed.numbers.keys()):
        line, name = _line_of(parsed, hi if hi in parsed.numbers else lo)
        lo_line, _ = _line_of(parsed, lo)
        raise TirError(
            parsed.path, line, name,
            f"contradictory range: {lo} = {params[lo]!r} (line {lo_line}) is not below "
            f"{hi} = {params[hi]!r}",
        )  # fmt: skip
    for key, lo, hi in _NOMINAL_IN_RANGE:
        for bound in (lo, hi):
            if bound not in parsed.numbers:
                continue  # a default range is wide; only the file's own can contradict it
            outside = params[key] < params[bound] if bound == lo else params[key] > params[bound]
            if outside:
                line, name = _line_of(parsed, key)
                raise TirError(
                    parsed.path, line, name,
                    f"{key} = {params[key]!r} lies outside the file's range {lo}..{hi} "
                    f"({params[lo]!r}..{params[hi]!r})",
                )  # fmt: skip


def _check_model(parsed: _Parsed, tir: TirData) -> None:
    """Refuse a model that is not a tyre on its own operating range (``check.check_model``)."""
    from .check import check_model
    from .mf import TireModel

    fault = check_model(TireModel(tir))
    if fault is None:
        return
    if fault.causes:
        line, name = _line_of(parsed, fault.causes[0])
    else:
        line = parsed.header_lines.get(_OUTPUT_SECTION.get(fault.output, ""), parsed.n_lines)
        name = fault.output
    raise TirError(
        parsed.path, line, name, f"the model is not a tyre on the file's operating range: {fault}"
    )


def _build(parsed: _Parsed, refusals: _Refusals) -> TirData:
    _check_units(parsed)
    fmt_entry = parsed.texts.get("PROPERTY_FILE_FORMAT")
    is_pac = fmt_entry is not None and str(fmt_entry.value).strip().upper() == "PAC2002"
    source_format = "PAC2002" if is_pac else "MF"
    fittyp, fittyp_in_file = _fittyp(parsed, source_format)
    _check_required(parsed, fittyp)
    _check_unknown_sections(parsed, refusals)
    filled = _check_needed(parsed, version_of(fittyp_in_file), refusals)
    _check_values(parsed)

    params = default_params()
    given = {key: float(entry.value) for key, entry in parsed.numbers.items()}
    params.update(given)
    if "INFLPRES" not in given:
        params["INFLPRES"] = params["NOMPRES"]
    _check_ranges(parsed, params)
    extra = {
        key: entry.section
        for key, entry in [*parsed.numbers.items(), *parsed.texts.items()]
        if key not in PARAMETERS and key not in STRING_KEYS
    }
    return TirData(
        path=parsed.path,
        fittyp=fittyp,
        params=params,
        strings={**_HEADER_DEFAULTS, **{k: str(e.value) for k, e in parsed.texts.items()}},
        units={key: str(entry.value) for key, entry in parsed.units.items()},
        given=frozenset(given),
        source_format=source_format,
        fittyp_in_file=fittyp_in_file,
        renamed=dict(parsed.renamed),
        extra_sections=extra,
        raw_sections=tuple(parsed.raw_sections),
        preamble=tuple(parsed.preamble),
        filled=filled,
        notes=tuple(refusals.notes),
    )


# ============================================================================================
# Writing
# ============================================================================================


def _format_number(value: float) -> str:
    """Shortest text that reads back as exactly ``value`` (integers without '.0')."""
    if value.is_integer() and abs(value) < 1e15:
        return "-0.0" if value == 0 and math.copysign(1.0, value) < 0 else str(int(value))
    return repr(value)


def _line(key: str, value: str, comment: str = "") -> str:
    text = f"{key:<24} = {value}"
    if comment:
        text = f"{text:<50} ${comment}"
    return text.rstrip()


def _quote(text: str) -> str:
    quote = '"' if "'" in text else "'"
    return f"{quote}{text}{quote}"


def _section_banner(name: str) -> list[str]:
    title = name.title().replace("_", " ")
    return [f"${'-' * max(4, 74 - len(title))}{title}", f"[{name}]"]


_TEMPERATURE_NOTE = (
    "$ Temperature extension (tire_model_ros, INTERFACE.md): dT = (T - NOMTEMP)/NOMTEMP,",
    "$ Kxk*(1+TTX1 dT+TTX2 dT^2), mux*(1+TTX3 dT+TTX4 dT^2), Kya: PKY1 term*(1+TTY1 dT),",
    "$ PKY2 term*(1+TTY2 dT), muy*(1+TTY3 dT+TTY4 dT^2). Other tools ignore this section.",
)


def _worth_writing(tir: TirData, name: str, value: float) -> bool:
    """Write a coefficient unless it is a default that only another model version uses, or
    the default temperature range (a file without ``[TEMPERATURE_RANGE]`` stays without it).

    Leaving those out keeps e.g. MF 6.2 vertical terms out of an MF 6.1 file; reading the file
    back gives the same default, so the round trip stays exact.
    """
    spec = PARAMETERS[name]
    if spec.section == "TEMPERATURE_RANGE":  # its default is a sanity range, not the file's
        return name in tir.given or value != spec.default
    if name in tir.given or value != spec.default or not spec.family:
        return True
    own = {6: "5.2", 61: "6.1", 62: "6.2"}.get(tir.fittyp, "")
    return spec.family == own or (spec.family == "PAC2002" and tir.source_format == "PAC2002")


def _body_lines(tir: TirData) -> dict[str, list[str]]:
    """The key lines of every known section, in table order."""
    body: dict[str, list[str]] = {name: [] for name in SECTION_ORDER}
    header = {**_HEADER_DEFAULTS, **{k: v for k, v in tir.strings.items() if k in _HEADER_DEFAULTS}}
    for key, text in header.items():
        body["MDI_HEADER"].append(
            _line(key, text if _parse_number(text) is not None else _quote(text))
        )
    units = {**_SI_WRITE, **tir.units}
    body["UNITS"] = [_line(k, _quote(v)) for k, v in units.items()]
    fittyp = (
        tir.fittyp_in_file
        if FITTYP_FAMILY.get(tir.fittyp_in_file or 0) == tir.fittyp
        else tir.fittyp
    )
    body["MODEL"].append(_line("FITTYP", str(fittyp), "Magic Formula version number"))
    for key, text in tir.strings.items():
        if key in _HEADER_DEFAULTS:
            continue
        section = STRING_KEYS.get(key) or tir.extra_sections.get(key, "MODEL")
        body.setdefault(section, []).append(_line(key, _quote(text)))
    for name, spec in PARAMETERS.items():
        number = tir.params.get(name, spec.default)
        if _worth_writing(tir, name, number):
            body[spec.section].append(_line(name, _format_number(number), spec.description))
    for key, number in tir.params.items():
        if key not in PARAMETERS and key != "FITTYP":  # FITTYP is written from tir.fittyp
            section = tir.extra_sections.get(key, "MODEL")
            body.setdefault(section, []).append(
                _line(key, _format_number(number), "(not used by this model)")
            )
    body["TEMPERATURE_COEFFICIENTS"][:0] = _TEMPERATURE_NOTE
    return body


def _check_writable(tir: TirData) -> None:
    """Refuse content that would not read back (a hand-built or edited TirData)."""
    if tir.fittyp not in FITTYP_FAMILY.values():
        raise ValueError(f"FITTYP {tir.fittyp!r}: not one of {sorted(set(FITTYP_FAMILY.values()))}")
    for key, value in tir.params.items():
        if _KEY_RE.fullmatch(key) is None or not isinstance(value, int | float):
            raise ValueError(f"parameter {key!r}: cannot be written as 'KEY = number'")
        if not math.isfinite(value):
            raise ValueError(f"parameter {key}: {value!r} is not finite; a .tir needs numbers")
    for key, text in [*tir.strings.items(), *tir.units.items()]:
        if _KEY_RE.fullmatch(key) is None or ("'" in text and '"' in text) or "\n" in text:
            raise ValueError(f"string {key!r} = {text!r}: cannot be written as a quoted value")
        if "\r" in text:
            raise ValueError(f"string {key!r} = {text!r}: cannot be written as a quoted value")


def tir_text(tir: TirData) -> str:
    """The text of a standard .tir file holding ``tir`` (what :func:`write_tir` writes).

    Raises
    ------
    ValueError
        for content no .tir can hold (non-finite numbers, keys with spaces, ...).
    """
    _check_writable(tir)
    body = _body_lines(tir)
    raw_after: dict[str, list[RawSection]] = {}
    for raw in tir.raw_sections:
        anchor = raw.after if raw.after in body else "TEMPERATURE_COEFFICIENTS"
        raw_after.setdefault(anchor, []).append(raw)
    out: list[str] = list(tir.preamble)
    for raw in raw_after.pop("", []):
        out += [f"[{raw.name}]", *raw.lines]
    for name, lines in body.items():
        if lines:
            out += _section_banner(name) if name != "MDI_HEADER" else ["[MDI_HEADER]"]
            out += lines
        if name == "MDI_HEADER":
            out.append("$ written by tire_model_ros; descriptions follow each value after '$'")
        for raw in raw_after.get(name, []):
            out += [f"[{raw.name}]", *raw.lines]
    return "\n".join(out).rstrip("\n") + "\n"


def write_tir(tir: TirData, path: str | os.PathLike[str], *, overwrite: bool = False) -> None:
    """Write ``tir`` as a standard .tir file, atomically (temporary file + rename).

    Every coefficient is written (defaults included) with repr() precision, so reading the file
    back gives exactly ``tir.params``.

    Raises
    ------
    FileExistsError
        if ``path`` exists and ``overwrite`` is False.
    """
    write_atomic(path, tir_text(tir), overwrite=overwrite)
