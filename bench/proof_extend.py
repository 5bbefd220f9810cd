"""Proof of ``fit --extend`` on a truth the fit cannot see (``make proof-extend``).

The seed paper's situation on the virtual rig, with the tyre of ``config/default.tir`` and the
rig's own physics (a grip window in the tread surface's temperature, stiffness falling with the
carcass', sidewall contact):

1. the rig: ``safe_envelope`` (loads 40-120 %, pressures 85-115 % NOMPRES at 25 degC), the tyre
   heating as it runs, no temperature channel;
2. the simulation: ``special_conditions`` (an FE model: isothermal at set temperatures, the
   rig's conditions and the seed's 60/140/220 kPa, 120/140/160 % load, -10/40/80 degC, with
   sidewall contact), its friction input 5 % too high (``mu_step`` from t = 0) and numerical
   noise;
3. the truth: the same conditions run noise-free without the friction error: the tyre itself,
   held at each temperature. Neither fit sees it;
4. the real command lines, from START (the tyre's file without pressure and temperature terms,
   its friction and stiffness off by up to 10 %: what an engineer starts from):
   ``tire-model fit RIG --tir START -o fused.tir --extend SIM`` and the rig-only
   ``tire-model fit RIG --tir START -o rig_only.tir``; for reference the simulation alone.

Scored per group of special conditions (low pressure: 60 kPa at 120 % load; high load: 140 and
160 % at 60 kPa; cold: -10 degC; hot: 80 degC, at 220 kPa and 120 %), Fx on the pure
longitudinal and Fy on the pure lateral samples: NRMSE = RMSE / (max - min of the truth) of
each model against the truth, outside the sidewall-contact corner (where the truth's Fy is
more than 0.1 % below the tyre's without it; reported apart). Targets (issue 15): fused
<= 2 % everywhere outside the corner, at least 3x lower than rig-only at low pressure and at
-10/80 degC, ``temperature`` named as the difference between rig and simulation, the ranges
widened to the fitted conditions. Prints the table and writes proof_extend.json.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

ROOT = Path(__file__).resolve().parents[1]
_SCRIPT = Path(sys.executable).with_name("tire-model")
TOOL = [str(_SCRIPT)] if _SCRIPT.is_file() else [sys.executable, "-m", "tire_model_ros.cli"]
FIT_TIMEOUT_S = 3600.0
FE_FRICTION_ERROR = 1.05  # the simulation's friction input against the tyre's
# START: the tyre's file as an engineer would start: no pressure or temperature terms, its
# friction and stiffness off.
ZEROED = (
    *("PPX1", "PPX2", "PPX3", "PPX4", "PPY1", "PPY2", "PPY3", "PPY4", "PPY5", "PPZ1"),
    *("TTX1", "TTX2", "TTX3", "TTX4", "TTY1", "TTY2", "TTY3", "TTY4"),
)
OFF = {"PDX1": 0.92, "PDY1": 1.08, "PKX1": 0.9, "PKY1": 1.1}
# Groups: load [FNOMIN] (low, high), pressure [kPa], temperature [degC] or None (nominal).
GROUPS = {
    "low pressure": ((1.15, 1.25), 60.0, None),
    "high load": ((1.35, 1.65), 60.0, None),
    "cold": ((1.15, 1.25), 220.0, -10.0),
    "hot": ((1.15, 1.25), 220.0, 80.0),
}
TARGET_NRMSE = 0.02
TARGET_RATIO = 3.0
RATIO_GROUPS = ("low pressure", "cold", "hot")
PURE_KAPPA = 0.002
PURE_ALPHA_RAD = math.radians(0.2)
CORNER_LOSS = 1e-3

Bools = npt.NDArray[np.bool_]


def run(cmd: list[str], log: Path) -> float:
    """A command line, its output into ``log``; its wall time [s]."""
    t0 = time.monotonic()
    with open(log, "w") as fh:
        proc = subprocess.run(cmd, stdout=fh, stderr=subprocess.STDOUT, timeout=FIT_TIMEOUT_S)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}); see {log}")
    return time.monotonic() - t0


def record(tir: Path, out: Path, seed: int) -> tuple[Path, Path, Any]:
    """The rig's and the simulation's recordings; the truth's noise-free wheel."""
    from tire_model_ros.model import TireModel
    from tire_model_ros.rig import simulate_session, write_session

    truth_model = TireModel.from_file(tir)
    rig, rig_truth = simulate_session(truth_model, "safe_envelope", seed=seed)
    bias = {"mu_step": {"ratio": FE_FRICTION_ERROR, "at_s": 0.0}}
    sim, sim_truth = simulate_session(
        truth_model, "special_conditions", seed=seed + 1, effects=bias
    )
    write_session(out / "rig", rig, rig_truth)
    write_session(out / "sim", sim, sim_truth)
    truth, _ = simulate_session(truth_model, "special_conditions", effects={"noise": False})
    flat, _ = simulate_session(
        truth_model, "special_conditions", effects={"noise": False, "sidewall": False}
    )
    Fy, Fy_flat = truth[0].Fy, flat[0].Fy
    if Fy is None or Fy_flat is None:
        raise RuntimeError("special_conditions recorded no Fy")
    corner = np.abs(Fy) < (1.0 - CORNER_LOSS) * np.abs(Fy_flat)
    truth[0].meta["corner"] = corner
    return out / "rig", out / "sim", truth[0]


