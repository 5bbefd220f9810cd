"""The table of every Magic Formula coefficient the model knows.

One row per coefficient: the .tir section it belongs to, its default, a one-line description
with units, and -- where physics sets one -- its valid range.

Defaults policy
---------------
* A coefficient that a file leaves out takes the default of this table.
* Where MFeval 4.3 (Marco Furlan's open MATLAB evaluator, readTIR.m; the reference the project
  is checked against) has a default, that default is used, so that a file evaluates the same
  here and in MFeval. These are TNO's defaults: scaling factors 1, most coefficients 0, a few
  non-zero shape values chosen so that a missing group stays neutral (e.g. PCX1 1.65, PKY4 2,
  QSX4 5 with QSX7 = QSX8 = 0, RVY4..6 with RVY1..3 = 0) and the turn-slip set.
* Otherwise: scaling factors 1, coefficients 0, NOMTEMP 25 degC, the temperature
  coefficients TTX1..4 / TTY1..4 0 (no temperature effect; INTERFACE.md).
* Input ranges ([*_RANGE] sections) a file leaves out are wide, so that a default never clips a
  plausible input: FZMIN 0 / FZMAX 1e6 N, ALPMIN/ALPMAX -+1.5708 rad, CAMMIN/CAMMAX -+1 rad
  (MFeval's 100 N / 10 kN, -+1.5 rad, -+0.175 rad would clip a truck's load or a motorcycle's
  camber); KPUMIN/KPUMAX -+1.5 and PRESMIN/PRESMAX 10 kPa / 1 MPa as MFeval. The temperature
  range (``[TEMPERATURE_RANGE]`` TEMPMIN/TEMPMAX, INTERFACE.md) a file leaves out is a physical
  sanity range, -50..150 degC: below it the tread rubber is glassy, above it the tread
  degrades, so a temperature outside is a sensor fault, not a tyre (a fitted quadratic
  temperature term beyond it can flip the sign of a force).
* INFLPRES missing -> NOMPRES (the tyre runs at its nominal pressure); see ``tir.read_tir``.

Ranges
------
``minimum``/``maximum`` bound the values the model accepts, from a .tir file (``read_tir``
refuses a value outside them, naming its line) and from a user (ROS parameter descriptors,
``TireModel.with_params``). ``strict_min`` makes the lower bound exclusive. Every coefficient
has both bounds. Where physics sets one it is that: a positive radius, stiffness, load or
pressure, scaling factors >= 0 where a negative one reverses the physics, |alpha|, |gamma|
range limits within 90 deg (1.58 rad, room for a rounded pi/2), a peak friction coefficient
|PDX1|, |PDY1| <= 10 (as ``check``: a friction coefficient of 10 is no tyre), a temperature
above absolute zero. Elsewhere it is a sanity bound, at least 10 times the largest magnitude
found in the published files (MFeval's examples, TNO's, Chrono's, the FSAE TTC set): 1e4 for a
dimensionless or angular coefficient, 100 for a scaling factor, 1e6 for the camber terms
RBX3/RBY4 (1.7e3 in a published file), 1e7 for the MF 6.2 Q_FYS terms (8.8e4), 1e7 Pa, 1e7 N,
10 m, 300 m/s for the operating conditions. A value beyond is a typing error, not a tyre
(``PDY1 = 1e9``). MFeval's
Model_Unstable.tir, "a deliberately ill-behaved set", is refused for its VERTICAL_STIFFNESS = 0
and PCX1 = 0. The input-range pairs (FZMIN < FZMAX, ...) must be ordered
(``limit_pair_violations``).
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass

__all__ = [
    "ALIASES",
    "PAC2002_EQUIVALENTS",
    "PARAMETERS",
    "PRESSURE_COEFFICIENTS",
    "REQUIRED",
    "REQUIRED_MF6",
    "SECTION_ORDER",
    "STRING_KEYS",
    "ParamSpec",
    "check_limit_pairs",
    "check_params",
    "check_value",
    "default_params",
    "describe",
    "is_required",
    "limit_pair_violations",
    "section_of",
]


@dataclass(frozen=True)
class ParamSpec:
    """One coefficient of the table.

    Attributes
    ----------
    name : UPPERCASE MF 6.1 name, e.g. ``"PDY1"``.
    section : .tir section without brackets, e.g. ``"LATERAL_COEFFICIENTS"``.
    default : value used when a file omits it.
    description : one line, units in brackets.
    minimum, maximum : valid range (None = unbounded); ``strict_min`` makes minimum exclusive.
    """

    name: str
    section: str
    default: float
    description: str
    minimum: float | None = None
    maximum: float | None = None
    strict_min: bool = False

    @property
    def family(self) -> str:
        """The model version that alone uses it: "5.2", "6.2", "PAC2002", or "" (all)."""
        for marker, family in (("(MF 5.2", "5.2"), ("(MF 6.2)", "6.2"), ("(PAC2002)", "PAC2002")):
            if marker in self.description:
                return family
        return ""

    def check(self, value: float) -> str | None:
        """Return why ``value`` is invalid for this coefficient, or None when it is valid."""
        if not math.isfinite(value):
            return f"{self.name} must be finite, got {value!r}"
        if self.minimum is not None:
            if self.strict_min and value <= self.minimum:
                return f"{self.name} must be > {self.minimum:g}, got {value!r}"
            if value < self.minimum:
                return f"{self.name} must be >= {self.minimum:g}, got {value!r}"
        if self.maximum is not None and value > self.maximum:
            return f"{self.name} must be <= {self.maximum:g}, got {value!r}"
        return None


# The order in which a standard .tir lists its sections (MF-Tyre 6.1 / MFeval example files),
# with the temperature extension of INTERFACE.md last.
SECTION_ORDER: tuple[str, ...] = (
    "MDI_HEADER",
    "UNITS",
    "MODEL",
    "DIMENSION",
    "OPERATING_CONDITIONS",
    "INERTIA",
    "VERTICAL",
    "STRUCTURAL",
    "CONTACT_PATCH",
    "INFLATION_PRESSURE_RANGE",
    "VERTICAL_FORCE_RANGE",
    "LONG_SLIP_RANGE",
    "SLIP_ANGLE_RANGE",
    "INCLINATION_ANGLE_RANGE",
    "TEMPERATURE_RANGE",
    "SCALING_COEFFICIENTS",
    "LONGITUDINAL_COEFFICIENTS",
    "OVERTURNING_COEFFICIENTS",
    "LATERAL_COEFFICIENTS",
    "ROLLING_COEFFICIENTS",
    "ALIGNING_COEFFICIENTS",
    "TURNSLIP_COEFFICIENTS",
    "TEMPERATURE_COEFFICIENTS",
)

# Keys whose value is text, with the section a writer puts them in.
STRING_KEYS: dict[str, str] = {
    "FILE_TYPE": "MDI_HEADER",
    "FILE_VERSION": "MDI_HEADER",
    "FILE_FORMAT": "MDI_HEADER",
    "TYRESIDE": "MODEL",
    "PROPERTY_FILE_FORMAT": "MODEL",
    "FUNCTION_NAME": "MODEL",
    "FE_METHOD": "MODEL",
    "BELT_DYNAMICS": "MODEL",
    "CONTACT_MODEL": "MODEL",
    "LOCAL_SOLVER": "MODEL",
    "LOCAL_SOLVER_HP": "MODEL",
}

# Other names for a coefficient -> its MF 6.1 name. Applied when reading any file.
# PAC2002 (MSC ADAMS) pressure terms: each enters its equation exactly as the MF 6.1 term does
# (checked against the PAC2002 equations as implemented in Project Chrono's ChPac02Tire):
#   QPZ1  Dt = Fz (QDZ1 + QDZ2 dfz)(1 - QPZ1 dpi) ...      == PPZ1 in Dt0 (4.E42)
#   QPZ2  Dr camber term (QDZ8 + QDZ9 dfz)(1 + QPZ2 dpi) y  == PPZ2 in Dr (4.E47)
#   QPX1  Mx: - QSX2 y (1 + QPX1 dpi)                       == PPMX1 in Mx (4.E69)
#   QPFZ1 vertical force/stiffness factor (1 + QPFZ1 dpi)   == PFZ1 of the MF 6.1 vertical
#         model (MF-Tyre / MFeval: Fz = (...)(1 + PFZ1 dpi) Fz0)
#   [TIRE_CONDITIONS] IP / IP_NOM, dpi = (IP - IP_NOM)/IP_NOM == INFLPRES / NOMPRES
# PAC2002 coefficients with no exact MF 6.1 counterpart keep their names (LGAX, LGAY, LGAZ,
# PHY3, PTX1..3, PTY1..2, LSGKP, LSGAL, LGYR, QTZ1, MBELT in the table; LKG, LCZ, LIP too,
# unused by the model). Their equations are MF 5.2's, hence FITTYP 6 for PAC2002 files.
PAC2002_EQUIVALENTS: dict[str, str] = {
    "QPZ1": "PPZ1",
    "QPZ2": "PPZ2",
    "QPX1": "PPMX1",
    "QPFZ1": "PFZ1",
    "IP": "INFLPRES",
    "IP_NOM": "NOMPRES",
}
ALIASES: dict[str, str] = {
    **PAC2002_EQUIVALENTS,
    # LFZ0 (digit zero) is a common misspelling of LFZO in generated files.
    "LFZ0": "LFZO",
}

# Required in every file (no default is a sensible guess for a particular tyre).
REQUIRED: tuple[str, ...] = ("FNOMIN", "UNLOADED_RADIUS", "LONGVL")
# Also required for MF 6.1 / 6.2 files (the pressure model is part of those versions).
REQUIRED_MF6: tuple[str, ...] = ("NOMPRES",)
# Required whenever any of these is non-zero (their effect is relative to NOMPRES).
PRESSURE_COEFFICIENTS: tuple[str, ...] = (
    "PFZ1", "PCFX3", "PCFY3", "PCMZ1", "PPX1", "PPX2", "PPX3", "PPX4", "PPMX1", "PPY1", "PPY2",
    "PPY3", "PPY4", "PPY5", "QSY8", "PPZ1", "PPZ2",
)  # fmt: skip


def is_required(name: str, fittyp: int | None = None) -> bool:
    """True when a .tir file must give ``name`` (for MF 6.1/6.2 when ``fittyp`` >= 61)."""
    key = name.upper()
    if key in REQUIRED:
        return True
    return key in REQUIRED_MF6 and fittyp is not None and fittyp >= 61


# --------------------------------------------------------------------------------------------
# The table. Columns: NAME  DEFAULT  MIN  MAX  description [unit]
# MIN/MAX: ">x" exclusive lower bound, "x" inclusive bound ("." unbounded: none is left).
# --------------------------------------------------------------------------------------------
_TABLE = """
[MODEL]
LONGVL                 16.7       >0    300   Reference speed V0 of the measurement [m/s]
VXLOW                  1.0        0     100   Speed below which the low-speed model applies [m/s]
ROAD_INCREMENT         0.01       >0    100   Increment in road sampling (ADAMS) [m]
ROAD_DIRECTION         1.0        -1    1     Direction of travelled distance (ADAMS) [-]
USE_MODE               124.0      0     1e6   Tyre use mode switch (ADAMS, MFeval useMode) [-]
USER_SUB_ID            815.0      0     1e9   User subroutine id (ADAMS) [-]
N_TIRE_STATES          4.0        0     1e3   Number of tyre states (ADAMS) [-]
HMAX_LOCAL             0.00025    >0    10    Local integration time step (ADAMS) [s]
TIME_SWITCH_INTEG      0.1        0     1e4   Time when local integrator is activated (ADAMS) [s]
SWITCH_INTEG           0.0        0     10    Integration method switch (MF 6.2) [-]
[DIMENSION]
UNLOADED_RADIUS        0.3135     >0    10    Free (unloaded) tyre radius R0 [m]
WIDTH                  0.205      0     10    Nominal section width of the tyre [m]
ASPECT_RATIO           0.6        0     10    Nominal aspect ratio [-]
RIM_RADIUS             0.1905     0     10    Nominal rim radius [m]
RIM_WIDTH              0.152      0     10    Rim width [m]
[OPERATING_CONDITIONS]
INFLPRES               220000.0   >0    1e7   Tyre inflation pressure, gauge (default: NOMPRES) [Pa]
NOMPRES                220000.0   >0    1e7   Nominal inflation pressure pi0, gauge [Pa]
NOMTEMP                25.0       >0    300   Reference tyre temperature of the temperature terms [degC]
[INERTIA]
MASS                   9.3        0     1e5   Tyre mass [kg]
IXX                    0.391      0     1e6   Tyre diametral moment of inertia [kg m^2]
IYY                    0.736      0     1e6   Tyre polar moment of inertia [kg m^2]
BELT_MASS              7.0        0     1e5   Belt mass [kg]
BELT_IXX               0.34       0     1e6   Belt diametral moment of inertia [kg m^2]
BELT_IYY               0.6        0     1e6   Belt polar moment of inertia [kg m^2]
GRAVITY                -9.81      -100  100   Gravity acting on belt in Z direction [m/s^2]
[VERTICAL]
FNOMIN                 4000.0     >0    1e7   Nominal (rated) wheel load Fz0 [N]
VERTICAL_STIFFNESS     200000.0   >0    1e10  Tyre vertical stiffness Cz0 [N/m]
VERTICAL_DAMPING       50.0       0     1e8   Tyre vertical damping [N s/m]
MC_CONTOUR_A           0.5        -1e4  1e4   Motorcycle contour ellipse A [-]
MC_CONTOUR_B           0.5        -1e4  1e4   Motorcycle contour ellipse B [-]
BREFF                  8.4        -1e4  1e4   Low load stiffness of effective rolling radius [-]
DREFF                  0.27       -1e4  1e4   Peak value of effective rolling radius [-]
FREFF                  0.07       -1e4  1e4   High load stiffness of effective rolling radius [-]
Q_RE0                  1.0        -1e4  1e4   Ratio of free tyre radius to nominal tyre radius [-]
Q_V1                   0.0        -1e4  1e4   Tyre radius increase with speed [-]
Q_V2                   0.0        -1e4  1e4   Vertical stiffness increase with speed [-]
Q_FZ2                  0.0001     -1e4  1e4   Quadratic term in load vs. deflection [-]
Q_FCX                  0.0        -1e4  1e4   Longitudinal force influence on vertical stiffness [-]
Q_FCY                  0.0        -1e4  1e4   Lateral force influence on vertical stiffness [-]
Q_CAM                  0.0        -1e4  1e4   Stiffness reduction due to camber [-]
PFZ1                   0.0        -1e4  1e4   Pressure effect on vertical stiffness (PAC2002 QPFZ1) [-]
Q_FCY2                 0.0        -1e4  1e4   Explicit load dependency of the Fy influence on vertical stiffness (MF 6.2) [-]
Q_CAM1                 0.0        -1e4  1e4   Linear load dependent camber influence on vertical stiffness (MF 6.2) [-]
Q_CAM2                 0.0        -1e4  1e4   Quadratic load dependent camber influence on vertical stiffness (MF 6.2) [-]
Q_CAM3                 0.0        -1e4  1e4   Linear load and camber dependent reduction of vertical stiffness (MF 6.2) [-]
Q_FYS1                 0.0        -1e7  1e7   Combined camber and slip angle effect on vertical stiffness, constant (MF 6.2) [-]
Q_FYS2                 0.0        -1e7  1e7   Combined camber and slip angle effect on vertical stiffness, linear (MF 6.2) [-]
Q_FYS3                 0.0        -1e7  1e7   Combined camber and slip angle effect on vertical stiffness, quadratic (MF 6.2) [-]
BOTTOM_OFFST           0.01       -10   10    Distance to rim when bottoming starts to occur [m]
BOTTOM_STIFF           2000000.0  0     1e11  Vertical stiffness of bottomed tyre [N/m]
[STRUCTURAL]
LONGITUDINAL_STIFFNESS 300000.0   0     1e10  Tyre overall longitudinal stiffness [N/m]
LATERAL_STIFFNESS      100000.0   0     1e10  Tyre overall lateral stiffness [N/m]
YAW_STIFFNESS          5000.0     0     1e9   Tyre overall yaw stiffness [N m/rad]
FREQ_LONG              80.0       0     1e5   Undamped frequency fore/aft and vertical mode [Hz]
FREQ_LAT               40.0       0     1e5   Undamped frequency lateral mode [Hz]
FREQ_YAW               50.0       0     1e5   Undamped frequency yaw and camber mode [Hz]
FREQ_WINDUP            70.0       0     1e5   Undamped frequency wind-up mode [Hz]
DAMP_LONG              0.04       0     1e3   Dimensionless damping fore/aft and vertical mode [-]
DAMP_LAT               0.04       0     1e3   Dimensionless damping lateral mode [-]
DAMP_YAW               0.04       0     1e3   Dimensionless damping yaw and camber mode [-]
DAMP_WINDUP            0.04       0     1e3   Dimensionless damping wind-up mode [-]
DAMP_RESIDUAL          0.002      0     1e3   Residual damping, proportional to stiffness [s]
DAMP_VLOW              0.001      0     1e3   Additional low speed damping, proportional to stiffness [s]
Q_BVX                  0.0        -1e4  1e4   Load and speed influence on in-plane translation stiffness [-]
Q_BVT                  0.0        -1e4  1e4   Load and speed influence on in-plane rotation stiffness [-]
PCFX1                  0.0        -1e4  1e4   Longitudinal carcass stiffness vs. deflection, linear [-]
PCFX2                  0.0        -1e4  1e4   Longitudinal carcass stiffness vs. deflection, quadratic [-]
PCFX3                  0.0        -1e4  1e4   Longitudinal carcass stiffness vs. pressure [-]
PCFY1                  0.0        -1e4  1e4   Lateral carcass stiffness vs. deflection, linear [-]
PCFY2                  0.0        -1e4  1e4   Lateral carcass stiffness vs. deflection, quadratic [-]
PCFY3                  0.0        -1e4  1e4   Lateral carcass stiffness vs. pressure [-]
PCMZ1                  0.0        -1e4  1e4   Yaw carcass stiffness vs. pressure [-]
[CONTACT_PATCH]
Q_RA1                  0.5        -1e4  1e4   Square root term in contact length equation [-]
Q_RA2                  1.0        -1e4  1e4   Linear term in contact length equation [-]
Q_RB1                  1.0        -1e4  1e4   Root term in contact width equation [-]
Q_RB2                  -1.0       -1e4  1e4   Linear term in contact width equation [-]
ELLIPS_SHIFT           0.8        -1e4  1e4   Scaling of distance between front and rear ellipsoid [-]
ELLIPS_LENGTH          1.0        -1e4  1e4   Semi major axis of ellipsoid [-]
ELLIPS_HEIGHT          1.0        -1e4  1e4   Semi minor axis of ellipsoid [-]
ELLIPS_ORDER           1.8        -1e4  1e4   Order of ellipsoid [-]
ELLIPS_MAX_STEP        0.025      -10   10    Maximum height of road step [m]
ELLIPS_NWIDTH          10.0       0     1e4   Number of parallel ellipsoids [-]
ELLIPS_NLENGTH         10.0       0     1e4   Number of ellipsoids at sides of contact patch [-]
ENV_C1                 0.0        -1e4  1e4   Effective height attenuation (MF 6.2) [-]
ENV_C2                 0.0        -1e4  1e4   Effective plane angle attenuation (MF 6.2) [-]
Q_A1                   0.0        -1e4  1e4   Square root load term in contact length (MF 5.2) [-]
Q_A2                   0.0        -1e4  1e4   Linear load term in contact length (MF 5.2) [-]
[INFLATION_PRESSURE_RANGE]
PRESMIN                10000.0    0     1e7   Minimum valid inflation pressure, gauge [Pa]
PRESMAX                1000000.0  0     1e7   Maximum valid inflation pressure, gauge [Pa]
[VERTICAL_FORCE_RANGE]
FZMIN                  0.0        0     1e7   Minimum allowed wheel load [N]
FZMAX                  1000000.0  >0    1e7   Maximum allowed wheel load [N]
[LONG_SLIP_RANGE]
KPUMIN                 -1.5       -100  100   Minimum valid longitudinal slip [-]
KPUMAX                 1.5        -100  100   Maximum valid longitudinal slip [-]
[SLIP_ANGLE_RANGE]
ALPMIN                 -1.5708    -1.58 1.58  Minimum valid slip angle [rad]
ALPMAX                 1.5708     -1.58 1.58  Maximum valid slip angle [rad]
[INCLINATION_ANGLE_RANGE]
CAMMIN                 -1.0       -1.58 1.58  Minimum valid inclination (camber) angle [rad]
CAMMAX                 1.0        -1.58 1.58  Maximum valid inclination (camber) angle [rad]
[TEMPERATURE_RANGE]
TEMPMIN                -50.0      -273.15 500 Minimum valid tyre temperature (absent: a physical sanity range) [degC]
TEMPMAX                150.0      -273.15 500 Maximum valid tyre temperature (absent: a physical sanity range) [degC]
[SCALING_COEFFICIENTS]
LFZO                   1.0        >0    100   Scale factor of nominal (rated) load [-]
LCX                    1.0        0     100   Scale factor of Fx shape factor [-]
LMUX                   1.0        0     100   Scale factor of Fx peak friction coefficient [-]
LEX                    1.0        -100  100   Scale factor of Fx curvature factor [-]
LKX                    1.0        0     100   Scale factor of Fx slip stiffness [-]
LHX                    1.0        -100  100   Scale factor of Fx horizontal shift [-]
LVX                    1.0        -100  100   Scale factor of Fx vertical shift [-]
LCY                    1.0        0     100   Scale factor of Fy shape factor [-]
LMUY                   1.0        >0    100   Scale factor of Fy peak friction coefficient [-]
LEY                    1.0        -100  100   Scale factor of Fy curvature factor [-]
LKY                    1.0        0     100   Scale factor of Fy cornering stiffness [-]
LHY                    1.0        -100  100   Scale factor of Fy horizontal shift [-]
LVY                    1.0        -100  100   Scale factor of Fy vertical shift [-]
LTR                    1.0        -100  100   Scale factor of peak of pneumatic trail [-]
LRES                   1.0        -100  100   Scale factor for offset of residual torque [-]
LXAL                   1.0        -100  100   Scale factor of alpha influence on Fx [-]
LYKA                   1.0        -100  100   Scale factor of kappa influence on Fy [-]
LVYKA                  1.0        -100  100   Scale factor of kappa induced Fy [-]
LS                     1.0        -100  100   Scale factor of moment arm of Fx [-]
LKYC                   1.0        -100  100   Scale factor of camber force stiffness [-]
LKZC                   1.0        -100  100   Scale factor of camber torque stiffness [-]
LVMX                   1.0        -100  100   Scale factor of Mx vertical shift [-]
LMX                    1.0        -100  100   Scale factor of overturning couple [-]
LMY                    1.0        -100  100   Scale factor of rolling resistance torque [-]
LMP                    1.0        -100  100   Scale factor of parking moment [-]
LMUV                   0.0        0     100   Friction decay with slip speed (0 = none, as MFeval) [-]
LGAX                   1.0        -100  100   Scale factor of camber for Fx (MF 5.2 / PAC2002) [-]
LGAY                   1.0        -100  100   Scale factor of camber for Fy (MF 5.2 / PAC2002) [-]
LGAZ                   1.0        -100  100   Scale factor of camber for Mz (MF 5.2 / PAC2002) [-]
LSGKP                  1.0        -100  100   Scale factor of relaxation length of Fx (MF 5.2) [-]
LSGAL                  1.0        -100  100   Scale factor of relaxation length of Fy (MF 5.2) [-]
LGYR                   1.0        -100  100   Scale factor of gyroscopic torque (MF 5.2) [-]
LKG                    1.0        -100  100   Scale factor of camber stiffness (PAC2002) [-]
LCZ                    1.0        -100  100   Scale factor of vertical stiffness (PAC2002) [-]
LIP                    1.0        -100  100   Scale factor of inflation pressure (PAC2002) [-]
[LONGITUDINAL_COEFFICIENTS]
PCX1                   1.65       >0    1e4   Shape factor Cfx for longitudinal force [-]
PDX1                   1.3        -10   10    Longitudinal friction Mux at Fznom [-]
PDX2                   -0.15      -1e4  1e4   Variation of friction Mux with load [-]
PDX3                   0.0        -1e4  1e4   Variation of friction Mux with camber squared [1/rad^2]
PEX1                   0.0        -1e4  1e4   Longitudinal curvature Efx at Fznom [-]
PEX2                   0.0        -1e4  1e4   Variation of curvature Efx with load [-]
PEX3                   0.0        -1e4  1e4   Variation of curvature Efx with load squared [-]
PEX4                   0.0        -1e4  1e4   Factor in curvature Efx while driving [-]
PKX1                   20.0       -1e4  1e4   Longitudinal slip stiffness Kfx/Fz at Fznom [-]
PKX2                   0.0        -1e4  1e4   Variation of slip stiffness Kfx/Fz with load [-]
PKX3                   0.0        -1e4  1e4   Exponent in slip stiffness Kfx/Fz with load [-]
PHX1                   0.0        -1e4  1e4   Horizontal shift Shx at Fznom [-]
PHX2                   0.0        -1e4  1e4   Variation of shift Shx with load [-]
PVX1                   0.0        -1e4  1e4   Vertical shift Svx/Fz at Fznom [-]
PVX2                   0.0        -1e4  1e4   Variation of shift Svx/Fz with load [-]
PPX1                   0.0        -1e4  1e4   Linear influence of inflation pressure on longitudinal slip stiffness [-]
PPX2                   0.0        -1e4  1e4   Quadratic influence of inflation pressure on longitudinal slip stiffness [-]
PPX3                   0.0        -1e4  1e4   Linear influence of inflation pressure on peak longitudinal friction [-]
PPX4                   0.0        -1e4  1e4   Quadratic influence of inflation pressure on peak longitudinal friction [-]
RBX1                   20.0       -1e4  1e4   Slope factor for combined slip Fx reduction [-]
RBX2                   15.0       -1e4  1e4   Variation of slope Fx reduction with kappa [-]
RBX3                   0.0        -1e6  1e6   Influence of camber on stiffness for Fx combined [1/rad^2]
RCX1                   1.0        -1e4  1e4   Shape factor for combined slip Fx reduction [-]
REX1                   0.0        -1e4  1e4   Curvature factor of combined Fx [-]
REX2                   0.0        -1e4  1e4   Curvature factor of combined Fx with load [-]
RHX1                   0.0        -1e4  1e4   Shift factor for combined slip Fx reduction [-]
PTX1                   0.0        -1e4  1e4   Relaxation length SigKap0/Fz at Fznom (MF 5.2) [-]
PTX2                   0.0        -1e4  1e4   Variation of SigKap0/Fz with load (MF 5.2) [-]
PTX3                   0.0        -1e4  1e4   Variation of SigKap0/Fz with exponent of load (MF 5.2) [-]
[OVERTURNING_COEFFICIENTS]
QSX1                   0.0        -1e4  1e4   Vertical shift of overturning moment [-]
QSX2                   0.0        -1e4  1e4   Camber induced overturning couple [1/rad]
QSX3                   0.0        -1e4  1e4   Fy induced overturning couple [-]
QSX4                   5.0        -1e4  1e4   Mixed load, lateral force and camber on Mx [-]
QSX5                   1.0        -1e4  1e4   Load effect on Mx with lateral force and camber [-]
QSX6                   10.0       -1e4  1e4   B-factor of load with Mx [-]
QSX7                   0.0        -1e4  1e4   Camber with load on Mx [1/rad]
QSX8                   0.0        -1e4  1e4   Lateral force with load on Mx [-]
QSX9                   0.4        -1e4  1e4   B-factor of lateral force with load on Mx [-]
QSX10                  0.0        -1e4  1e4   Vertical force with camber on Mx [1/rad]
QSX11                  5.0        -1e4  1e4   B-factor of vertical force with camber on Mx [-]
QSX12                  0.0        -1e4  1e4   Camber squared induced overturning moment [1/rad^2]
QSX13                  0.0        -1e4  1e4   Lateral force induced overturning moment [m]
QSX14                  0.0        -1e4  1e4   Lateral force induced overturning moment with camber [m/rad]
PPMX1                  0.0        -1e4  1e4   Influence of inflation pressure on overturning moment (PAC2002 QPX1) [-]
[LATERAL_COEFFICIENTS]
PCY1                   1.3        >0    1e4   Shape factor Cfy for lateral forces [-]
PDY1                   1.1        -10   10    Lateral friction Muy at Fznom [-]
PDY2                   -0.15      -1e4  1e4   Variation of friction Muy with load [-]
PDY3                   0.0        -1e4  1e4   Variation of friction Muy with camber squared [1/rad^2]
PEY1                   0.0        -1e4  1e4   Lateral curvature Efy at Fznom [-]
PEY2                   0.0        -1e4  1e4   Variation of curvature Efy with load [-]
PEY3                   0.0        -1e4  1e4   Zero order camber dependency of curvature Efy [-]
PEY4                   0.0        -1e4  1e4   Variation of curvature Efy with camber [1/rad]
PEY5                   0.0        -1e4  1e4   Variation of curvature Efy with camber squared [1/rad^2]
PKY1                   -20.0      -1e4  1e4   Maximum value of stiffness Kfy/Fznom [-]
PKY2                   1.0        -1e4  1e4   Load at which Kfy reaches maximum value, per Fznom [-]
PKY3                   0.0        -1e4  1e4   Variation of Kfy/Fznom with camber [1/rad]
PKY4                   2.0        -1e4  1e4   Curvature of stiffness Kfy [-]
PKY5                   0.0        -1e4  1e4   Peak stiffness variation with camber squared [1/rad^2]
PKY6                   -1.0       -1e4  1e4   Fy camber stiffness factor [-]
PKY7                   0.0        -1e4  1e4   Vertical load dependency of camber stiffness [-]
PHY1                   0.0        -1e4  1e4   Horizontal shift Shy at Fznom [-]
PHY2                   0.0        -1e4  1e4   Variation of shift Shy with load [-]
PHY3                   0.0        -1e4  1e4   Variation of shift Shy with camber (MF 5.2 / PAC2002) [1/rad]
PVY1                   0.0        -1e4  1e4   Vertical shift Svy/Fz at Fznom [-]
PVY2                   0.0        -1e4  1e4   Variation of shift Svy/Fz with load [-]
PVY3                   0.0        -1e4  1e4   Variation of shift Svy/Fz with camber [1/rad]
PVY4                   0.0        -1e4  1e4   Variation of shift Svy/Fz with camber and load [1/rad]
PPY1                   0.0        -1e4  1e4   Influence of inflation pressure on cornering stiffness [-]
PPY2                   0.0        -1e4  1e4   Influence of inflation pressure on the load of peak cornering stiffness [-]
PPY3                   0.0        -1e4  1e4   Linear influence of inflation pressure on lateral peak friction [-]
PPY4                   0.0        -1e4  1e4   Quadratic influence of inflation pressure on lateral peak friction [-]
PPY5                   0.0        -1e4  1e4   Influence of inflation pressure on camber stiffness [-]
RBY1                   10.0       -1e4  1e4   Slope factor for combined Fy reduction [-]
RBY2                   10.0       -1e4  1e4   Variation of slope Fy reduction with alpha [-]
RBY3                   0.0        -1e4  1e4   Shift term for alpha in slope Fy reduction [rad]
RBY4                   0.0        -1e6  1e6   Influence of camber on stiffness of Fy combined [1/rad^2]
RCY1                   1.0        -1e4  1e4   Shape factor for combined Fy reduction [-]
REY1                   0.0        -1e4  1e4   Curvature factor of combined Fy [-]
REY2                   0.0        -1e4  1e4   Curvature factor of combined Fy with load [-]
RHY1                   0.0        -1e4  1e4   Shift factor for combined Fy reduction [-]
RHY2                   0.0        -1e4  1e4   Shift factor for combined Fy reduction with load [-]
RVY1                   0.0        -1e4  1e4   Kappa induced side force Svyk/(Muy Fz) at Fznom [-]
RVY2                   0.0        -1e4  1e4   Variation of Svyk/(Muy Fz) with load [-]
RVY3                   0.0        -1e4  1e4   Variation of Svyk/(Muy Fz) with camber [1/rad]
RVY4                   20.0       -1e4  1e4   Variation of Svyk/(Muy Fz) with alpha [1/rad]
RVY5                   2.0        -1e4  1e4   Variation of Svyk/(Muy Fz) with kappa [-]
RVY6                   10.0       -1e4  1e4   Variation of Svyk/(Muy Fz) with atan(kappa) [-]
PTY1                   0.0        -1e4  1e4   Peak value of relaxation length SigAlp0/R0 (MF 5.2) [-]
PTY2                   0.0        -1e4  1e4   Value of Fz/Fznom where SigAlp0 is extreme (MF 5.2) [-]
[ROLLING_COEFFICIENTS]
QSY1                   0.01       -1e4  1e4   Rolling resistance torque coefficient [-]
QSY2                   0.0        -1e4  1e4   Rolling resistance torque depending on Fx [-]
QSY3                   0.0004     -1e4  1e4   Rolling resistance torque depending on speed [-]
QSY4                   4e-05      -1e4  1e4   Rolling resistance torque depending on speed^4 [-]
QSY5                   0.0        -1e4  1e4   Rolling resistance torque depending on camber squared [1/rad^2]
QSY6                   0.0        -1e4  1e4   Rolling resistance torque depending on load and camber squared [1/rad^2]
QSY7                   0.85       -1e4  1e4   Rolling resistance torque coefficient load dependency [-]
QSY8                   -0.4       -1e4  1e4   Rolling resistance torque coefficient pressure dependency [-]
[ALIGNING_COEFFICIENTS]
QBZ1                   10.0       -1e4  1e4   Trail slope factor for trail Bpt at Fznom [-]
QBZ2                   0.0        -1e4  1e4   Variation of slope Bpt with load [-]
QBZ3                   0.0        -1e4  1e4   Variation of slope Bpt with load squared [-]
QBZ4                   0.0        -1e4  1e4   Variation of slope Bpt with camber [1/rad]
QBZ5                   0.0        -1e4  1e4   Variation of slope Bpt with absolute camber [1/rad]
QBZ9                   10.0       -1e4  1e4   Factor for scaling factors of slope factor Br of Mzr [-]
QBZ10                  0.0        -1e4  1e4   Factor for dimensionless cornering stiffness of Br of Mzr [-]
QCZ1                   1.1        >0    1e4   Shape factor Cpt for pneumatic trail [-]
QDZ1                   0.12       -1e4  1e4   Peak trail Dpt = Dpt*(Fz/Fznom*R0) [-]
QDZ2                   0.0        -1e4  1e4   Variation of peak Dpt with load [-]
QDZ3                   0.0        -1e4  1e4   Variation of peak Dpt with camber [1/rad]
QDZ4                   0.0        -1e4  1e4   Variation of peak Dpt with camber squared [1/rad^2]
QDZ6                   0.0        -1e4  1e4   Peak residual torque Dmr = Dmr/(Fz*R0) [-]
QDZ7                   0.0        -1e4  1e4   Variation of peak factor Dmr with load [-]
QDZ8                   -0.05      -1e4  1e4   Variation of peak factor Dmr with camber [1/rad]
QDZ9                   0.0        -1e4  1e4   Variation of peak factor Dmr with camber and load [1/rad]
QDZ10                  0.0        -1e4  1e4   Variation of peak factor Dmr with camber squared [1/rad^2]
QDZ11                  0.0        -1e4  1e4   Variation of Dmr with camber squared and load [1/rad^2]
QEZ1                   0.0        -1e4  1e4   Trail curvature Ept at Fznom [-]
QEZ2                   0.0        -1e4  1e4   Variation of curvature Ept with load [-]
QEZ3                   0.0        -1e4  1e4   Variation of curvature Ept with load squared [-]
QEZ4                   0.0        -1e4  1e4   Variation of curvature Ept with sign of alpha-t [-]
QEZ5                   0.0        -1e4  1e4   Variation of Ept with camber and sign alpha-t [1/rad]
QHZ1                   0.0        -1e4  1e4   Trail horizontal shift Sht at Fznom [rad]
QHZ2                   0.0        -1e4  1e4   Variation of shift Sht with load [rad]
QHZ3                   0.0        -1e4  1e4   Variation of shift Sht with camber [-]
QHZ4                   0.0        -1e4  1e4   Variation of shift Sht with camber and load [-]
PPZ1                   0.0        -1e4  1e4   Effect of inflation pressure on length of pneumatic trail (PAC2002 QPZ1) [-]
PPZ2                   0.0        -1e4  1e4   Influence of inflation pressure on residual aligning torque (PAC2002 QPZ2) [-]
SSZ1                   0.0        -1e4  1e4   Nominal value of s/R0: effect of Fx on Mz [-]
SSZ2                   0.0        -1e4  1e4   Variation of distance s/R0 with Fy/Fznom [-]
SSZ3                   0.0        -1e4  1e4   Variation of distance s/R0 with camber [1/rad]
SSZ4                   0.0        -1e4  1e4   Variation of distance s/R0 with load and camber [1/rad]
QTZ1                   0.0        -1e4  1e4   Gyration torque constant (MF 5.2) [-]
MBELT                  0.0        0     1e5   Belt mass of the wheel (MF 5.2) [kg]
[TURNSLIP_COEFFICIENTS]
PDXP1                  0.4        -1e4  1e4   Peak Fx reduction due to spin [-]
PDXP2                  0.0        -1e4  1e4   Peak Fx reduction due to spin with varying load [-]
PDXP3                  0.0        -1e4  1e4   Peak Fx reduction due to spin with kappa [-]
PKYP1                  1.0        -1e4  1e4   Cornering stiffness reduction due to spin [-]
PDYP1                  0.4        -1e4  1e4   Peak Fy reduction due to spin [-]
PDYP2                  0.0        -1e4  1e4   Peak Fy reduction due to spin with varying load [-]
PDYP3                  0.0        -1e4  1e4   Peak Fy reduction due to spin with alpha [-]
PDYP4                  0.0        -1e4  1e4   Peak Fy reduction due to square root of spin [-]
PHYP1                  1.0        -1e4  1e4   Fy-alpha curve lateral shift limitation [-]
PHYP2                  0.15       -1e4  1e4   Fy-alpha curve maximum lateral shift [-]
PHYP3                  0.0        -1e4  1e4   Fy-alpha curve maximum lateral shift varying with load [-]
PHYP4                  -4.0       -1e4  1e4   Fy-alpha curve maximum lateral shift parameter [-]
PECP1                  0.5        -1e4  1e4   Camber w.r.t. spin reduction factor in camber stiffness [-]
PECP2                  0.0        -1e4  1e4   Camber w.r.t. spin reduction factor varying with load [-]
QDTP1                  10.0       -1e4  1e4   Pneumatic trail reduction factor due to turn slip [-]
QCRP1                  0.2        -1e4  1e4   Turning moment at constant turning and zero forward speed [-]
QCRP2                  0.1        -1e4  1e4   Turn slip moment (at alpha = 90 deg) increase with spin [-]
QBRP1                  0.1        -1e4  1e4   Residual (spin) torque reduction factor due to side slip [-]
QDRP1                  1.0        -1e4  1e4   Turn slip moment peak magnitude [-]
[TEMPERATURE_COEFFICIENTS]
TTX1                   0.0        -1e4  1e4   Linear temperature effect on slip stiffness Kxk, per dT=(T-NOMTEMP)/NOMTEMP [-]
TTX2                   0.0        -1e4  1e4   Quadratic temperature effect on slip stiffness Kxk [-]
TTX3                   0.0        -1e4  1e4   Linear temperature effect on longitudinal friction mux [-]
TTX4                   0.0        -1e4  1e4   Quadratic temperature effect on longitudinal friction mux [-]
TTY1                   0.0        -1e4  1e4   Temperature effect on the PKY1 term of cornering stiffness Kya [-]
TTY2                   0.0        -1e4  1e4   Temperature effect on the PKY2 term (load of peak Kya) [-]
TTY3                   0.0        -1e4  1e4   Linear temperature effect on lateral friction muy [-]
TTY4                   0.0        -1e4  1e4   Quadratic temperature effect on lateral friction muy [-]
"""  # noqa: E501 (a table: one coefficient per line)


def _bound(text: str) -> tuple[float | None, bool]:
    if text == ".":
        return None, False
    if text.startswith(">"):
        return float(text[1:]), True
    return float(text), False


def _parse_table(table: str) -> dict[str, ParamSpec]:
    specs: dict[str, ParamSpec] = {}
    section = ""
    for line in table.strip().splitlines():
        if line.startswith("["):
            section = line.strip("[]")
            continue
        name, default, lo, hi, description = line.split(maxsplit=4)
        minimum, strict = _bound(lo)
        maximum, _ = _bound(hi)
        specs[name] = ParamSpec(
            name, section, float(default), description, minimum, maximum, strict
        )
    return specs


PARAMETERS: dict[str, ParamSpec] = _parse_table(_TABLE)


def section_of(name: str) -> str | None:
    """Section of a known numeric or string key, None for a key the table does not know."""
    key = name.upper()
    if key in PARAMETERS:
        return PARAMETERS[key].section
    return STRING_KEYS.get(key)


def describe(name: str) -> str:
    """One-line description with units of a known coefficient (KeyError if unknown)."""
    key = ALIASES.get(name.upper(), name.upper())
    return PARAMETERS[key].description


def default_params() -> dict[str, float]:
    """A fresh dict of every coefficient at its default (INFLPRES = NOMPRES)."""
    return {name: spec.default for name, spec in PARAMETERS.items()}


def check_value(name: str, value: float) -> str | None:
    """Why ``value`` is invalid for coefficient ``name`` (None when valid or unbounded).

    Unknown names are only checked for finiteness.
    """
    spec = PARAMETERS.get(name.upper())
    if spec is None:
        return None if math.isfinite(value) else f"{name} must be finite, got {value!r}"
    return spec.check(value)


_ORDERED_PAIRS: tuple[tuple[str, str], ...] = (
    ("PRESMIN", "PRESMAX"),
    ("FZMIN", "FZMAX"),
    ("KPUMIN", "KPUMAX"),
    ("ALPMIN", "ALPMAX"),
    ("CAMMIN", "CAMMAX"),
    ("TEMPMIN", "TEMPMAX"),
)


def limit_pair_violations(
    params: Mapping[str, float], changed: Collection[str] = ()
) -> list[tuple[str, str]]:
    """(min name, max name) of the input-range pairs (PRESMIN < PRESMAX, ...) not ordered.

    With ``changed`` given, only the pairs that involve one of those names are checked.
    """
    return [
        (lo, hi)
        for lo, hi in _ORDERED_PAIRS
        if (not changed or lo in changed or hi in changed)
        and lo in params
        and hi in params
        and not params[lo] < params[hi]
    ]


def check_limit_pairs(params: Mapping[str, float], changed: Collection[str] = ()) -> list[str]:
    """Input-range pairs (PRESMIN < PRESMAX, ...) that are not ordered, as messages.

    With ``changed`` given, only the pairs that involve one of those names are checked.
    """
    return [
        f"{lo} ({params[lo]!r}) must be < {hi} ({params[hi]!r})"
        for lo, hi in limit_pair_violations(params, changed)
    ]


def check_params(params: Mapping[str, float]) -> list[str]:
    """Every range violation in ``params``: single values and min < max of the limit pairs."""
    problems = [p for name, v in params.items() if (p := check_value(name, v)) is not None]
    return problems + check_limit_pairs(params)
