"""The base tyre of the flattrac generator and the property files derived from it.

The steady-state force law of the tyre at its nominal conditions is the Magic Formula of a
public .tir file, evaluated with ``tire_model_ros.model.TireModel`` (allowed by the brief).
Files without inflation-pressure terms get a pressure behaviour of our own (the MF 6.1 pressure
terms of a passenger-car fit, scaled per seed), so that the tyre has one consistent pressure
dependence in every case. Everything the generator adds on top (heat, wear, relaxation, ...)
lives in :mod:`.physics`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tire_model_ros.model import TireModel, read_tir, write_tir
from tire_model_ros.model.params import PRESSURE_COEFFICIENTS

# the shared checkout beside the project root (as test/conftest.py finds it)
REF_DIR = Path(__file__).resolve().parents[3] / "shared" / "reference" / "tir"
TYRES = ("MagicFormula61_Parameters.tir", "PacejkaBook_Defaults.tir", "FSAE_Defaults.tir")

# Our own pressure behaviour for files that have none: the shape of a passenger-car MF 6.1
# pressure fit (signs and magnitudes of a 205/60R15-like tyre), scaled by a factor per seed.
# +10 % pressure: Kya about -6 %, Kxk about -1..-3 %, mu about -1..+2 %.
OWN_PRESSURE_TERMS = {
    "PPX1": -0.35, "PPX2": 0.20, "PPX3": -0.05, "PPX4": -0.40,
    "PPY1": 0.0, "PPY2": 0.90, "PPY3": -0.10, "PPY4": -0.10, "PPY5": -0.80,
    "PPZ1": 0.90, "PPZ2": 0.50, "PPMX1": -0.03,
}  # fmt: skip

# Every coefficient that carries inclination (camber) in MF 5.2/6.1/6.2 (forces, moments,
# combined slip, vertical); zeroed in the camber case's model.tir.
CAMBER_COEFFICIENTS = (
    "PDX3", "RBX3",
    "PDY3", "PEY4", "PEY5", "PKY3", "PKY5", "PKY6", "PKY7", "PHY3", "PVY3", "PVY4", "PPY5",
    "RBY4", "RVY3",
    "QSX2", "QSX7", "QSX10", "QSX12", "QSX14",
    "QSY5", "QSY6",
    "QBZ4", "QBZ5", "QDZ3", "QDZ4", "QDZ8", "QDZ9", "QDZ10", "QDZ11", "QEZ5", "QHZ3", "QHZ4",
    "SSZ3", "SSZ4",
    "Q_CAM", "Q_CAM1", "Q_CAM2", "Q_CAM3", "Q_FYS1", "Q_FYS2", "Q_FYS3",
)  # fmt: skip

# Combined-slip weighting set to 1 (B = 0 makes cos(C atan(B x ...)) = 1; no kappa-induced Fy).
COMBINED_NEUTRAL = {
    "RBX1": 0.0, "RBX2": 0.0, "RBX3": 0.0, "RCX1": 1.0, "REX1": 0.0, "REX2": 0.0, "RHX1": 0.0,
    "RBY1": 0.0, "RBY2": 0.0, "RBY3": 0.0, "RBY4": 0.0, "RCY1": 1.0, "REY1": 0.0, "REY2": 0.0,
    "RHY1": 0.0, "RHY2": 0.0,
    "RVY1": 0.0, "RVY2": 0.0, "RVY3": 0.0, "RVY4": 0.0, "RVY5": 0.0, "RVY6": 0.0,
}  # fmt: skip

TEMPERATURE_COEFFICIENTS = ("TTX1", "TTX2", "TTX3", "TTX4", "TTY1", "TTY2", "TTY3", "TTY4")


class BaseTyre:
    """The tyre of one generated session: a TirData plus our additions."""

    def __init__(self, rng: np.random.Generator, name: str | None = None):
        self.name = name or TYRES[int(rng.integers(len(TYRES)))]
        tir = read_tir(REF_DIR / self.name)
        P = tir.params
        updates: dict[str, float] = {}
        self.own_pressure = all(P.get(k, 0.0) == 0.0 for k in ("PPX1", "PPY1", "PPY3"))
        scale = float(rng.uniform(0.8, 1.2))
        if self.own_pressure:
            updates.update({k: v * scale for k, v in OWN_PRESSURE_TERMS.items()})
        self.pressure_scale = scale if self.own_pressure else 1.0
        for k in TEMPERATURE_COEFFICIENTS:  # our heat physics never goes through TTX/TTY
            if P.get(k, 0.0) != 0.0:
                updates[k] = 0.0
        self.tir = tir.with_params(updates) if updates else tir
        self.P = dict(self.tir.params)
        self.Fz0 = float(self.P["FNOMIN"])
        self.p0 = float(self.P["INFLPRES"])  # the nominal (cold set) gauge pressure
        self.R0 = float(self.P["UNLOADED_RADIUS"])
        self.V0 = float(self.P["LONGVL"])
        self.model = TireModel(self.tir)
        # friction level and size class (for heat capacities, noise, relaxation lengths)
        o = self.model.evaluate(self.Fz0, 0.0, np.radians(np.linspace(0, 25, 60)), 0.0,
                                self.V0, self.p0, full=False)  # fmt: skip
        self.mu_y = float(np.max(np.abs(o.Fy)) / self.Fz0)
        self.size = self.Fz0 * self.mu_y / 4000.0  # ~1 for a 4 kN car tyre
        self.car = self.name != "FSAE_Defaults.tir"

    def widen_ranges(self, p_min: float, p_max: float, fz_max: float) -> None:
        """Let the file's validity ranges cover the programme (the lab characterised there)."""
        P = self.P
        upd = {}
        if p_min < P["PRESMIN"]:
            upd["PRESMIN"] = float(np.floor(0.9 * p_min / 1000.0) * 1000.0)
        if p_max > P["PRESMAX"]:
            upd["PRESMAX"] = float(np.ceil(1.1 * p_max / 1000.0) * 1000.0)
        if fz_max > P["FZMAX"]:
            upd["FZMAX"] = float(np.ceil(1.2 * fz_max / 100.0) * 100.0)
        if upd:
            self.tir = self.tir.with_params(upd)
            self.P = dict(self.tir.params)
            self.model = TireModel(self.tir)

    def variant(self, *, no_pressure=False, no_camber=False, no_combined=False, nomtemp=None):
        """A TireModel of this tyre with some physics removed (for model.tir and 'without')."""
        upd: dict[str, float] = {}
        if no_pressure:
            upd.update({k: 0.0 for k in PRESSURE_COEFFICIENTS if k in self.P})
        if no_camber:
            upd.update({k: 0.0 for k in CAMBER_COEFFICIENTS if k in self.P})
        if no_combined:
            upd.update(COMBINED_NEUTRAL)
        if nomtemp is not None:
            upd["NOMTEMP"] = float(nomtemp)
            upd.update({k: 0.0 for k in TEMPERATURE_COEFFICIENTS})
        return TireModel(self.tir.with_params(upd)) if upd else self.model

    def write_model_tir(self, path, model: TireModel) -> None:
        write_tir(model.tir, path)