def start_tir(tir: Path, out: Path) -> Path:
    from tire_model_ros.model import TireModel, write_tir

    m = TireModel.from_file(tir)
    changes = {k: 0.0 for k in ZEROED} | {k: f * m.params[k] for k, f in OFF.items()}
    path = out / "start.tir"
    write_tir(m.with_params(changes).tir, path)
    return path


def group_masks(w: Any, FNOMIN: float, T_nom: float) -> dict[str, Bools]:
    out = {}
    for name, ((lo, hi), p_kPa, T) in GROUPS.items():
        m = (w.Fz >= lo * FNOMIN) & (w.Fz <= hi * FNOMIN) & (np.abs(w.p - 1e3 * p_kPa) < 2e3)
        out[name] = m & (np.abs(w.T - (T_nom if T is None else T)) < 0.5)
    return out


def score(model_path: Path, truth: Any) -> dict[str, dict[str, float | None]]:
    """NRMSE per group and channel outside the corner, and in it (Fy)."""
    from tire_model_ros.model import TireModel

    m = TireModel.from_file(model_path)
    o = m.evaluate(truth.Fz, truth.kappa, truth.alpha, truth.gamma, truth.Vx, truth.p, truth.T)
    corner = truth.meta["corner"]
    res: dict[str, dict[str, float | None]] = {}
    for name, g in group_masks(truth, m.params["FNOMIN"], 25.0).items():
        lon = g & (np.abs(truth.alpha) < PURE_ALPHA_RAD) & (np.abs(truth.kappa) > 0)
        lat = g & (np.abs(truth.kappa) < PURE_KAPPA) & (np.abs(truth.alpha) > 0)
        res[name] = {
            "Fx": _nrmse(truth.Fx, o.Fx, lon),
            "Fy": _nrmse(truth.Fy, o.Fy, lat & ~corner, truth.Fy[lat]),
            "Fy_corner": _nrmse(truth.Fy, o.Fy, lat & corner, truth.Fy[lat]),
        }
    return res


def _nrmse(y: Any, pred: Any, sel: Bools, ref: Any = None) -> float | None:
    """RMSE on ``sel`` over the range of ``ref`` (default: of the selected truth)."""
    if sel.sum() < 10:
        return None
    span = np.ptp(y[sel] if ref is None else ref)
    return float(np.sqrt(np.mean((pred[sel] - y[sel]) ** 2)) / span)


