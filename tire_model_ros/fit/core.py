"""Bounded robust least squares of named Magic Formula coefficients on recorded samples.

One call fits a few coefficients of a :class:`~tire_model_ros.model.TireModel` to the measured
channels of one or more :class:`WheelSeries`. The model is evaluated on the recorded inputs
(pressure, temperature and speed where recorded, the file's nominal values otherwise) through its
vectorised batch path, so one evaluation of 10^5 samples costs milliseconds and a fit of ten
coefficients a few seconds.

Residuals are measured - model (the sign the fit report and the diagnosis use), scaled per
channel by a robust estimate of the measurement noise (so Fx [N] and Mz [N m] weigh alike),
and the robust loss switches from quadratic to linear at ``f_scale`` noise levels: outliers
and unmodelled spikes pull with a bounded force.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from tire_model_ros.recording.series import WheelSeries
from tire_model_ros.vocabulary import FORCE_CHANNELS, MODEL_INPUTS

from .sweeps import noise_sigma

if TYPE_CHECKING:
    from tire_model_ros.model import MFOutput, TireModel

# Coefficients that scale a peak, a stiffness or a shape factor: their sign must not change
# (C > 0, D > 0 and the stiffness sign of the file), so the bounds keep them on their side.
SIGN_KEEPING = frozenset(
    [
        "PCX1",
        "PDX1",
        "PKX1",
        "PCY1",
        "PDY1",
        "PKY1",
        "PKY2",
        "PKY4",
        "QBZ1",
        "QCZ1",
        "QDZ1",
        "RBX1",
        "RCX1",
        "RBY1",
        "RCY1",
    ]
)
# Curvature factors: E <= 1 (the formula folds over beyond it).
CURVATURE = frozenset(["PEX1", "PEY1", "QEZ1", "REX1", "REY1"])


def default_bounds(name: str, x0: float) -> tuple[float, float]:
    """Physical search range of one coefficient around its start value ``x0``."""
    if name in SIGN_KEEPING and x0 != 0.0:
        a, b = 0.2 * x0, 5.0 * x0
        return (min(a, b), max(a, b))
    if name in CURVATURE:
        return (min(-20.0, x0 - 1.0), 1.0)
    if name.startswith(("PPX", "PPY", "PPZ", "TTX", "TTY")):
        return (min(-3.0, x0 - 1.0), max(3.0, x0 + 1.0))
    span = max(10.0 * abs(x0), 1.0)
    return (x0 - span, x0 + span)


def default_scale(name: str, x0: float) -> float:
    """Typical magnitude of a coefficient, for ``x_scale`` (zero start values get a floor)."""
    if name.startswith(("PHX", "PHY", "QHZ", "RHX", "RHY")):
        floor = 1e-2  # horizontal shifts are small slips
    elif name.startswith(("PVX", "PVY", "RVY")):
        floor = 2e-2
    else:
        floor = 0.1
    return max(abs(x0), floor)


def _as_list(value: Any, lengths: Sequence[int], what: str) -> list[np.ndarray]:
    """Per-series arrays from a list (one per series) or one concatenated array."""
    if isinstance(value, (list, tuple)):
        if len(value) != len(lengths):
            raise ValueError(f"{what}: {len(value)} arrays for {len(lengths)} series")
        out = [
            np.broadcast_to(np.asarray(v, dtype=np.float64), (n,))
            for v, n in zip(value, lengths, strict=True)
        ]
        return out
    arr = np.asarray(value, dtype=np.float64)
    total = int(sum(lengths))
    if arr.ndim == 0:
        arr = np.full(total, float(arr))
    if arr.shape != (total,):
        raise ValueError(f"{what}: shape {arr.shape}, expected ({total},) or a list per series")
    return list(np.split(arr, np.cumsum(lengths)[:-1]))


def nominal_inputs(model: TireModel) -> dict[str, float]:
    """Values the node uses when an optional input never arrives."""
    P = model.params
    p_nom = P.get("INFLPRES", 0.0) or P.get("NOMPRES", 0.0)
    return {
        "Vx": float(P.get("LONGVL", 16.7)),
        "p": float(p_nom),
        "T": float(P.get("NOMTEMP", 25.0)),
    }


def stack_inputs(
    model: TireModel,
    series_list: Sequence[WheelSeries],
    channels: Sequence[str],
    extra_inputs: Mapping[str, Any] | None = None,
) -> tuple[dict[str, np.ndarray | None], dict[str, np.ndarray], np.ndarray]:
    """Concatenate inputs and measured channels of several series.

    Returns ``(inputs, measured, valid)``: ``inputs[k]`` is None when no series records ``k``
    (the model then uses its nominal value), a series lacking a channel that others record gets
    the nominal value; ``measured[c]`` has NaN where channel ``c`` is missing; ``valid`` marks the
    rows whose inputs are all finite.
    """
    lengths = [len(s) for s in series_list]
    nominal = nominal_inputs(model)
    inputs: dict[str, np.ndarray | None] = {}
    for k in MODEL_INPUTS:
        arrays = [getattr(s, k) for s in series_list]
        if all(a is None for a in arrays):
            inputs[k] = None
            continue
        inputs[k] = np.concatenate(
            [
                np.asarray(a, dtype=np.float64) if a is not None else np.full(n, nominal[k])
                for a, n in zip(arrays, lengths, strict=True)
            ]
        )
    for k, v in (extra_inputs or {}).items():
        if v is None:
            continue
        inputs[k] = np.concatenate(_as_list(v, lengths, f"extra input {k}"))
    measured = {}
    for c in channels:
        if c not in FORCE_CHANNELS:
            raise ValueError(f"unknown channel {c!r}; expected one of {', '.join(FORCE_CHANNELS)}")
        measured[c] = np.concatenate(
            [
                np.asarray(getattr(s, c), dtype=np.float64)
                if getattr(s, c) is not None
                else np.full(n, np.nan)
                for s, n in zip(series_list, lengths, strict=True)
            ]
        )
    total = int(sum(lengths))
    valid = np.ones(total, dtype=bool)
    for v in inputs.values():
        if v is not None and np.ndim(v) == 1:
            valid &= np.isfinite(v)
    return inputs, measured, valid


def evaluate_on(
    model: TireModel, inputs: Mapping[str, np.ndarray | None], limits: bool = True
) -> MFOutput:
    """Evaluate ``model`` on stacked inputs (batch path): an MFOutput."""
    kw: dict[str, Any] = dict(inputs)
    Fz, kappa, alpha = (kw.pop(k) for k in ("Fz", "kappa", "alpha"))
    g = kw.pop("gamma", None)
    gamma = 0.0 if g is None else g
    # forces and moments only: the batch path skips radii and relaxation lengths
    return model.evaluate(Fz, kappa, alpha, gamma, limits=limits, full=False, **kw)


def _channel_sigma(series_list: Sequence[WheelSeries], channel: str) -> float:
    """Noise level of a measured channel, pooled over the series, with a floor."""
    sig: list[float] = []
    rng: list[float] = []
    for s in series_list:
        y = getattr(s, channel)
        if y is None:
            continue
        y = np.asarray(y, dtype=np.float64)
        finite = y[np.isfinite(y)]
        if len(finite) < 5:
            continue
        sig.append(noise_sigma(y))
        q = np.percentile(finite, [1.0, 99.0])
        rng.append(float(q[1] - q[0]))
    if not sig:
        return 1.0
    floor = max(1e-3 * max(rng), 1e-6)  # noise-free data: 0.1 % of the range
    return max(float(np.median(sig)), floor)


def robust_cost(r: np.ndarray, loss: str, f_scale: float) -> float:
    """The cost ``least_squares`` minimises: 0.5 * f^2 * sum(rho((r/f)^2))."""
    z = (np.asarray(r) / f_scale) ** 2
    if loss == "linear":
        rho = z
    elif loss == "soft_l1":
        rho = 2.0 * (np.sqrt(1.0 + z) - 1.0)
    elif loss == "huber":
        rho = np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)
    elif loss == "cauchy":
        rho = np.log1p(z)
    elif loss == "arctan":
        rho = np.arctan(z)
    else:
        raise ValueError(f"unknown loss {loss!r}")
    return float(0.5 * f_scale**2 * np.sum(rho))


def _integrated_autocorr(r: np.ndarray, lengths: Sequence[int], max_lag: int = 300) -> float:
    """Integrated autocorrelation time 1 + 2 sum(rho_k) of residuals (>= 1), per channel block,
    summed until the autocorrelation first drops below 0.05: m / tau independent samples."""
    taus, weights = [], []
    start = 0
    for n in lengths:
        x = np.asarray(r[start : start + n], dtype=np.float64)
        start += n
        if n < 10:
            continue
        x = x - x.mean()
        nfft = 1 << int(np.ceil(np.log2(2 * n)))
        f = np.fft.rfft(x, nfft)
        acf = np.fft.irfft(f * np.conj(f), nfft)[: min(n, max_lag + 1)]
        if acf[0] <= 0:
            continue
        acf = acf / acf[0]
        below = np.flatnonzero(acf[1:] < 0.05)
        k = int(below[0]) if len(below) else len(acf) - 1
        taus.append(1.0 + 2.0 * float(np.sum(acf[1 : k + 1])))
        weights.append(n)
    if not taus:
        return 1.0
    return max(1.0, float(np.average(taus, weights=weights)))


def _lag1(r: np.ndarray) -> float:
    """Lag-1 autocorrelation of a residual sequence (0 when undefined)."""
    if len(r) < 3:
        return 0.0
    r = r - r.mean()
    den = float(np.dot(r, r))
    return float(np.dot(r[1:], r[:-1]) / den) if den > 0 else 0.0


def _standard_errors(jac: np.ndarray, cost: float, m: int, n: int) -> np.ndarray:
    """Gauss-Newton standard errors: sqrt(diag(inv(J'J)) * 2*cost/(m-n)), pinv if singular."""
    if m <= n:
        return np.full(n, np.inf)
    s2 = 2.0 * cost / (m - n)
    jtj = jac.T @ jac
    try:
        cov = np.linalg.pinv(jtj, rcond=1e-12)
    except np.linalg.LinAlgError:
        return np.full(n, np.inf)
    stderr: npt.NDArray[np.float64] = np.sqrt(np.clip(np.diag(cov), 0.0, None) * s2)
    return stderr


def fit_coefficients(
    model: TireModel,
    series_list: Sequence[WheelSeries],
    names: Sequence[str],
    channels: Sequence[str] = ("Fx", "Fy"),
    weights: Mapping[str, float] | Sequence[np.ndarray] | np.ndarray | None = None,
    loss: str = "soft_l1",
    extra_inputs: Mapping[str, Any] | None = None,
    *,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    f_scale: float = 3.0,
    max_samples: int | None = 10_000,
    max_nfev: int | None = None,
    limits: bool = True,
    min_samples: int | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> tuple[TireModel, dict[str, Any]]:
    """Fit the coefficients ``names`` of ``model`` to the measured ``channels``.

    Parameters
    ----------
    model : TireModel
        Start model; its values of ``names`` are the start point.
    series_list : sequence of WheelSeries
        Samples to fit (select subsets beforehand with ``WheelSeries.select``).
    names : sequence of str
        UPPERCASE coefficient names (e.g. ``("PDY1", "PKY1")``).
    channels : sequence of str
        Measured channels to match: any of Fx, Fy, Mx, My, Mz.
    weights : mapping or array, optional
        A mapping channel -> multiplier of that channel's residuals, or per-sample weights (one
        array per series, or one concatenated array). Residuals are already divided by each
        channel's noise level.
    loss : str
        ``least_squares`` loss: "soft_l1" (default), "huber", "cauchy", "linear".
    extra_inputs : mapping, optional
        Model inputs that replace or add to the recorded ones, e.g. ``{"T": [T_est]}`` (one
        array per series, or concatenated).
    bounds : mapping, optional
        Per-name (lo, hi); others get :func:`default_bounds`.
    f_scale : float
        Soft margin of the robust loss in noise levels.
    max_samples : int or None
        Uniform decimation above this many rows (100 Hz rows are autocorrelated: little is lost).
    min_samples : int or None
        Fewest usable rows (default max(20, 5 per coefficient)); fewer raise ValueError.
    progress : callable, optional
        Called as ``progress(nfev, cost)`` after each model evaluation.

    Returns
    -------
    (TireModel, dict)
        The fitted model and ``info``: names, x0, x, stderr (inflated for residual
        autocorrelation), stderr_iid, cost, nfev, status, message, success, n_used, sigma (noise
        per channel), rmse_before/rmse_after per channel, rho1, at_bound, time_s.
    """
    t0 = time.perf_counter()
    names = list(names)
    unknown = [k for k in names if k not in model.params]
    if unknown:
        raise ValueError(f"unknown coefficient(s): {', '.join(unknown)}")
    if not series_list:
        raise ValueError("no samples to fit")
    channels = [c for c in channels]
    inputs, measured, valid = stack_inputs(model, series_list, channels, extra_inputs)
    total = len(valid)
    lengths = [len(s) for s in series_list]

    sample_w = np.ones(total)
    chan_w = {c: 1.0 for c in channels}
    if isinstance(weights, Mapping):
        chan_w.update({c: float(w) for c, w in weights.items() if c in chan_w})
    elif weights is not None:
        sample_w = np.concatenate(_as_list(weights, lengths, "weights"))
        valid &= np.isfinite(sample_w) & (sample_w > 0)

    # Decimate uniformly (keeps time order, so lag-1 autocorrelation stays meaningful).
    rows = np.flatnonzero(valid)
    if max_samples is not None and len(rows) > max_samples:
        rows = rows[:: int(np.ceil(len(rows) / max_samples))]
    sub = {k: (v[rows] if v is not None and np.ndim(v) == 1 else v) for k, v in inputs.items()}
    sigma = {c: _channel_sigma(series_list, c) for c in channels}
    masks, targets, scales = {}, {}, {}
    for c in channels:
        y = measured[c][rows]
        masks[c] = np.isfinite(y)
        targets[c] = y[masks[c]]
        scales[c] = chan_w[c] * sample_w[rows][masks[c]] / sigma[c]
    m = int(sum(len(v) for v in targets.values()))
    need = min_samples if min_samples is not None else max(20, 5 * len(names))
    if m < need:
        raise ValueError(
            f"too few samples to fit {', '.join(names) or 'nothing'} on "
            f"{'/'.join(channels)}: {m} usable of {total} (need {need})"
        )

    x0 = np.array([float(model.params[k]) for k in names])
    bnd = {k: (bounds or {}).get(k) or default_bounds(k, v) for k, v in zip(names, x0, strict=True)}
    lo = np.array([bnd[k][0] for k in names])
    hi = np.array([bnd[k][1] for k in names])
    xs = np.array([default_scale(k, v) for k, v in zip(names, x0, strict=True)])
    # least_squares wants a strictly feasible start.
    x_start = np.clip(x0, lo + 1e-9 * xs, hi - 1e-9 * xs) if names else x0
    nfev = [0]

    def predict(x: np.ndarray) -> MFOutput:
        mod = model.with_params(dict(zip(names, map(float, x), strict=True))) if names else model
        return evaluate_on(mod, sub, limits=limits)

    def residuals(x: np.ndarray) -> np.ndarray:
        try:
            out = predict(x)
        except ValueError:  # a value the model refuses (e.g. a divisor at 0): a wall, not a crash
            return np.full(m, 1e6)
        parts = []
        for c in channels:
            pred = np.asarray(getattr(out, c), dtype=np.float64)[masks[c]]
            parts.append((targets[c] - pred) * scales[c])  # measured - model, as everywhere
        r = np.concatenate(parts)
        nfev[0] += 1
        if progress is not None:
            progress(nfev[0], 0.5 * float(np.dot(r, r)))
        # A non-finite model output must not derail the solver: a large finite penalty.
        return np.where(np.isfinite(r), r, 1e6)

    def rmse(x: np.ndarray) -> dict[str, float]:
        out = predict(x)
        res = {}
        for c in channels:
            d = targets[c] - np.asarray(getattr(out, c), dtype=np.float64)[masks[c]]
            res[c] = float(np.sqrt(np.mean(d * d))) if len(d) else float("nan")
        return res

    rmse_before = rmse(x_start)
    cost_start = robust_cost(residuals(x_start), loss, f_scale)
    if not names:
        info = {
            "names": [],
            "x0": [],
            "x": [],
            "stderr": {},
            "stderr_iid": {},
            "cost": 0.0,
            "nfev": 0,
            "status": 0,
            "message": "nothing to fit",
            "success": True,
        }
        return model, info
    sol = least_squares(
        residuals,
        x_start,
        bounds=(lo, hi),
        x_scale=xs,
        loss=loss,
        f_scale=f_scale,
        method="trf",
        jac="2-point",
        max_nfev=max_nfev or 60,
        # Residuals are in noise units, so the cost is half a chi-square: a relative change
        # below 0.5/m is a fraction of one chi-square unit, statistically nothing.
        xtol=1e-8,
        ftol=max(1e-10, min(1e-4, 0.5 / m)),
        gtol=1e-8,
    )
    fitted = model.with_params(dict(zip(names, map(float, sol.x), strict=True)))
    r_final = residuals(sol.x)
    rho = float(np.clip(_lag1(r_final), 0.0, 0.99))
    tau = _integrated_autocorr(r_final, [len(v) for v in targets.values()])
    se_iid = _standard_errors(sol.jac, float(sol.cost), m, len(names))
    se = se_iid * np.sqrt(tau)  # effective sample size m / tau
    s2 = 2.0 * float(sol.cost) / max(m - len(names), 1)  # residual level in noise units
    at_bound = [
        k
        for k, v, a, b in zip(names, sol.x, lo, hi, strict=True)
        if v <= a + 1e-6 * abs(a) + 1e-12 or v >= b - 1e-6 * abs(b) - 1e-12
    ]
    info = {
        "names": names,
        "x0": [float(v) for v in x0],
        "x": [float(v) for v in sol.x],
        "stderr": dict(zip(names, map(float, se), strict=True)),
        "stderr_iid": dict(zip(names, map(float, se_iid), strict=True)),
        "cost": float(sol.cost),
        "nfev": int(sol.nfev),
        "status": int(sol.status),
        "message": str(sol.message),
        "success": bool(sol.status > 0),
        "n_used": m,
        "n_rows": len(rows),
        "sigma": sigma,
        "rmse_before": rmse_before,
        "rmse_after": rmse(sol.x),
        "rho1": rho,
        "cost_start": cost_start,
        "tau_int": tau,
        # Improvement in effective chi-square units: scaled by the residual level reached
        # (the noise estimate may be low for coloured noise) and by the autocorrelation time.
        "delta_chi2_eff": 2.0 * (cost_start - float(sol.cost)) / max(s2, 1e-12) / tau,
        "at_bound": at_bound,
        "bounds": {k: [float(a), float(b)] for k, a, b in zip(names, lo, hi, strict=True)},
        "time_s": time.perf_counter() - t0,
    }
    return fitted, info
