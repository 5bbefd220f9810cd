"""``make demo``: the story end to end on the embedded default tyre.

1. Record a Flat-Trac session on the virtual rig while the tyre heats up, with NO temperature
   topic in the recording (the heating is concealed).
2. Diagnose it against the default .tir: name what the model misses, fit it, and measure the
   held-out RMSE before and after.
3. Write the improved .tir, its effects file (the hidden states a .tir cannot hold), the
   diagnosis JSON and the report (Markdown + plots).
4. Run the ROS 2 node (``tire-model-node``) with the improved .tir and its effects file, replay
   the session as recorded, still without temperature (``tire-model play``, decimated), and
   record the node's forces (``tire-model record``); compare them with the same improved model
   run offline on the same messages, and with the measured forces. Every slip message played
   is accounted for: recorded as a force, or counted by play, the node or the recorder; an
   unexplained loss fails the step.
5. Compare the diagnosis with the rig's truth.
6. Beyond the rig (the seed paper's extension): the same tyre on a rig's safe envelope (heating,
   no temperature channel) and in a simulation at the special conditions (isothermal at set
   temperatures, 60 kPa, up to 160 % load, -10 and 80 degC), fused with ``tire-model fit RIG
   --extend SIM``; its report holds the operating envelope and the seed's three figures.

Everything goes into ``./out/demo/run-<UTC time>/`` (or ``--out DIR``, which must not exist or
be empty). ROS traffic stays on this machine (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) in a
random ROS_DOMAIN_ID. Exit status 0 only when every step worked and the node matched.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tire_model_ros.delivery import PLAY
from tire_model_ros.vocabulary import NS_PER_S
from tire_model_ros.wheel.hold import HOLD_COUNTS
from tire_model_ros.wheel.params import REPLAY_ALIGN_WAIT

if TYPE_CHECKING:
    from tire_model_ros.diagnosis import Diagnosis
    from tire_model_ros.model import TireModel
    from tire_model_ros.model.states import Effects, WheelEffects
    from tire_model_ros.recording import WheelSeries

Wheels = dict[str, "WheelSeries"]

PROGRAMME = "flat_trac"
SEED = 7
# The node must reproduce the improved model: its forces are computed by the same code from the
# same .tir, so anything beyond float round-off of the inputs in transit is a failure.
MATCH_TOL_N = 1.0
# The whole session is replayed through the node (its hidden states build up over it), every
# REPLAY_EVERY-th slip sample (20 Hz of the rig's 100 Hz), at REPLAY_RATE times real time.
REPLAY_EVERY = 5
REPLAY_RATE = 20.0
# The extension step's sessions at 20 Hz: the fused fit's sweeps are slow and smooth.
EXTEND_RATE_HZ = 20.0
EXTEND_FIGURES = ("envelope.png", "seed_pressure.png", "seed_load.png", "seed_temperature.png")


_STEP = {"now": "set-up"}


def say(step: str, text: str = "") -> None:
    """Print one line of the story (a line without text starts a step)."""
    if not text:
        _STEP["now"] = step
    print(f"[{step}] {text}" if text else f"\n== {step} ==", flush=True)


def tool(name: str) -> list[str]:
    """A console script of this environment (``tire-model``, ``tire-model-node``)."""
    exe = Path(sys.executable).with_name(name)
    if exe.is_file():
        return [str(exe)]
    modules = {"tire-model": "tire_model_ros.cli", "tire-model-node": "tire_model_ros.ros.node"}
    return [sys.executable, "-m", modules[name]]


def _short(text: str, limit: int = 160) -> str:
    """The first clauses of a long diagnosis text (the report has all of it)."""
    text = " ".join(str(text).split())
    if len(text) <= limit:
        return text
    cut = text.rfind(";", 0, limit)
    return text[: cut if cut > 40 else limit].rstrip() + " ..."


def default_tir() -> Path:
    from tire_model_ros.wheel.params import default_tir_path

    path = default_tir_path()
    if not path:
        raise OSError("config/default.tir not found in the source tree or the installed share dir")
    return Path(path)


def out_dir(arg: Path | None) -> Path:
    if arg is None:
        arg = Path("out") / "demo" / time.strftime("run-%Y%m%d-%H%M%S", time.gmtime())
    arg = arg.absolute()
    if arg.exists() and any(arg.iterdir()):
        raise FileExistsError(f"{arg}: exists and is not empty; give another --out")
    arg.mkdir(parents=True, exist_ok=True)
    return arg


def run(cmd: list[str], step: str, timeout: float, env: dict[str, str] | None = None) -> str:
    """Run a command, echo it, fail with its stderr."""
    say(step, "$ " + " ".join(cmd))
    proc = subprocess.run(
        cmd, capture_output=True, text=True, timeout=timeout, env=env, check=False
    )
    if proc.returncode != 0:
        raise RuntimeError(f"{step}: command failed ({proc.returncode}):\n{proc.stderr.strip()}")
    return proc.stdout


# --------------------------------------------------------------------------- steps


def step_record(tir: Path, out: Path) -> Path:
    say("1 record the session on the rig")
    bag = out / "session"
    run(
        [
            *tool("tire-model"),
            "simulate",
            "--tir",
            str(tir),
            "--programme",
            PROGRAMME,
            "-o",
            str(bag),
            "--effect",
            "heating",
            "--omit",
            "temperature",
            "--seed",
            str(SEED),
        ],
        "1",
        600,
    )
    truth = Path(f"{bag}.truth.json")
    hidden = out / "truth" / truth.name
    if truth.is_file():  # keep the truth out of the diagnosis' sight, for the end of the story
        hidden.parent.mkdir(exist_ok=True)
        os.replace(truth, hidden)
    from tire_model_ros.recording import read_recording

    wheels = read_recording(bag)
    for prefix, w in wheels.items():
        topics = [
            n
            for n, c in (("pressure", w.p), ("temperature", w.T), ("velocity", w.Vx))
            if c is not None
        ]
        say(
            "1",
            f"{bag.name}: wheel {prefix}, {len(w)} samples over {w.t[-1] - w.t[0]:.0f} s; "
            f"optional topics recorded: {', '.join(topics) or 'none'} (no temperature)",
        )
    return bag


def step_diagnose(bag: Path, tir: Path, out: Path) -> tuple[Wheels, Diagnosis, Path]:
    say("2 diagnose the session against the default .tir")
    from tire_model_ros.diagnosis import diagnose
    from tire_model_ros.model import TireModel, write_tir
    from tire_model_ros.recording import read_recording

    wheels = read_recording(bag)
    say(
        "2",
        f"diagnose(read_recording({bag.name}), TireModel.from_file({tir.name})) "
        f"(what `tire-model diagnose {bag.name} --tir {tir.name}` runs)",
    )
    t0 = time.monotonic()
    diag = diagnose(list(wheels.values()), TireModel.from_file(tir))
    say("2", f"done in {time.monotonic() - t0:.0f} s")
    from tire_model_ros.diagnosis.report import fmt_param, look_alike_summary

    for i, e in enumerate(diag.effects, 1):
        params = ", ".join(
            fmt_param(k, float(v), e.uncertainty.get(k)) for k, v in list(e.parameters.items())[:4]
        )
        more = len(e.parameters) - 4
        say(
            "2",
            f"finding {i}: {e.name}{' (concealed)' if e.concealed else ''} in {e.channel}"
            + (f"; fitted {params}" if params else "")
            + (f" (+{more} more in the report)" if more > 0 else ""),
        )
        say("2", f"   where: {_short(e.where)}")
        say("2", f"   evidence: {_short(e.evidence)}")
    if diag.look_alikes:
        say("2", look_alike_summary(diag.look_alikes))
    fit = diag.fit
    for c, unit, digits in (("Fx", "N", 0), ("Fy", "N", 0), ("Mz", "N m", 1)):
        b = fit.get("heldout_baseline", {}).get(c, {}).get("rmse")
        a = fit.get("heldout_improved", {}).get(c, {}).get("rmse")
        if b is not None and a is not None:
            say(
                "2",
                f"held-out {c} RMSE {b:.{digits}f} {unit} -> {a:.{digits}f} {unit} "
                f"({100 * (1 - a / b):.0f} % less)",
            )
    from tire_model_ros.cli.diagnose_cmd import effects_path, improved_tir

    improved = out / "improved.tir"
    write_tir(
        improved_tir(next(iter(diag.wheels.values())), TireModel.from_file(tir).tir), improved
    )
    effects = diag.node_effects(improved.name)
    effects_path(improved).write_text(effects.to_json())
    (out / "diagnosis.json").write_text(json.dumps(diag.to_json(), indent=2) + "\n")
    say(
        "2",
        f"wrote {improved}, {effects_path(improved).name} (hidden states for the node: "
        f"{', '.join(_carried(effects)) or 'none'}) and {out / 'diagnosis.json'}",
    )
    return wheels, diag, improved


def _carried(effects: Effects) -> list[str]:
    wheel = next(iter(effects.wheels.values()))
    return [k for k, v in wheel.to_dict().items() if k != "T_amb_C" and v]


def step_report(diag: Diagnosis, wheels: Wheels, out: Path) -> None:
    say("3 write the report")
    from tire_model_ros.diagnosis.report import write_report

    path = write_report(diag, wheels, out / "report", source="session")
    pngs = sorted(p.name for p in path.parent.glob("*.png"))
    say("3", f"{path} with {len(pngs)} plots: {', '.join(pngs)}")


def replay_bag(wheels: Wheels, out: Path) -> tuple[Path, Wheels]:
    """The session as recorded (no temperature), every REPLAY_EVERY-th sample."""
    from tire_model_ros.recording import write_recording

    parts = {}
    for prefix, w in wheels.items():
        keep = np.arange(0, len(w), REPLAY_EVERY)
        part = w.select(keep)
        part.meta = {"demo_keep": keep}  # where each replayed sample sits in the session
        parts[prefix] = part
    bag = out / "replay"
    write_recording(bag, [replace(w, meta={}) for w in parts.values()])  # stamps from t
    return bag, parts


def ros_env() -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(random.randint(1, 101))
    env.pop("ROS_STATIC_PEERS", None)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def _stop(proc: subprocess.Popen[bytes], timeout: float = 20.0) -> None:
    """SIGINT (clean shutdown, a recorder closes its bag), then SIGKILL if it hangs (after
    the teardown deadline, so a Fast DDS hang leaves its stacks in the log)."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def step_node(wheels: Wheels, diag: Diagnosis, tir: Path, improved: Path, out: Path) -> bool:
    say("4 run the node with the improved .tir and its effects file on the recording")
    from tire_model_ros.cli.diagnose_cmd import effects_path

    bag, parts = replay_bag(wheels, out)
    n_msgs = sum(len(w) for w in parts.values())
    span = max(float(w.t[-1] - w.t[0]) for w in parts.values())
    say(
        "4",
        f"replay bag {bag.name}: the whole session ({span:.0f} s), every "
        f"{REPLAY_EVERY}th slip sample, no temperature topic (as recorded)",
    )
    env = ros_env()
    say("4", f"ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']}, ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST")
    prefixes = list(parts)
    logs = out / "logs"
    logs.mkdir(exist_ok=True)
    node_cmd = [
        *tool("tire-model-node"),
        "--ros-args",
        "-p",
        f"tir_file:={improved}",
        "-p",
        f"effects_file:={effects_path(improved)}",
        "-p",
        f"wheels:={json.dumps(prefixes)}",
        "-p",
        f"align.wait:={REPLAY_ALIGN_WAIT}",  # a replay: exact alignment over latency
    ]
    forces_bag = out / "node_forces"
    rec_cmd = [
        *tool("tire-model"),
        "record",
        "-o",
        str(forces_bag),
        "--wheels",
        *prefixes,
        "--count",
        str(n_msgs),
        "--duration",
        str(_replay_bound_s(span)),  # a bound, not the plan: it stops at --count
    ]
    play_cmd = [*tool("tire-model"), "play", str(bag), "--rate", str(REPLAY_RATE), "--wait", "10"]
    procs: list[subprocess.Popen[bytes]] = []
    handles = []
    try:
        for name, cmd in (("node", node_cmd), ("record", rec_cmd)):
            say("4", f"start {name}: $ {' '.join(cmd)}  (log: {logs / f'{name}.log'})")
            handles.append(open(logs / f"{name}.log", "w"))  # noqa: SIM115 (closed below)
            procs.append(
                subprocess.Popen(cmd, stdout=handles[-1], stderr=subprocess.STDOUT, env=env)
            )
        # play starts once the recorder listens to every wheel's forces: none is published
        # before it can be recorded (the node logs each match)
        matched = [f"{prefix}/forces: 1 subscriber(s) matched" for prefix in prefixes]
        _wait_logs(procs, logs, {"node": matched, "record": ["recording"]}, timeout_s=180.0)
        out_play = run(play_cmd, "4", _replay_bound_s(span), env)
        for line in out_play.strip().splitlines():
            if not line.startswith(PLAY):
                say("4", line)
        try:  # the recorder stops by itself after one force message per slip message
            procs[1].wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            say("4", "the recorder has not seen every force message after 10 s; stopping it")
    finally:
        for p in reversed(procs):
            _stop(p)
        for h in handles:
            h.close()
    if not forces_bag.exists():
        raise RuntimeError(f"the recorder wrote no bag at {forces_bag}; see {logs}/record.log")
    accounted = account_for_loss(prefixes, out_play, logs)
    return compare(forces_bag, parts, improved, tir, diag) and accounted


