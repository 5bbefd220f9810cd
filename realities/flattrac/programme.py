"""A Flat-Trac test programme as a lab runs it, randomised per seed.

Every channel is piecewise linear in time (way points, then ``np.interp`` onto the 100 Hz
grid): slip angle, slip ratio, inclination, load set point, belt speed and the inflation
pressure set point. The programme is a sequence of blocks at one condition (load, pressure,
inclination, speed) holding lateral sweeps (0 -> +A -> -A -> 0 or the reverse order) at
different rates and drive/brake sweeps at a few slip angles, separated by short free-rolling
rests, cooling pauses (sometimes with the belt stopped) and repeated reference sweeps at the
same condition early, mid and late in the session.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

DEG = np.pi / 180.0
KMH = 1.0 / 3.6
CHANNELS = ("kappa", "alpha", "gamma", "load", "V", "p")

# phase codes per sample
REST, LAT, LONG, MOVE, PAUSE, REF_LAT, REF_LONG = range(7)
PHASE_NAMES = ("rest", "lateral sweep", "drive/brake sweep", "condition change", "cooling pause",
               "reference lateral sweep", "reference drive/brake sweep")  # fmt: skip


@dataclass
class Style:
    """Case-specific emphasis of the programme."""

    pressure_regulated: bool = True  # False: one cold set pressure, no pressure set points
    n_pressures: tuple[int, int] = (2, 3)
    camber_values: tuple[float, ...] = (0.0, 1.0, 2.0, 3.0, 4.0)  # deg to draw from
    n_cambers: tuple[int, int] = (2, 3)
    sidewall: bool = False  # visit low pressure x high load with sweeps beyond the peak
    p_low: float = 0.4  # sidewall corner pressure / p0
    fz_high: float = 1.45  # sidewall corner load / Fz0
    amp_range: tuple[float, float] = (6.0, 12.0)  # deg
    rate_range: tuple[float, float] = (1.0, 6.0)  # deg/s
    long_prob: float = 0.6  # chance of drive/brake sweeps in a block
    long_alpha: tuple[float, ...] = (0.0, 2.0, -2.0, 4.0, -4.0)  # deg
    pause_prob: float = 0.35
    stop_prob: float = 0.35  # chance a pause stops the belt
    speeds_kmh: tuple[float, ...] = (30.0, 40.0, 50.0, 60.0, 70.0)
    n_speeds: tuple[int, int] = (2, 3)
    intense: float = 1.0  # >1: fewer rests, more sweeps (more heat)
    first: str = ""  # "camber" / "pressure" / "speed": the first block shows it


@dataclass
class Programme:
    t: np.ndarray  # [s] from 0, 100 Hz
    kappa: np.ndarray
    alpha: np.ndarray  # [rad]
    gamma: np.ndarray  # [rad]
    load: np.ndarray  # set point [N]
    V: np.ndarray  # belt speed [m/s]
    p_set: np.ndarray  # gauge set pressure [Pa] (constant p0 when not regulated)
    phase: np.ndarray  # int8 phase codes
    events: list = field(default_factory=list)
    conditions: dict = field(default_factory=dict)

    def describe(self) -> str:
        c = self.conditions
        n_lat = sum(e["kind"] == "lateral" for e in self.events)
        n_long = sum(e["kind"] == "drive/brake" for e in self.events)
        n_ref = sum(e.get("reference", False) for e in self.events)
        n_pause = sum(e["kind"] == "pause" for e in self.events)
        n_stop = sum(e["kind"] == "pause" and e.get("belt_stopped") for e in self.events)
        return (
            f"Flat-Trac programme {self.t[-1] + 0.01:.0f} s: loads {c['loads_N']} N, "
            f"pressures {c['pressures_kPa']} kPa ({'regulated' if c['regulated'] else 'sealed/unregulated'}), "
            f"inclinations {c['inclinations_deg']} deg, belt speeds {c['speeds_kmh']} km/h; "
            f"{n_lat} lateral sweeps (+-{c['amp_deg'][0]:.0f}..{c['amp_deg'][1]:.0f} deg at "
            f"{c['rate_dps'][0]:.1f}..{c['rate_dps'][1]:.1f} deg/s, some reversed), {n_long} "
            f"drive/brake sweeps (kappa up to {c['kappa_max']:.2f}) at slip angles "
            f"{c['long_alpha_deg']} deg, {n_ref} reference sweeps (early/mid/late), {n_pause} "
            f"cooling pauses ({n_stop} with the belt stopped)."
        )  # fmt: skip


class _Builder:
    def __init__(self, start: dict):
        self.now = 0.0
        self.cur = dict(start)
        self.wp = {ch: [(0.0, start[ch])] for ch in CHANNELS}
        self.phases: list[tuple[float, float, int]] = []
        self.events: list[dict] = []

    def move(self, targets: dict, dur: float, phase: int = MOVE) -> None:
        dur = max(float(dur), 0.01)
        for ch, v in targets.items():
            if self.cur[ch] != v:
                self.wp[ch].append((self.now, self.cur[ch]))
                self.wp[ch].append((self.now + dur, float(v)))
                self.cur[ch] = float(v)
        self.phases.append((self.now, self.now + dur, phase))
        self.now += dur

    def hold(self, dur: float, phase: int = REST) -> None:
        self.move({}, dur, phase)


def _condition_change(b: _Builder, load=None, V=None, gamma=None, p=None) -> None:
    """Go to a new condition at zero slip, like a rig does between blocks."""
    if b.cur["kappa"] != 0.0 or b.cur["alpha"] != 0.0:
        b.move({"kappa": 0.0, "alpha": 0.0}, 1.0)
    if p is not None and abs(p - b.cur["p"]) > 1.0:
        b.move({"p": p}, max(2.0, abs(p - b.cur["p"]) / 15e3))  # ~15 kPa/s regulator
        b.hold(2.0, MOVE)
    if V is not None and abs(V - b.cur["V"]) > 1e-6:
        b.move({"V": V}, max(1.0, abs(V - b.cur["V"]) / 2.5))  # 2.5 m/s^2
    tg = {}
    if gamma is not None and abs(gamma - b.cur["gamma"]) > 1e-9:
        tg["gamma"] = gamma
    if load is not None and abs(load - b.cur["load"]) > 1e-6:
        tg["load"] = load
    if tg:
        dur = 1.5
        if "gamma" in tg:
            dur = max(dur, abs(tg["gamma"] - b.cur["gamma"]) / (2.0 * DEG))
        b.move(tg, dur)


def _lateral(b: _Builder, A: float, rate: float, reverse: bool, ref: bool, cond: dict) -> None:
    s = -1.0 if reverse else 1.0
    ph = REF_LAT if ref else LAT
    t0 = b.now
    b.move({"alpha": s * A * DEG}, A / rate, ph)
    b.move({"alpha": -s * A * DEG}, 2 * A / rate, ph)
    b.move({"alpha": 0.0}, A / rate, ph)
    b.events.append({"kind": "lateral", "t0": round(t0, 2), "t1": round(b.now, 2),
                     "amp_deg": round(A, 2), "rate_dps": round(rate, 2), "reversed": reverse,
                     "reference": ref, **cond})  # fmt: skip


def _drive_brake(b: _Builder, a0: float, K: float, rate: float, reverse: bool, ref: bool,
                 cond: dict) -> None:  # fmt: skip
    ph = REF_LONG if ref else LONG
    if a0 != 0.0:
        b.move({"alpha": a0 * DEG}, max(0.5, abs(a0) / 3.0), MOVE)
    t0 = b.now
    s = -1.0 if reverse else 1.0
    b.move({"kappa": s * K}, K / rate, ph)
    b.move({"kappa": -s * K}, 2 * K / rate, ph)
    b.move({"kappa": 0.0}, K / rate, ph)
    t1 = b.now
    if a0 != 0.0:
        b.move({"alpha": 0.0}, max(0.5, abs(a0) / 3.0), MOVE)
    b.events.append({"kind": "drive/brake", "t0": round(t0, 2), "t1": round(t1, 2),
                     "alpha_deg": a0, "kappa_max": round(K, 3), "rate_per_s": round(rate, 3),
                     "reversed": reverse, "reference": ref, **cond})  # fmt: skip


def _pause(b: _Builder, rng, dur: float, stop: bool) -> None:
    t0 = b.now
    V = b.cur["V"]
    if stop:
        b.move({"V": 0.0}, max(1.0, V / 2.5), PAUSE)
        b.hold(dur, PAUSE)
        b.move({"V": V}, max(1.0, V / 2.5), PAUSE)
    else:
        b.hold(dur, PAUSE)
    b.events.append({"kind": "pause", "t0": round(t0, 2), "t1": round(b.now, 2),
                     "belt_stopped": bool(stop)})  # fmt: skip


def build(rng: np.random.Generator, Fz0: float, p0: float, duration: float, style: Style,
          fs: float = 100.0) -> Programme:  # fmt: skip
    """Draw a programme of ``duration`` seconds (the grid has round(duration*fs) samples)."""
    # ---- the condition sets
    load_pool = np.array([0.5, 0.75, 1.25, 1.5])
    n_l = int(rng.integers(2, 5))  # 2-4 loads, nominal always among them
    loads = sorted({1.0, *rng.choice(load_pool, size=n_l - 1, replace=False).tolist()})
    if style.pressure_regulated:
        n_p = int(rng.integers(style.n_pressures[0], style.n_pressures[1] + 1))
        pool = np.array([0.8, 0.9, 1.1, 1.2])
        pressures = sorted({1.0, *rng.choice(pool, size=n_p - 1, replace=False).tolist()})
    else:
        pressures = [1.0]
    n_g = int(rng.integers(style.n_cambers[0], style.n_cambers[1] + 1))
    others = [g for g in style.camber_values if g != 0.0]
    cambers = sorted({0.0, *rng.choice(others, size=min(n_g - 1, len(others)),
                                        replace=False).tolist()})  # fmt: skip
    n_v = int(rng.integers(style.n_speeds[0], style.n_speeds[1] + 1))
    speeds = sorted(rng.choice(style.speeds_kmh, size=n_v, replace=False).tolist())
    v_ref = speeds[len(speeds) // 2]
    A_ref = float(rng.uniform(7.0, 10.0))
    r_ref = float(rng.uniform(2.5, 4.0))
    K_ref = float(rng.uniform(0.1, 0.15))
    rk_ref = float(rng.uniform(0.04, 0.07))
    ref_long = bool(rng.random() < 0.6)
    kappa_max = float(rng.uniform(0.1, 0.2))

    ref_cond = {"load": Fz0, "p": p0, "gamma": 0.0, "V": v_ref * KMH}
    b = _Builder({"kappa": 0.0, "alpha": 0.0, "gamma": 0.0, "load": Fz0, "V": v_ref * KMH,
                  "p": p0})  # fmt: skip

    def cond_tag():
        return {
            "Fz": round(b.cur["load"], 1),
            "p_kPa": round(b.cur["p"] / 1e3, 1),
            "gamma_deg": round(b.cur["gamma"] / DEG, 2),
            "V_kmh": round(b.cur["V"] / KMH, 1),
        }

    def reference():
        _condition_change(b, **ref_cond)
        b.hold(float(rng.uniform(2.0, 4.0)))
        _lateral(b, A_ref, r_ref, False, True, cond_tag())
        if ref_long:
            b.hold(1.5)
            _drive_brake(b, 0.0, K_ref, rk_ref, False, True, cond_tag())
        b.hold(float(rng.uniform(1.5, 3.0)))

    ref_dur = 4 * A_ref / r_ref + (4 * K_ref / rk_ref + 1.5 if ref_long else 0.0) + 8.0

    # ---- the block conditions
    corner_blocks: list[dict] = []
    if style.sidewall:
        pl, fh = style.p_low * p0, style.fz_high * Fz0
        corner_blocks = [
            {"load": fh, "p": pl, "side": True},
            {"load": fh, "p": p0, "side": True},
            {"load": Fz0, "p": pl, "side": True},
            {"load": fh, "p": pl, "side": True},
        ]

    count = [0]

    def draw_block():
        count[0] += 1
        if corner_blocks and count[0] % 2 == 1:
            c = corner_blocks.pop(0)
            return {"load": c["load"], "p": c["p"], "gamma": 0.0,
                    "V": speeds[int(rng.integers(len(speeds)))] * KMH, "side": True}  # fmt: skip
        c = {"load": float(rng.choice(loads)) * Fz0,
             "p": float(rng.choice(pressures)) * p0,
             "gamma": float(rng.choice(cambers)) * DEG,
             "V": float(rng.choice(speeds)) * KMH, "side": False}  # fmt: skip
        if count[0] == 1:  # the case's condition of interest comes first (short sessions)
            if style.first == "camber":
                c["gamma"] = max(cambers) * DEG
            elif style.first == "pressure":
                c["p"] = min(pressures) * p0
            elif style.first == "speed":
                c["V"] = max(speeds, key=lambda v: abs(v - v_ref)) * KMH
        return c

    def block(c, deadline):
        """One condition block; sweeps and pauses that would run past ``deadline`` are left out
        (their random draws are made all the same, so the stream does not depend on it)."""
        _condition_change(b, load=c["load"], V=c["V"], gamma=c["gamma"], p=c["p"])
        b.hold(float(rng.uniform(1.0, 3.0)) / style.intense)
        n_lat = int(rng.integers(1, 4))
        for _ in range(n_lat):
            if c["side"]:
                A = float(rng.uniform(13.0, 16.0))
                rate = float(rng.uniform(2.0, 5.0))
            else:
                A = float(rng.uniform(*style.amp_range))
                rate = float(rng.uniform(*style.rate_range))
            rev = bool(rng.random() < 0.4)
            rest = float(rng.uniform(1.0, 3.0)) / style.intense
            if b.now + 4 * A / rate + rest <= deadline:
                _lateral(b, A, rate, rev, False, cond_tag())
                b.hold(rest)
        if rng.random() < style.long_prob:
            n_long = int(rng.integers(1, 3))
            for a0 in rng.choice(style.long_alpha, size=n_long, replace=False):
                K = float(rng.uniform(0.1, kappa_max)) if kappa_max > 0.1 else kappa_max
                rk = float(rng.uniform(0.03, 0.1))
                rev = bool(rng.random() < 0.4)
                rest = float(rng.uniform(1.0, 2.5)) / style.intense
                if b.now + 4 * K / rk + 2.0 + rest <= deadline:
                    _drive_brake(b, float(a0), K, rk, rev, False, cond_tag())
                    b.hold(rest)
        if rng.random() < style.pause_prob / style.intense:
            dur = float(rng.uniform(10.0, 60.0))
            stop = bool(rng.random() < style.stop_prob)
            dur = min(dur, deadline - b.now - (2 * b.cur["V"] / 2.5 + 2.0 if stop else 0.0))
            if dur >= 10.0:
                _pause(b, rng, dur, stop)

    b.hold(float(rng.uniform(2.0, 4.0)))
    reference()
    if duration < 240.0:  # a short session: one reference sweep, then blocks to the end
        while b.now + 20.0 < duration:
            t_before = b.now
            block(draw_block(), duration - 1.0)
            if b.now - t_before < 12.0:
                break
    mid_done = duration < 240.0
    while duration >= 240.0:
        if not mid_done and b.now >= 0.45 * duration:
            reference()
            mid_done = True
            continue
        if b.now + ref_dur + 25.0 > duration:
            break
        deadline = duration - ref_dur - 15.0  # room for the change to the reference condition
        if not mid_done:
            deadline = min(deadline, 0.45 * duration + 40.0)
        block(draw_block(), deadline)
    if duration >= 240.0 and b.now + ref_dur <= duration + 5.0:
        reference()
    # fill the rest with free rolling at zero slip
    if b.now < duration:
        b.move({"kappa": 0.0, "alpha": 0.0}, 0.5)
        b.hold(max(duration - b.now, 0.0) + 1.0)

    n = int(round(duration * fs))
    t = np.arange(n) / fs
    arr = {}
    for ch in CHANNELS:
        wt, wv = zip(*b.wp[ch], strict=True)
        wt = np.asarray(wt)
        # equal times (a step): keep order; np.interp needs non-decreasing xp
        arr[ch] = np.interp(t, wt, np.asarray(wv))
    phase = np.zeros(n, np.int8)
    for t0, t1, ph in b.phases:
        i0, i1 = int(np.ceil(t0 * fs - 1e-9)), int(np.ceil(t1 * fs - 1e-9))
        phase[max(i0, 0) : min(i1, n)] = ph
    events = [e for e in b.events if e["t0"] < duration]
    conds = {
        "loads_N": [round(x * Fz0, 1) for x in loads],
        "pressures_kPa": [round(x * p0 / 1e3, 1) for x in pressures],
        "regulated": style.pressure_regulated,
        "inclinations_deg": cambers,
        "speeds_kmh": speeds,
        "reference": {
            "Fz": Fz0,
            "p_kPa": p0 / 1e3,
            "gamma_deg": 0.0,
            "V_kmh": v_ref,
            "amp_deg": round(A_ref, 2),
            "rate_dps": round(r_ref, 2),
            "drive_brake": ref_long,
        },  # fmt: skip
        "amp_deg": (13.0, 16.0) if style.sidewall else style.amp_range,
        "rate_dps": style.rate_range,
        "kappa_max": kappa_max,
        "long_alpha_deg": list(style.long_alpha),
    }
    if style.sidewall:
        conds["sidewall_corner"] = {"p_kPa": round(style.p_low * p0 / 1e3, 1),
                                    "Fz": round(style.fz_high * Fz0, 1)}  # fmt: skip
    return Programme(t, arr["kappa"], arr["alpha"], arr["gamma"], arr["load"], arr["V"],
                     arr["p"], phase, events, conds)  # fmt: skip
