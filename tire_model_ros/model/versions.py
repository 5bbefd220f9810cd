"""The .tir file versions and the coefficients each one needs.

A version is chosen by the FITTYP a file gives (none: ``PROPERTY_FILE_FORMAT='PAC2002'``).
Its ``needed`` keys are the coefficients of the steady-state force and moment equations of that
version (and the ranges and reference values they are scaled by) that every file of the version
carries: their absence cannot be told apart from damage (a file cut short, a deleted line, a
mistyped section header), so ``read_tir`` refuses a file without them unless ``lenient``.
Sections listed in ``complete_if_present`` are optional, but all or nothing: a turn-slip or
temperature section that is there is there whole.

Coefficients outside these sets (relaxation lengths, inertias, ADAMS switches, terms added in
later releases with neutral defaults such as QSX12-14) take the defaults of ``params``.
Checked against every file in ``../shared/reference/tir`` (the MFeval MF 5.2, 6.1, 6.2 sets, the
Chrono PAC2002 and MF-Tyre 5.0 files).

To support another version, add one :class:`Version` to :data:`VERSIONS`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["VERSIONS", "Version", "version_of"]


@dataclass(frozen=True)
class Version:
    """One .tir file version.

    Attributes
    ----------
    name : label used in messages, e.g. ``"MF 6.1"``.
    fittyps : FITTYP values of the files of this version (None: a file without FITTYP).
    needed : section -> coefficients a file of this version must give (MF 6.1 names).
    complete_if_present : section -> coefficients it must give when the section is there.
    """

    name: str
    fittyps: frozenset[int | None]
    needed: Mapping[str, tuple[str, ...]]
    complete_if_present: Mapping[str, tuple[str, ...]]


def _keys(text: str) -> tuple[str, ...]:
    return tuple(text.split())


def _merge(*parts: Mapping[str, tuple[str, ...]]) -> dict[str, tuple[str, ...]]:
    out: dict[str, tuple[str, ...]] = {}
    for part in parts:
        for section, keys in part.items():
            have = out.get(section, ())
            out[section] = have + tuple(k for k in keys if k not in have)
    return out


def _without(
    sets: Mapping[str, tuple[str, ...]], dropped: tuple[str, ...]
) -> dict[str, tuple[str, ...]]:
    return {s: tuple(k for k in keys if k not in dropped) for s, keys in sets.items()}


# MF-Tyre 5.0 (FITTYP 5): the oldest set in use; the Chrono FED truck tyre has exactly this.
_MF50: dict[str, tuple[str, ...]] = {
    "MODEL": _keys("LONGVL VXLOW"),
    "DIMENSION": _keys("UNLOADED_RADIUS"),
    "VERTICAL": _keys("FNOMIN VERTICAL_STIFFNESS BREFF DREFF FREFF"),
    "VERTICAL_FORCE_RANGE": _keys("FZMIN FZMAX"),
    "LONG_SLIP_RANGE": _keys("KPUMIN KPUMAX"),
    "SLIP_ANGLE_RANGE": _keys("ALPMIN ALPMAX"),
    "INCLINATION_ANGLE_RANGE": _keys("CAMMIN CAMMAX"),
    "SCALING_COEFFICIENTS": _keys(
        "LFZO LCX LMUX LEX LKX LHX LVX LCY LMUY LEY LKY LHY LVY LTR LRES LXAL LYKA LVYKA LS LMX LMY"
    ),
    "LONGITUDINAL_COEFFICIENTS": _keys(
        "PCX1 PDX1 PDX2 PEX1 PEX2 PEX3 PEX4 PKX1 PKX2 PKX3 PHX1 PHX2 PVX1 PVX2 RBX1 RBX2 RCX1 RHX1"
    ),
    "OVERTURNING_COEFFICIENTS": _keys("QSX1 QSX2 QSX3"),
    "LATERAL_COEFFICIENTS": _keys(
        "PCY1 PDY1 PDY2 PDY3 PEY1 PEY2 PEY3 PEY4 PKY1 PKY2 PKY3 PHY1 PHY2 PHY3 PVY1 PVY2 PVY3 "
        "PVY4 RBY1 RBY2 RBY3 RCY1 RHY1 RVY1 RVY2 RVY3 RVY4 RVY5 RVY6"
    ),
    "ROLLING_COEFFICIENTS": _keys("QSY1 QSY2"),
    "ALIGNING_COEFFICIENTS": _keys(
        "QBZ1 QBZ2 QBZ3 QBZ4 QBZ5 QBZ9 QCZ1 QDZ1 QDZ2 QDZ3 QDZ4 QDZ6 QDZ7 QDZ8 QDZ9 QEZ1 QEZ2 "
        "QEZ3 QEZ4 QEZ5 QHZ1 QHZ2 QHZ3 QHZ4 SSZ1 SSZ2 SSZ3 SSZ4"
    ),
}

# MF 5.2 (FITTYP 6, 21) and ADAMS PAC2002 add the combined-slip curvatures, the speed terms
# of the rolling resistance and the camber scaling factors.
_MF52 = _merge(
    _MF50,
    {
        "SCALING_COEFFICIENTS": _keys("LGAX LGAY LGAZ"),
        "LONGITUDINAL_COEFFICIENTS": _keys("PDX3 REX1 REX2"),
        "LATERAL_COEFFICIENTS": _keys("REY1 REY2 RHY2"),
        "ROLLING_COEFFICIENTS": _keys("QSY3 QSY4"),
        "ALIGNING_COEFFICIENTS": _keys("QBZ10"),
    },
)

# MF 6.1 (FITTYP 61): camber enters through its own terms (no PHY3, LGAX..LGAZ), with the
# inflation-pressure model, the MF 6.1 vertical model, carcass stiffness and contact patch.
_MF61 = _merge(
    _without(_MF52, ("PHY3", "LGAX", "LGAY", "LGAZ")),
    {
        "OPERATING_CONDITIONS": _keys("NOMPRES"),
        "INFLATION_PRESSURE_RANGE": _keys("PRESMIN PRESMAX"),
        "VERTICAL": _keys("Q_RE0 Q_V1 Q_V2 Q_FZ2 Q_FCX Q_FCY Q_CAM PFZ1"),
        "STRUCTURAL": _keys(
            "LONGITUDINAL_STIFFNESS LATERAL_STIFFNESS YAW_STIFFNESS PCFX1 PCFX2 PCFX3 PCFY1 PCFY2 "
            "PCFY3 PCMZ1"
        ),
        "CONTACT_PATCH": _keys("Q_RA1 Q_RA2 Q_RB1 Q_RB2"),
        "SCALING_COEFFICIENTS": _keys("LKYC LKZC LVMX"),
        "LONGITUDINAL_COEFFICIENTS": _keys("RBX3 PPX1 PPX2 PPX3 PPX4"),
        "OVERTURNING_COEFFICIENTS": _keys("QSX4 QSX5 QSX6 QSX7 QSX8 QSX9 QSX10 QSX11 PPMX1"),
        "LATERAL_COEFFICIENTS": _keys("PEY5 PKY4 PKY5 PKY6 PKY7 RBY4 PPY1 PPY2 PPY3 PPY4 PPY5"),
        "ROLLING_COEFFICIENTS": _keys("QSY5 QSY6 QSY7 QSY8"),
        "ALIGNING_COEFFICIENTS": _keys("QDZ10 QDZ11 PPZ1 PPZ2"),
    },
)

# MF 6.2 (FITTYP 62): the MF 6.2 vertical stiffness terms.
_MF62 = _merge(_MF61, {"VERTICAL": _keys("Q_FCY2 Q_CAM1 Q_CAM2 Q_CAM3 Q_FYS1 Q_FYS2 Q_FYS3")})

_OPTIONAL: dict[str, tuple[str, ...]] = {
    "TURNSLIP_COEFFICIENTS": _keys(
        "PDXP1 PDXP2 PDXP3 PKYP1 PDYP1 PDYP2 PDYP3 PDYP4 PHYP1 PHYP2 PHYP3 PHYP4 PECP1 PECP2 "
        "QDTP1 QCRP1 QCRP2 QBRP1 QDRP1"
    ),
    # dT is relative to NOMTEMP: terms without their reference temperature mean nothing.
    "TEMPERATURE_COEFFICIENTS": _keys("NOMTEMP TTX1 TTX2 TTX3 TTX4 TTY1 TTY2 TTY3 TTY4"),
    # the saturation range of T (INTERFACE.md): a range needs both ends.
    "TEMPERATURE_RANGE": _keys("TEMPMIN TEMPMAX"),
}

VERSIONS: tuple[Version, ...] = (
    Version("MF-Tyre 5.0", frozenset({5}), _MF50, _OPTIONAL),
    Version("MF 5.2", frozenset({6, 21}), _MF52, _OPTIONAL),
    Version("PAC2002", frozenset({None}), _MF52, _OPTIONAL),
    Version("MF 6.1", frozenset({61}), _MF61, _OPTIONAL),
    Version("MF 6.2", frozenset({62}), _MF62, _OPTIONAL),
)


def version_of(fittyp_in_file: int | None) -> Version:
    """The version of a file with this FITTYP (None: a PAC2002 file without one).

    Raises
    ------
    KeyError
        for a FITTYP no version claims (``tir`` refuses those before asking).
    """
    for version in VERSIONS:
        if fittyp_in_file in version.fittyps:
            return version
    raise KeyError(f"no .tir version with FITTYP {fittyp_in_file!r}")