def _replay_bound_s(span_s: float) -> float:
    """A generous bound on the replay of ``span_s`` of recording [s]: play waits for every
    subscriber's acknowledgement, which a loaded machine slows down many times (a replay
    planned for 30 s took over 3 min beside two diagnoses)."""
    return span_s / REPLAY_RATE * 10.0 + 300.0


def _wait_logs(
    procs: list[subprocess.Popen[bytes]],
    logs: Path,
    lines: dict[str, list[str]],
    timeout_s: float,
) -> None:
    """Wait until each process's log holds its lines (discovery done); fail if one exits."""
    end = time.monotonic() + timeout_s
    while True:
        missing = [
            f"{name}: {text!r}"
            for name, texts in lines.items()
            for text in texts
            if text not in (logs / f"{name}.log").read_text()
        ]
        if not missing:
            return
        for p, name in zip(procs, lines, strict=True):
            if p.poll() is not None:
                raise RuntimeError(f"{name} exited early ({p.returncode}); see {logs}/{name}.log")
        if time.monotonic() > end:
            raise RuntimeError(f"not ready after {timeout_s:.0f} s: {'; '.join(missing)}")
        time.sleep(0.1)


def account_for_loss(prefixes: list[str], out_play: str, logs: Path) -> bool:
    """Every slip message played is a recorded force or counted by a stage (play's
    acknowledgements, the node's final counts, the recorder's gaps); False on any other loss."""
    from tire_model_ros.delivery import NODE, RECORD, account, parse_reports

    plays = parse_reports(out_play, PLAY)
    nodes = parse_reports((logs / "node.log").read_text(), NODE)
    records = parse_reports((logs / "record.log").read_text(), RECORD)
    ok = True
    for prefix in prefixes:
        try:
            acc = account(prefix, plays, nodes, records)
        except KeyError as exc:
            say("4", f"FAILED: {prefix}: cannot account for its messages: {exc}")
            ok = False
            continue
        say("4", f"{prefix}: {acc.text()}")
        say("4", f"{prefix}: {held_text(nodes[prefix])}")
        if acc.unexplained:
            say(
                "4",
                f"FAILED: {prefix}: {acc.unexplained} messages lost with no stage counting them",
            )
            ok = False
    return ok


