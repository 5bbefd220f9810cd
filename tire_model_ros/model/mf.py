"""``TireModel``: the Magic Formula 5.2/6.1/6.2 evaluator with the temperature extension.

The equations live in numba kernels (:mod:`.forces`, :mod:`.moments`, :mod:`.vertical`,
:mod:`.conditions`, assembled in :mod:`.kernel`); this module turns a .tir parameter set into
the coefficient vector they read, broadcasts inputs and wraps the results.

NaN or inf inputs never raise: a NaN input gives NaN in every output that depends on it (for
example a NaN slip angle gives NaN Fy, Mz, Mx, and Fx through the combined-slip weighting),
other outputs stay finite; infinite inputs are saturated like any other out-of-range input
when the limits are on, and give inf/NaN where the plain equations do when they are off.
Iterative quantities (Re, Rl) stop after a fixed number of steps, so no input can hang a call.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, fields
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from numpy.typing import ArrayLike

from . import coef as c
from .kernel import N_FORCES, N_OUT, OUT_NAMES, evaluate_batch, evaluate_point
from .params import PARAMETERS

#: (Fx, Fy, Fz [N], Mx, My, Mz [N m]) of one sample, ISO-W axes.
Wrench = tuple[float, float, float, float, float, float]

if TYPE_CHECKING:
    from .tir import TirData


def _pressure_nominal(params: Mapping[str, float]) -> float:
    """INFLPRES if given, else NOMPRES (the 'None' pressure of evaluate)."""
    infl = params.get("INFLPRES", 0.0)
    return float(infl) if infl and math.isfinite(infl) and infl > 0 else float(params["NOMPRES"])


@dataclass(frozen=True)
class MFOutput:
    """Outputs of :meth:`TireModel.evaluate`: float64 arrays of the broadcast input shape.

    Units: N, N m, m, rad/s; Kxk [N per unit slip], Kya [N/rad]. ``t`` is the pneumatic trail,
    ``Mzr`` the residual aligning torque, ``Re`` the effective rolling radius, ``Rl`` the loaded
    radius, ``rho`` the deflection, ``Cx, Cy, Cz`` the carcass stiffnesses, ``two_a, two_b`` the
    contact patch length and width. The fields after ``Mzr`` are None with ``full=False``;
    Mx, My, Mz, t and Mzr are NaN with ``moments=False``.
    """

    Fx: np.ndarray
    Fy: np.ndarray
    Fz: np.ndarray
    Mx: np.ndarray
    My: np.ndarray
    Mz: np.ndarray
    Kxk: np.ndarray
    Kya: np.ndarray
    mux: np.ndarray
    muy: np.ndarray
    t: np.ndarray
    Mzr: np.ndarray
    Re: np.ndarray | None = None
    omega: np.ndarray | None = None
    rho: np.ndarray | None = None
    Rl: np.ndarray | None = None
    Cz: np.ndarray | None = None
    Cx: np.ndarray | None = None
    Cy: np.ndarray | None = None
    sigmax: np.ndarray | None = None
    sigmay: np.ndarray | None = None
    two_a: np.ndarray | None = None
    two_b: np.ndarray | None = None
    kappa_used: np.ndarray | None = None
    alpha_used: np.ndarray | None = None
    gamma_used: np.ndarray | None = None
    p_used: np.ndarray | None = None


assert tuple(f.name for f in fields(MFOutput)) == OUT_NAMES


class TireModel:
    """An immutable Magic Formula tyre: a .tir parameter set ready to evaluate.

    Parameters
    ----------
    tir : TirData
        Parsed property file (``read_tir``); ``tir.params`` holds UPPERCASE coefficient names.
    """

    __slots__ = ("_P", "_p_nom", "_params", "_tir")

    def __init__(self, tir: TirData):
        self._tir = tir
        params = dict(tir.params)
        params["FITTYP"] = float(tir.fittyp)
        for name in c.NAMES:  # TirData from read_tir has them all; a hand-built one may not
            if name not in params:
                params[name] = PARAMETERS[name].default
        P = np.array([float(params[name]) for name in c.NAMES], dtype=np.float64)
        P.setflags(write=False)
        self._P = P
        self._params = MappingProxyType(params)
        self._p_nom = _pressure_nominal(params)

    @classmethod
    def from_file(cls, path: str | os.PathLike[str], *, lenient: bool = False) -> TireModel:
        """Read a .tir file (``read_tir``, with its ``lenient``) and build the model.

        With ``lenient``, ``model.tir.notes`` lists what was let through and filled.
        """
        from .tir import read_tir

        return cls(read_tir(path, lenient=lenient))

    @property
    def tir(self) -> TirData:
        """The parameter set this model was built from (write it with ``write_tir``)."""
        return self._tir

    @property
    def params(self) -> Mapping[str, float]:
        """Read-only view of every coefficient, defaults filled."""
        return self._params

    @property
    def coefficient_vector(self) -> np.ndarray:
        """The read-only float64 vector the kernels read (order of ``coef.NAMES``)."""
        return self._P

    def with_params(self, updates: Mapping[str, float]) -> TireModel:
        """A new model with some coefficients changed; this one is left as it was.

        Raises
        ------
        ValueError
            Unknown name, non-finite value, or a value that breaks the equations (e.g.
            FNOMIN <= 0); the message names the parameter.
        """
        # One validation for the node, the fit and the diagnosis: the parameter table's ranges.
        return TireModel(self._tir.with_params(updates))

    def _inputs(
        self,
        Fz: ArrayLike,
        kappa: ArrayLike,
        alpha: ArrayLike,
        gamma: ArrayLike,
        Vx: ArrayLike | None,
        p: ArrayLike | None,
        T: ArrayLike | None,
        phit: ArrayLike,
        omega: ArrayLike | None,
    ) -> tuple[tuple[int, ...], list[npt.NDArray[np.float64]]]:
        Vx = self._params["LONGVL"] if Vx is None else Vx
        p = self._p_nom if p is None else p
        T = self._params["NOMTEMP"] if T is None else T
        omega = math.nan if omega is None else omega
        arrays = [np.asarray(x, dtype=np.float64) for x in (Fz, kappa, alpha, gamma, Vx, p, T,
                                                             phit, omega)]  # fmt: skip
        shape = np.broadcast_shapes(*(a.shape for a in arrays))
        # one array type for the kernels (C-contiguous, writable, aligned): one compiled
        # specialization. An input of that type and of the full shape is passed as it is (the
        # kernels only read it); any other is broadcast into a new array.
        flat = []
        for a in arrays:
            f = a.flags
            if a.shape != shape or not (f.c_contiguous and f.writeable and f.aligned):
                b = np.empty(shape)
                np.copyto(b, a)
                a = b
            flat.append(a.reshape(-1))
        return shape, flat

    def evaluate(self, Fz: ArrayLike, kappa: ArrayLike, alpha: ArrayLike, gamma: ArrayLike = 0.0,
                 Vx: ArrayLike | None = None, p: ArrayLike | None = None,
                 T: ArrayLike | None = None, *, phit: ArrayLike = 0.0,
                 omega: ArrayLike | None = None, limits: bool = True, full: bool = True,
                 turn_slip: bool = False, alpha_star: bool = False,
                 moments: bool = True) -> MFOutput:  # fmt: skip
        """Evaluate the model; array inputs broadcast against each other.

        Parameters
        ----------
        Fz : vertical load [N], positive in compression.
        kappa : longitudinal slip ratio [-]. alpha : slip angle [rad]. gamma : inclination [rad].
        Vx : forward speed [m/s] (None: LONGVL). p : inflation pressure, gauge [Pa]
            (None: INFLPRES, else NOMPRES). T : tyre temperature [degC] (None: NOMTEMP).
        phit : turn slip [1/m] (path curvature); used only with ``turn_slip``.
        omega : wheel spin [rad/s] (None: from kappa and Vx); changes Re/Rl/omega, and the
            camber spin of the turn-slip model.
        limits : True = MFeval useMode 1xx (saturation to the file ranges, low-speed model,
            E <= 1), and T saturated to TEMPMIN..TEMPMAX (``[TEMPERATURE_RANGE]``, else the
            table's physical sanity range; MFeval has no temperature); False = plain equations
            (useMode 2xx).
        full : False skips the radii, stiffnesses and relaxation lengths (faster).
        moments : False skips Mx, My, Mz, t and Mzr (NaN): the forces alone, more than twice
            as fast (a fit of Fx and Fy).
        turn_slip : the turn-slip model of Pacejka 2012 §4.3.3 (spin phi from phit and the
            camber, the zeta factors), useMode xx2; False (default) = xx1, every zeta = 1.
            The wheel speed for the spin (and the reported omega, Re) is then iterated until Re
            changes by at most 1e-9 m, MFeval's test on one sample, instead of two passes.
            At phit = 0 MFeval's Mz, Mzr are 0/0 (NaN); the limit phit -> 0 is returned.
        alpha_star : alpha* = tan(alpha) sgn(Vx), gamma* = sin(gamma) in the force and
            aligning-torque equations (4.E3, 4.E4; Fy0 reversed for Vx < 0), useMode x2x;
            False (default) = x1x, alpha and gamma as given (TNO MF-Tyre).

        The MFeval useMode abc is ``limits = (a == 1)``, ``alpha_star = (b == 2)``,
        ``turn_slip = (c == 2)``. The variants run a separate compiled loop (compiled on its
        first use); the default path is unchanged by them.
        """
        shape, (Fz, kappa, alpha, gamma, Vx, p, T, phit, omega) = self._inputs(
            Fz, kappa, alpha, gamma, Vx, p, T, phit, omega
        )
        out = np.empty((N_OUT if full else N_FORCES, Fz.size))
        evaluate_batch(self._P, Fz, kappa, alpha, gamma, Vx, p, T, phit, omega, bool(limits),
                       out, turn_slip=bool(turn_slip), alpha_star=bool(alpha_star),
                       moments=bool(moments))  # fmt: skip
        values = {name: out[k].reshape(shape) for k, name in enumerate(OUT_NAMES[: out.shape[0]])}
        return MFOutput(**values)

    def evaluate_one(self, Fz: float, kappa: float, alpha: float, gamma: float, Vx: float,
                     p: float, T: float, limits: bool = True) -> Wrench:  # fmt: skip
        """(Fx, Fy, Fz, Mx, My, Mz) of one sample; all inputs required, SI units, p gauge."""
        out: Wrench = evaluate_point(self._P, float(Fz), float(kappa), float(alpha),
                                     float(gamma), float(Vx), float(p), float(T),
                                     bool(limits))  # fmt: skip
        return out

    def __repr__(self) -> str:
        path = getattr(self._tir, "path", None)
        return f"TireModel(FITTYP={int(self._P[c.FITTYP])}, path={path!r})"
