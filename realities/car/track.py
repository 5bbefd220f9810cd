"""A closed race track (curvature against distance) and the driver's speed profile.

The track is a template of straights and corners (clothoid entry/exit, constant-radius middle):
a main straight, a slow hairpin, a fast sweeper, a chicane, a medium corner, a back straight, a
fast kink and a closing corner. Radii, angles and lengths are drawn per seed; the last corner
closes the heading and two straights are solved for so that the loop closes in position.
Mostly left-hand (counter-clockwise) unless mirrored.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import lsq_linear

DS = 1.0  # track grid [m]


def _curvature_of(segments, ds=DS):
    """Curvature samples of a segment list [(kind, length or (R, angle, Lcl))]."""
    ks = []
    for seg in segments:
        if seg[0] == "S":
            n = max(1, int(round(seg[1] / ds)))
            ks.append(np.zeros(n))
        else:
            _, R, ang, Lcl = seg
            k = math.copysign(1.0 / R, ang)
            # angle = k * (La + Lcl)  (two half-clothoids of length Lcl each turn k*Lcl/2)
            La = abs(ang) / abs(k) - Lcl
            if La < 0:
                Lcl = abs(ang) / abs(k) * 0.5
                La = abs(ang) / abs(k) - Lcl
            n1 = max(1, int(round(Lcl / ds)))
            n2 = max(1, int(round(La / ds)))
            ramp = (np.arange(n1) + 0.5) / n1
            kk = np.concatenate([ramp * k, np.full(n2, k), ramp[::-1] * k])
            # exact heading: rescale so that sum(kk)*ds == ang
            kk *= ang / (kk.sum() * ds)
            ks.append(kk)
    return ks


def _integrate(k, ds=DS):
    th = np.concatenate([[0.0], np.cumsum(k) * ds])[:-1] + 0.5 * k * ds
    # midpoint heading per cell
    x = np.concatenate([[0.0], np.cumsum(np.cos(th)) * ds])
    y = np.concatenate([[0.0], np.cumsum(np.sin(th)) * ds])
    return th, x, y


def build_track(rng: np.random.Generator, mirror: bool):
    """Return dict(x, y, th, k, length, segments, description). Deterministic for the rng."""
    d = math.radians
    for _attempt in range(400):
        segs = []
        segs.append(["S", rng.uniform(500, 800)])  # 0 main straight
        R1 = rng.uniform(22, 35)
        a1 = d(rng.uniform(155, 175))
        segs.append(["C", R1, a1, min(0.5 * R1, 15.0)])  # 1 hairpin (left)
        segs.append(["S", rng.uniform(120, 250)])  # 2
        R2 = rng.uniform(110, 180)
        a2 = d(rng.uniform(45, 70))
        segs.append(["C", R2, -a2, 30.0])  # 3 fast sweeper (right)
        segs.append(["S", rng.uniform(150, 350)])  # 4
        Rc = rng.uniform(28, 42)
        ac = d(rng.uniform(40, 60))
        segs.append(["C", Rc, -ac, 10.0])  # 5 chicane (right)
        segs.append(["S", rng.uniform(15, 30)])  # 6
        ac2 = ac + d(rng.uniform(0, 10))
        segs.append(["C", Rc * rng.uniform(0.9, 1.1), ac2, 10.0])  # 7 chicane (left)
        segs.append(["S", rng.uniform(80, 200)])  # 8
        R3 = rng.uniform(45, 80)
        a3 = d(rng.uniform(75, 100))
        segs.append(["C", R3, a3, 20.0])  # 9 medium (left)
        segs.append(["S", rng.uniform(300, 550)])  # 10 back straight
        R4 = rng.uniform(55, 110)
        a4 = d(rng.uniform(95, 125))
        segs.append(["C", R4, a4, 25.0])  # 11 long left
        segs.append(["S", rng.uniform(100, 300)])  # 12
        a5 = 2 * math.pi - (a1 - a2 - ac + ac2 + a3 + a4)
        if not d(30) <= a5 <= d(110):
            continue
        R5 = rng.uniform(50, 100)
        segs.append(["C", R5, a5, 20.0])  # 13 closing corner (left)
        segs.append(["S", rng.uniform(60, 160)])  # 14 onto main straight

        # closure: the end position is linear in the straights' lengths; solve for lengths
        # within their bounds, close to the drawn ones (bounded least squares)
        bounds = {
            0: (400, 900),
            2: (100, 300),
            4: (150, 500),
            6: (12, 35),
            8: (60, 300),
            10: (200, 700),
            12: (80, 400),
            14: (40, 250),
        }
        idx = sorted(bounds)
        heads = []
        ang = 0.0
        for q, sg in enumerate(segs):
            if sg[0] == "S":
                heads.append(ang)
            else:
                ang += sg[2]
        arcs = [sg for sg in segs]
        for q in idx:
            arcs[q] = ["S", 0.0]
        ks0 = _curvature_of([sg if sg[0] == "C" else ["S", 1e-9] for sg in arcs])
        k0 = np.concatenate([q for q in ks0 if np.any(q != 0)])
        _, x0, y0 = _integrate(k0)
        A = np.array([[math.cos(h) for h in heads], [math.sin(h) for h in heads]])
        Lnom = np.array([segs[q][1] for q in idx])
        W = 50.0
        M = np.vstack([A * W, np.eye(len(idx)) * (1.0 / Lnom)])
        rhs = np.concatenate([[-x0[-1] * W, -y0[-1] * W], np.ones(len(idx))])
        sol = lsq_linear(M, rhs, bounds=([bounds[q][0] for q in idx], [bounds[q][1] for q in idx]))
        if np.hypot(*(A @ sol.x + [x0[-1], y0[-1]])) > 2.0:
            continue
        for q, Lq in zip(idx, sol.x, strict=True):
            segs[q][1] = float(Lq)
        ks = _curvature_of(segs)
        k = np.concatenate(ks)
        th, x, y = _integrate(k)
        # residual closure (rounding of straights to the grid) spread linearly
        n = len(k)
        w = np.arange(n + 1) / n
        x = x - w * x[-1]
        y = y - w * y[-1]
        # self-intersection check: points > 150 m apart along track must be > 30 m apart
        sub = np.arange(0, n, 5)
        P = np.stack([x[sub], y[sub]], 1)
        D = np.sqrt(((P[:, None, :] - P[None, :, :]) ** 2).sum(-1))
        sidx = sub * DS
        sep = np.abs(sidx[:, None] - sidx[None, :])
        sep = np.minimum(sep, n * DS - sep)
        if np.any(D[sep > 150] < 30):
            continue
        break
    else:  # pragma: no cover
        raise RuntimeError("could not build a closed track")
    if mirror:
        k = -k
        th = -th
        y = -y
    # smooth curvature a little (a driven line, not a polygon of clothoids)
    kern = np.ones(9) / 9
    ks_ = np.convolve(np.concatenate([k[-4:], k, k[:4]]), kern, mode="valid")
    names = [
        "main straight",
        "hairpin",
        "straight",
        "fast sweeper",
        "straight",
        "chicane (a)",
        "link",
        "chicane (b)",
        "straight",
        "medium corner",
        "back straight",
        "long corner",
        "straight",
        "closing corner",
        "straight",
    ]
    desc = []
    for nm, sgm in zip(names, segs, strict=True):
        if sgm[0] == "S":
            desc.append(f"{nm} {sgm[1]:.0f} m")
        else:
            ang = math.degrees(sgm[2]) * (-1 if mirror else 1)
            desc.append(f"{nm} R{sgm[1]:.0f} m {ang:+.0f} deg")
    return {
        "x": x[:-1].copy(),
        "y": y[:-1].copy(),
        "th": th.copy(),
        "k": ks_.copy(),
        "length": n * DS,
        "description": "; ".join(desc),
        "direction": "clockwise" if mirror else "counter-clockwise",
    }


def speed_profile(track, laps, car, v0, n_extra_m=3000.0):
    """Speed reference over the distance driven (grid DS), lap after lap.

    laps: list of dict(pace, vtop). car: dict(mu_lat, mu_brk, mu_drv, g, P, m, cda, rho).
    Returns v_ref, a_ff (v dv/ds), pace, lap index arrays over s_total.
    """
    L = len(track["k"])
    n = L * len(laps) + int(n_extra_m / DS)
    kk = np.resize(track["k"], n)
    pace = np.empty(n)
    vtop = np.empty(n)
    lap = np.empty(n)
    for j, lp in enumerate(laps):
        pace[j * L : (j + 1) * L] = lp["pace"]
        vtop[j * L : (j + 1) * L] = lp["vtop"]
        lap[j * L : (j + 1) * L] = j
    pace[len(laps) * L :] = laps[-1]["pace"]
    vtop[len(laps) * L :] = laps[-1]["vtop"]
    lap[len(laps) * L :] = len(laps) - 1
    g = car["g"]
    alat = pace * car["mu_lat"] * g
    ak = np.abs(kk)
    vlat = np.sqrt(alat / np.maximum(ak, 1e-6))
    v = np.minimum(vlat, vtop)
    m = car["m"]
    # forward pass (acceleration, power and traction limited, friction ellipse)
    v[0] = min(v[0], v0)
    for i in range(n - 1):
        vi = v[i]
        lat = min(1.0, vi * vi * ak[i] / alat[i])
        ell = math.sqrt(max(0.0, 1.0 - lat * lat))
        drag = 0.5 * car["rho"] * car["cda"] * vi * vi + car["crr"] * m * g
        a_pow = car["P"] / (m * max(vi, 5.0)) - drag / m
        a = min(pace[i] * car["mu_drv"] * g * ell, a_pow)
        vn = math.sqrt(max(vi * vi + 2.0 * DS * max(a, -2.0), 1.0))
        if vn < v[i + 1]:
            v[i + 1] = vn
    # backward pass (braking)
    for i in range(n - 2, -1, -1):
        vn = v[i + 1]
        lat = min(1.0, vn * vn * ak[i + 1] / alat[i + 1])
        ell = math.sqrt(max(0.0, 1.0 - lat * lat))
        drag = 0.5 * car["rho"] * car["cda"] * vn * vn + car["crr"] * m * g
        a = pace[i] * car["mu_brk"] * g * ell + drag / m
        vb = math.sqrt(vn * vn + 2.0 * DS * a)
        if vb < v[i]:
            v[i] = vb
    # light smoothing (a human's anticipation) and the feed-forward acceleration
    kern = np.ones(7) / 7
    vs = np.convolve(np.concatenate([np.full(3, v[0]), v, np.full(3, v[-1])]), kern, "valid")
    vs = np.minimum(vs, v + 0.5)
    aff = np.empty(n)
    aff[:-1] = vs[:-1] * np.diff(vs) / DS
    aff[-1] = 0.0
    return vs, aff, pace, lap