def held_text(counts: dict[str, int]) -> str:
    """What the node's hold did (``align.wait``): slips that came before their inputs."""
    c = {k: counts.get(k, 0) for k in HOLD_COUNTS}
    return (
        f"the node held {c['held']} slips until their inputs caught up: "
        f"{c['released_caught_up']} answered once they had, {c['released_by_wait']} after "
        f"waiting the bound, {c['released_by_overflow']} by overflow, "
        f"{c['released_by_flush']} at shutdown (the longest wait that ended with the inputs: "
        f"{counts.get('longest_catch_up_ms', 0)} ms); load missing for "
        f"{sum(v for k, v in counts.items() if k.startswith('fallback.load.'))} slips"
    )


def offline(model: TireModel, effects: WheelEffects | None, w: WheelSeries) -> np.ndarray:
    """The node's computation for every sample of ``w``, offline: the node's own per-wheel
    code (``WheelState.compute``, default settings) fed the replayed messages in stamp order,
    so the improved model with the effects' hidden states stepped on the same stamps, an input
    outside the file's range saturated and leaving no trace in the hidden states, as in the
    node (rows Fx, Fy, Fz, Mx, My, Mz). Only the transport can make the node differ."""
    from tire_model_ros.model.states import EffectState
    from tire_model_ros.wheel.params import DEFAULT_TIMEOUTS
    from tire_model_ros.wheel.state import Settings, WheelModel, WheelState

    ws = WheelState("offline", "offline")
    ws.effects = EffectState(effects) if effects is not None else None
    wm, settings = WheelModel.of(model), Settings.of(DEFAULT_TIMEOUTS, True, False)
    t_ns = np.round(w.t * NS_PER_S).astype(np.int64)
    inputs = {"load": w.Fz, "pressure": w.p, "temperature": w.T, "velocity": w.Vx}
    rows = np.full((len(w), 6), np.nan)
    for i, t in enumerate(t_ns.tolist()):
        for name, values in inputs.items():  # each input as the node takes its messages
            if values is not None:
                ws.set_input(name, t, float(values[i]))
        out, _ = ws.compute(float(w.kappa[i]), float(w.alpha[i]), float(w.gamma[i]), t, wm,
                            settings)  # fmt: skip
        if out is not None:
            rows[i] = out
    return rows