def verdict(scores: dict[str, Any], ext: dict[str, Any]) -> list[str]:
    """The targets, one line each, 'met' or 'NOT met'."""
    fused, rig = scores["fused"], scores["rig_only"]
    worst = max(v for g in fused.values() for k, v in g.items() if k != "Fy_corner" and v)
    lines = [f"fused NRMSE <= {TARGET_NRMSE:.0%} outside the corner: worst {worst:.2%} "
             f"({'met' if worst <= TARGET_NRMSE else 'NOT met'})"]  # fmt: skip
    for g in RATIO_GROUPS:
        for c in ("Fx", "Fy"):
            r = (rig[g][c] or 0.0) / max(fused[g][c] or 1e-12, 1e-12)
            ok = "met" if r >= TARGET_RATIO else "NOT met"
            lines.append(f"{g} {c}: rig-only / fused = {r:.1f} (>= {TARGET_RATIO:g}: {ok})")
    words = ext["comparison"]["words"]
    lines.append(f"difference named: {', '.join(words)} "
                 f"({'met' if 'temperature' in words else 'NOT met'})")  # fmt: skip
    r = ext["ranges"]
    wide = (r["PRESMIN"]["fused"] <= 60e3 and r["TEMPMIN"]["fused"] <= -10
            and r["TEMPMAX"]["fused"] >= 80)  # fmt: skip
    lines.append(
        "ranges: "
        + ", ".join(f"{k} {v['start']:g} -> {v['fused']:g}" for k, v in r.items())
        + f" ({'met' if wide else 'NOT met'})"
    )
    return lines


def table(scores: dict[str, Any]) -> list[str]:
    lines = [
        "| group | channel | fused | rig-only | simulation only |",
        "| --- | --- | --- | --- | --- |",
    ]
    for g in GROUPS:
        for c in ("Fx", "Fy", "Fy_corner"):
            vals = [scores[k][g][c] for k in ("fused", "rig_only", "sim_only")]
            label = "Fy in the sidewall corner" if c == "Fy_corner" else c
            cells = " | ".join("-" if v is None else f"{100 * v:.2f} %" for v in vals)
            lines.append(f"| {g} | {label} | {cells} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--out", type=Path, default=None, help="keep the files here (new folder)")
    args = ap.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix="proof_extend_"))
    out.mkdir(parents=True, exist_ok=True)
    tir = ROOT / "config" / "default.tir"
    t0 = time.monotonic()
    rig, sim, truth = record(tir, out, args.seed)
    start = start_tir(tir, out)
    times = {
        "fused": run([*TOOL, "fit", str(rig), "--tir", str(start), "-o", str(out / "fused.tir"),
                      "--extend", str(sim)], out / "fused.log"),
        "rig_only": run([*TOOL, "fit", str(rig), "--tir", str(start), "-o",
                         str(out / "rig_only.tir")], out / "rig_only.log"),
        "sim_only": run([*TOOL, "fit", str(sim), "--tir", str(start), "-o",
                         str(out / "sim_only.tir")], out / "sim_only.log"),
    }  # fmt: skip
    scores = {k: score(out / f"{k}.tir", truth) for k in times}
    ext = json.loads((out / "fused_fit_report" / "extension.json").read_text())
    lines = [
        f"proof of fit --extend (seed {args.seed}; files in {out})",
        f"the simulation's friction is {FE_FRICTION_ERROR:g} x the tyre's; NRMSE against the "
        "truth (the tyre held at each condition, noise-free), outside the sidewall corner:",
        *table(scores),
        *verdict(scores, ext),
        "wall time: "
        + ", ".join(f"{k} {v:.0f} s" for k, v in times.items())
        + f"; total {time.monotonic() - t0:.0f} s",
    ]
    print("\n".join(lines))
    result = {"seed": args.seed, "scores": scores, "extension": ext, "times_s": times,
              "verdict": verdict(scores, ext)}  # fmt: skip
    (out / "proof_extend.json").write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
