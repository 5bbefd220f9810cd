"""The ``track`` programme: four wheels of a car lapping a circuit.

A quasi-steady car: a list of manoeuvres (longitudinal and lateral acceleration held for a
while, blended smoothly) gives the speed, yaw rate and accelerations; loads come from the
static distribution plus longitudinal and lateral load transfer; each wheel's force demand
(lateral per axle by moment balance, braking with front bias, rear-wheel traction) is turned
into a slip angle / slip ratio by inverting the pure-slip Magic Formula of the tyre at the
wheel's load (done by the session with the real model, see ``invert_pure``).
The car is scaled from the tyre so it suits any .tir: static wheel load ~0.8 FNOMIN.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .programmes import CAR_PREFIXES, DEG, G_ACC, Programme, Segment, TyreInfo, WheelProgramme

if TYPE_CHECKING:
    from tire_model_ros.model import TireModel

F64 = npt.NDArray[np.float64]

# (name, duration [s], ax [g], ay [g]); ay > 0 = left turn (ISO y to the left)
LAP = (
    ("launch straight", 6.0, 0.30, 0.0),
    ("brake", 2.5, -0.80, 0.0),
    ("corner left", 4.0, 0.0, 0.85),
    ("exit accel", 4.0, 0.25, 0.35),
    ("straight", 3.0, 0.20, 0.0),
    ("brake", 2.0, -0.75, 0.0),
    ("trail brake right", 1.5, -0.40, -0.50),
    ("corner right", 3.5, 0.0, -0.90),
    ("chicane left", 1.5, 0.05, 0.60),
    ("chicane right", 1.5, 0.05, -0.60),
    ("accel", 5.0, 0.30, 0.0),
    ("brake", 2.5, -0.85, 0.0),
    ("hairpin left", 4.5, 0.0, 0.80),
    ("exit", 4.0, 0.30, 0.20),
    ("cruise", 3.0, 0.0, 0.0),
)
BLEND_S = 0.6


def _lap_profile(fs: float, laps: int) -> tuple[F64, F64, list[tuple[int, int, str, int]]]:
    """Samples of ax, ay [m/s^2] with cosine blends, and segment boundaries."""
    ax_parts: list[F64] = []
    ay_parts: list[F64] = []
    bounds: list[tuple[int, int, str, int]] = []
    prev = (0.0, 0.0)
    i = 0
    for lap in range(laps):
        for name, dur, ax_g, ay_g in LAP:
            m = round(dur * fs)
            t = np.arange(m) / fs
            w = np.clip(t / BLEND_S, 0.0, 1.0)
            w = 0.5 - 0.5 * np.cos(math.pi * w)
            ax_parts.append((prev[0] + (ax_g - prev[0]) * w) * G_ACC)
            ay_parts.append((prev[1] + (ay_g - prev[1]) * w) * G_ACC)
            bounds.append((i, i + m, name, lap))
            i += m
            prev = (ax_g, ay_g)
    return np.concatenate(ax_parts), np.concatenate(ay_parts), bounds


def build_track(tyre: TyreInfo, rate_hz: float, opt: Mapping[str, Any]) -> Programme:
    """Loads, speeds and force demands of the four wheels; slips are filled by the session
    (``WheelProgramme.kappa/alpha`` hold the *demanded* Fx/Fy until ``resolve_slips``)."""
    fs = rate_hz
    ax, ay, bounds = _lap_profile(fs, opt["laps"])
    n = len(ax)
    dt = 1.0 / fs
    V0 = 1.2 * opt["speed"]  # start a little above the tyre's nominal speed
    V = np.maximum(V0 + np.cumsum(ax) * dt, 5.0)
    ay = np.sign(ay) * np.minimum(np.abs(ay), 1.2 * G_ACC)
    # car scaled from the tyre: static wheel load 0.8 FNOMIN, 47 % front
    m = 4 * 0.8 * tyre.FNOMIN / G_ACC
    L, a_front, h, track = 2.6, 0.53 * 2.6, 0.5, 1.55  # wheelbase, CG-front, CG height, m
    b_rear = L - a_front
    front_roll_share = 0.55
    W = m * G_ACC
    stat_f, stat_r = W * b_rear / L / 2, W * a_front / L / 2
    dlong = m * ax * h / L / 2  # per wheel, to the rear under acceleration
    dlat = m * ay * h / track  # total, to the right wheels in a left turn (ay > 0)
    loads = {
        "/car/fl": stat_f - dlong - front_roll_share * dlat,
        "/car/fr": stat_f - dlong + front_roll_share * dlat,
        "/car/rl": stat_r + dlong - (1 - front_roll_share) * dlat,
        "/car/rr": stat_r + dlong + (1 - front_roll_share) * dlat,
    }
    loads = {k: np.maximum(v, 0.08 * tyre.FNOMIN) for k, v in loads.items()}
    # lateral demand per axle (moment balance), split by load within the axle
    Fy_axle = {"f": m * ay * b_rear / L, "r": m * ay * a_front / L}
    # braking 65 % front; traction on the rear wheels only
    Fx_total = m * ax
    Fx_axle = {
        "f": np.where(ax < 0, 0.65 * Fx_total, 0.0),
        "r": np.where(ax < 0, 0.35 * Fx_total, Fx_total),
    }
    r_yaw = ay / V
    wheels = []
    for pre in CAR_PREFIXES:
        axle = "f" if pre[-2] == "f" else "r"
        left = pre[-1] == "l"
        mate = pre[:-1] + ("r" if left else "l")
        share = loads[pre] / (loads[pre] + loads[mate])
        Vw = V - r_yaw * track / 2 if left else V + r_yaw * track / 2
        segs = [Segment(i0, i1, "track", f"lap {lap} {name}", {}) for i0, i1, name, lap in bounds]
        wp = WheelProgramme(
            pre,
            kappa=Fx_axle[axle] * share,
            alpha=Fy_axle[axle] * share,
            gamma=np.zeros(n),
            Fz=loads[pre],
            Vx=Vw,
            p_set=np.full(n, tyre.NOMPRES),
            segments=segs,
        )
        wp.needs_slip_inversion = True  # type: ignore[attr-defined]
        wheels.append(wp)
    opt = {
        **opt,
        "car": {
            "mass_kg": m,
            "wheelbase_m": L,
            "cg_to_front_m": a_front,
            "cg_height_m": h,
            "track_m": track,
            "brake_bias_front": 0.65,
            "drive": "rear",
        },
    }
    return Programme(
        "track", fs, wheels, np.full(n, float(opt["ambient_C"])), np.zeros(n, dtype=int), opt
    )


def invert_pure(
    model: TireModel,
    Fz: np.ndarray,
    demand: np.ndarray,
    Vx: np.ndarray,
    p: np.ndarray,
    lateral: bool,
    grid_n: int = 61,
    loads_n: int = 16,
) -> np.ndarray:
    """Slip (alpha [rad] or kappa) whose pure-slip force magnitude equals |demand| at each
    sample, on the rising branch of a (slip x load) table of the model at the mean speed and
    pressure; demands beyond 95 % of the peak give the slip of 95 % of the peak."""
    top = 15.0 * DEG if lateral else 0.25
    grid = np.linspace(0.0, top, grid_n)
    loads = np.linspace(float(Fz.min()), float(Fz.max()) + 1e-6, loads_n)
    S, L = np.meshgrid(grid, loads, indexing="ij")
    zeros = np.zeros_like(S)
    V, P = float(np.mean(Vx)), float(np.mean(p))
    if lateral:  # positive alpha gives negative Fy: the magnitude for +alpha
        o = model.evaluate(L, zeros, S, 0.0, V, P)
        mag = o.Fy[:1] - o.Fy
    else:
        o = model.evaluate(L, S, zeros, 0.0, V, P)
        mag = o.Fx - o.Fx[:1]
    mag = np.maximum.accumulate(np.maximum(mag, 0.0), axis=0)  # rising branch only
    # per-sample curve: linear in load between the two nearest table loads
    x = np.interp(Fz, loads, np.arange(loads_n))
    i0 = np.minimum(x.astype(int), loads_n - 2)
    w = x - i0
    curve = mag[:, i0] * (1.0 - w) + mag[:, i0 + 1] * w  # (grid_n, n)
    want = np.minimum(np.abs(demand), 0.95 * curve[-1])
    k = np.clip(np.sum(curve < want, axis=0) - 1, 0, grid_n - 2)
    cols = np.arange(len(Fz))
    lo, hi = curve[k, cols], curve[k + 1, cols]
    frac = np.where(hi > lo, (want - lo) / np.where(hi > lo, hi - lo, 1.0), 0.0)
    out = grid[k] + np.clip(frac, 0.0, 1.0) * (grid[1] - grid[0])
    sign = -np.sign(demand) if lateral else np.sign(demand)
    return sign * out