def _node_forces(forces_bag: Path, prefix: str, w: WheelSeries) -> tuple[np.ndarray, np.ndarray]:
    """(sample index into ``w``, node wrench rows) for every force message matched by stamp."""
    from tire_model_ros.recording import decode_topic, read_raw

    raw = read_raw(forces_bag)
    topic = f"{prefix}/forces"
    if topic not in raw.topics:
        raise RuntimeError(f"no {topic} in {forces_bag.name}: the node published nothing")
    ch = decode_topic(raw, topic)
    t_ns = np.round(w.t * 1e9).astype(np.int64)
    idx = np.clip(np.searchsorted(t_ns, ch.stamp_ns), 0, len(t_ns) - 1)
    hit = np.abs(t_ns[idx] - ch.stamp_ns) < 1000  # the slip message's own stamp (to 1 us)
    idx, rows = idx[hit], ch.values[hit]
    idx, first = np.unique(idx, return_index=True)  # one answer per slip message
    return idx, rows[first]


def _rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def compare(forces_bag: Path, parts: Wheels, improved: Path, tir: Path, diag: Diagnosis) -> bool:
    """Node forces against the improved model run offline, and against the measurement."""
    from tire_model_ros.cli.diagnose_cmd import effects_path
    from tire_model_ros.model import TireModel
    from tire_model_ros.model.states import Effects

    model = TireModel.from_file(improved)
    effects = Effects.read(effects_path(improved))
    default = TireModel.from_file(tir)
    ok = True
    worst, answered = 0.0, 0
    for prefix, w in parts.items():
        idx, node = _node_forces(forces_bag, prefix, w)
        say("4", f"{prefix}: the node answered {len(idx)} of {len(w)} slip messages")
        if len(idx) < 0.95 * len(w):
            say("4", "FAILED: fewer than 95 % of the slip messages got an answer")
            ok = False
        if len(idx) == 0:
            return False
        sub = w.select(idx)
        ref = offline(model, effects.for_wheel(prefix), w)[idx]
        old = default.evaluate(sub.Fz, sub.kappa, sub.alpha, sub.gamma, sub.Vx, sub.p, None)
        preds = diag.predictions.get(prefix, {})
        keep = w.meta["demo_keep"][idx]  # the replayed samples' place in the session
        for k, c in enumerate(("Fx", "Fy")):
            dev = float(np.max(np.abs(node[:, k] - ref[:, k])))
            meas = getattr(sub, c)
            say(
                "4",
                f"{c}: node vs the improved model run offline: max |difference| "
                f"{dev:.2g} N over {len(idx)} messages",
            )
            full = preds.get(f"improved_{c}")
            full_txt = (
                ""
                if full is None
                else f"; the diagnosis' improved model (hidden "
                f"states driven by the measured forces) {_rmse(full[keep], meas):.0f} N"
            )
            say(
                "4",
                f"{c}: RMSE against the measured {c} on the replay: node (improved .tir "
                f"+ effects file) {_rmse(node[:, k], meas):.0f} N, default .tir "
                f"{_rmse(getattr(old, c), meas):.0f} N{full_txt}",
            )
            worst, answered = max(worst, dev), max(answered, len(idx))
            if not dev <= MATCH_TOL_N:
                say(
                    "4",
                    f"FAILED: the node's {c} differs from the improved model by more "
                    f"than {MATCH_TOL_N} N",
                )
                ok = False
    if effects.not_carried:
        say("4", f"note: not carried by the effects file: {'; '.join(effects.not_carried)}")
    if ok:
        say(
            "4",
            f"=> the node's forces match the improved model: largest difference "
            f"{worst:.1g} N over {answered} force messages (tolerance {MATCH_TOL_N} N)",
        )
    return ok


def step_truth(out: Path, wheels: Wheels, diag: Diagnosis) -> None:
    say("5 compare with the rig's truth (hidden from the diagnosis until now)")
    files = sorted((out / "truth").glob("*.truth.json"))
    if not files:
        say("5", "no truth file: skipped")
        return
    truth = json.loads(files[0].read_text())
    named = [e.name for e in diag.effects]
    say(
        "5",
        f"the rig ran: {', '.join(truth.get('effects', {}))}; omitted channels: "
        f"{', '.join(truth.get('omitted', [])) or 'none'}; the words it expects: "
        f"{', '.join(truth.get('diagnosis_words', [])) or 'none'}; named: {', '.join(named)}",
    )
    for prefix, w in wheels.items():
        trace = truth.get("wheels", {}).get(prefix, {}).get("hidden_trace") or {}
        T_inf = (diag.inferred.get(prefix) or {}).get("T")
        if T_inf is None or "T_surface" not in trace:
            continue
        t_rel = np.asarray(trace["t_s"], dtype=float)
        T_at = np.interp(t_rel, w.t - w.t[0], np.asarray(T_inf, dtype=float))
        r = float(np.corrcoef(T_at, np.asarray(trace["T_surface"], dtype=float))[0, 1])
        say(
            "5",
            f"{prefix}: inferred tread temperature vs the rig's hidden tread surface: "
            f"correlation r = {r:.2f} (the rig's three-node model with a grip window is "
            "not the diagnosis' tread node on the TTX/TTY terms; its scale is a convention)",
        )


def _write_without_pressure_and_temperature(tir: Path, start: Path) -> None:
    """The file as a fit that knows nothing of pressure and temperature starts from (PP*, TT*
    zero): what the fused fit finds of them comes from the rig and the simulation."""
    from tire_model_ros.model import TireModel, write_tir

    zero = [f"{k}{a}{i}" for k in ("PP", "TT") for a in "XY" for i in range(1, 5)]
    write_tir(TireModel.from_file(tir).with_params(dict.fromkeys(zero, 0.0)).tir, start)


def step_extend(tir: Path, out: Path) -> None:
    say("6 beyond the rig: extend the model with a simulation (the seed paper)")
    sessions = {"rig": "safe_envelope", "simulation": "special_conditions"}
    for i, (name, programme) in enumerate(sessions.items()):
        run(
            [*tool("tire-model"), "simulate", "--tir", str(tir), "--programme", programme,
             "-o", str(out / name), "--seed", str(SEED + 1 + i), "--rate", str(EXTEND_RATE_HZ)],
            "6",
            600,
        )  # fmt: skip
        truth = out / f"{name}.truth.json"
        if truth.is_file():  # the fit sees the recordings only
            (out / "truth").mkdir(exist_ok=True)
            os.replace(truth, out / "truth" / truth.name)
    say(
        "6",
        "rig: loads 40-120 %, pressures 85-115 % of NOMPRES, heating, no temperature channel; "
        "simulation: isothermal, 60/140/220 kPa, up to 160 % load, -10...80 degC, sidewall",
    )
    start = out / "start.tir"
    _write_without_pressure_and_temperature(tir, start)
    say("6", f"{start}: the tyre's file with its pressure and temperature terms zeroed")
    fused = out / "fused.tir"
    stdout = run(
        [*tool("tire-model"), "fit", str(out / "rig"), "--tir", str(start), "-o", str(fused),
         "--extend", str(out / "simulation"), "--quiet"],
        "6",
        3600,
    )  # fmt: skip
    for line in stdout.strip().splitlines():
        say("6", line)
    report = out / "fused_fit_report"
    missing = [f for f in EXTEND_FIGURES if not (report / f).is_file()]
    if missing:
        raise RuntimeError(f"{report}: no {', '.join(missing)}")
    figures = ", ".join(EXTEND_FIGURES)
    say(
        "6", f"{report / 'extension.md'}: the operating envelope and the seed's figures ({figures})"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="output dir (new or empty)")
    parser.add_argument("--tir", type=Path, default=None, help="tyre (default config/default.tir)")
    args = parser.parse_args(argv)
    start = time.monotonic()
    try:
        tir = (args.tir or default_tir()).resolve()
        out = out_dir(args.out)
        say("demo", f"tyre {tir}; output in {out}")
        bag = step_record(tir, out)
        wheels, diag, improved = step_diagnose(bag, tir, out)
        step_report(diag, wheels, out)
        ok = step_node(wheels, diag, tir, improved, out)
        step_truth(out, wheels, diag)
        step_extend(tir, out)
    except (OSError, ValueError, RuntimeError, subprocess.TimeoutExpired) as exc:
        print(f"\ndemo: FAILED in step '{_STEP['now']}': {exc}", file=sys.stderr, flush=True)
        return 1
    say(
        "demo",
        f"{'done' if ok else 'FAILED at the node step'} in "
        f"{time.monotonic() - start:.0f} s; everything is in {out}",
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
