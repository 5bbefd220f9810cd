"""``tire_model_node``: streams each wheel's forces from the extended Magic Formula (ROS glue:
topics, parameters, services, diagnostics).

Console scripts ``tire-model-node`` and ``tire_model_node`` (``ros2 run tire_model_ros
tire_model_node``), or ``python -m tire_model_ros.ros.node``; the same node as a managed
(lifecycle) node: ``tire-model-lifecycle-node`` (:mod:`.lifecycle`).

Topics per wheel prefix P (INTERFACE.md): ``P/slip``, ``P/load``, ``P/pressure``,
``P/temperature``, ``P/velocity`` in; ``P/forces`` out, one per slip message with its header.
Input handling and counters (no ROS): :mod:`tire_model_ros.wheel.state`. Parameter names:
:mod:`tire_model_ros.wheel.params`. QoS: :mod:`.topics`. /diagnostics: :mod:`.diagnostics`.

Time: each slip message is computed with the other inputs aligned by header stamp, as the
offline tool aligns a recording (the latest value stamped at or before the slip; one function,
``recording.align.latest_at_or_before``); an input is stale when stamped more than its timeout
before the slip (stamp time). Everything else that is timed runs on the ROS clock
(``use_sim_time``, ``/clock``): the /diagnostics period and stamps, the log throttle, the wait.

Holding (``align.wait``, :mod:`tire_model_ros.wheel.hold`): topics are delivered each in stamp
order but not in step, so the load stamped with a slip may arrive after it (a loaded machine,
reliable back-pressure). A slip is answered on arrival when every input still arriving (one
whose last message came within ``align.wait`` of now, ROS clock) already has a value stamped at
or after it; otherwise it is held, in order, until they have (``released_caught_up``, answered
after the input message that completed it) or until it has waited ``align.wait``
(``released_by_wait``, computed with what there is; a timer on the ROS clock releases it, so a
paused simulation holds it). An input never received or no longer arriving is not waited for.
At most 8192 slips per wheel are held (``released_by_overflow``: the oldest answered early);
deactivation and shutdown answer the rest (``released_by_flush``). Inputs must be stamped on
the slips' clock: an input stamped behind (e.g. zero stamps) holds every slip the full wait.

Parameters
----------
wheels : string[]            wheel prefixes (read-only), default ["wheel"]
tir_file : string            shared model's .tir (default: the package's config/default.tir)
<wheelkey>.tir_file : string a wheel's own .tir ("" = shared model); ``/car/rl`` -> ``car.rl``
lenient : bool               read .tir files with ``read_tir(lenient=True)`` (default false)
effects_file : string        hidden states of an improved model, written by ``tire-model
                             diagnose`` beside its .tir ("" = none, the default): a hidden
                             tread/gas node stands in for a temperature/pressure that is not
                             fresh, a carcass node and a speed table scale friction, offsets
                             add (per wheel prefix; a one-wheel file serves every wheel)
<NAME>, <wheelkey>.<NAME> : double
                             every numeric coefficient of the shared / a wheel's own model,
                             each with its range
limits : bool                saturate inputs to the file's ranges, low-speed model (default true)
pressure_is_absolute : bool  P/pressure carries absolute pressure (gauge = p - ambient_pressure)
ambient_pressure : double    [Pa], default 101325
missing_load : string        "nominal" (FNOMIN, default) or "skip" when load is missing/stale
timeout.{load,pressure,temperature,velocity} : double  staleness [s of stamp time]; 0 = never
align.wait : double          [s] on the ROS clock a slip may wait for the inputs' stamps to
                             reach it, and an input may be silent and still be waited for
                             (default 0: answer each slip on arrival; see wheel.params)
diagnostics_period : double  [s] period of /diagnostics on the ROS clock (read-only), default 1
qos_depth : int              depth of the keep-last queues (read-only), default 100
input_reliability : string   best_available (default) | reliable | best_effort (read-only)
input_history : string       keep_all (default) | keep_last (read-only)
output_reliability : string  reliable (default) | best_effort (read-only)
rt_priority : int            SCHED_FIFO priority 1..99 of all the node's threads (read-only);
                             default 0 = normal scheduling (see :mod:`.realtime`)
cpus : int[]                 CPU affinity of the node's threads (read-only); default unset = all

Live changes: a coefficient change builds a new immutable model with ``with_params`` inside the
on-set callback, checks it on its operating grid (``model.check.check_model``) and swaps one
reference, so every message is computed with the old or the new model, never a mix; a model
that fails the check, or a value outside its range, is refused with the reason (the old model
keeps running). Setting a ``tir_file`` or ``effects_file`` (even to the same path) reloads that
file (a new effects file restarts the hidden states); coefficients set in the same atomic
request apply on top of the new file; afterwards the coefficient parameters of that model are
re-declared with the file's values. A wheel's ``<wheelkey>.<NAME>`` parameters exist only while
it has its own file (set ``<wheelkey>.tir_file`` first, then its coefficients; setting it back
to "" returns the wheel to the shared model and removes them). ``~/reload`` (std_srvs/Trigger)
re-reads every file in use (edits made through parameters since the last load are replaced by
the file's values).

Loss: a message that cannot be read is counted and dropped; every slip message taken is
answered or counted under a reason (:data:`..wheel.state.UNANSWERED`); at exit the node prints
one ``final counts`` line per wheel with every counter.

Executor: rclpy's EventsExecutor (2-3x the message rate of SingleThreadedExecutor here; the
single-threaded one on a simulated clock, whose timers the events executor does not follow
reliably), driven by ``spin_once`` so that SIGINT/SIGTERM end the process cleanly with exit
code 0.

Latency: once started, ``main`` freezes the start-up heap (a full garbage collection of it
would stall messages by 16-54 ms) and applies ``rt_priority`` and ``cpus`` to every thread.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from operator import attrgetter
from pathlib import Path
from typing import Any, cast

import rclpy
import rclpy.exceptions
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.serialization import deserialize_message
from rclpy.timer import Timer
from std_srvs.srv import Trigger

from tire_model_ros.model import TireModel
from tire_model_ros.model.check import check_model
from tire_model_ros.model.states import Effects, EffectState
from tire_model_ros.recording import cdr
from tire_model_ros.ros import cdr_fast, realtime
from tire_model_ros.ros.diagnostics import wheel_status
from tire_model_ros.ros.msg_types import msg_class
from tire_model_ros.ros.parameters import coefficient_descriptor, declare_node_params, descriptor
from tire_model_ros.ros.teardown import deadline
from tire_model_ros.ros.topics import InputSubscription, TopicQoS, output_events
from tire_model_ros.vocabulary import (
    CHANNEL_TYPES,
    FORCES,
    INPUT_FIELDS,
    NODE_INPUTS,
    NS_PER_S,
)
from tire_model_ros.wheel import params as pn
from tire_model_ros.wheel.hold import PendingSlip
from tire_model_ros.wheel.state import Settings, Throttle, WheelModel, WheelState, final_line

NODE_NAME = "tire_model_node"


def _input_topic(channel: str) -> tuple[type, int, str]:
    """(message class, index of its float64 after the header, field for the slow path)."""
    msgtype = CHANNEL_TYPES[channel]
    field = INPUT_FIELDS[channel]
    return msg_class(msgtype), cdr.LAYOUTS[msgtype].index(field), field


#: Input channel -> what the node reads from it (INTERFACE.md, :mod:`tire_model_ros.vocabulary`).
INPUT_TOPICS = {channel: _input_topic(channel) for channel in NODE_INPUTS}
#: What a held slip keeps to be published later: the publisher, the slip's CDR bytes, its
#: header end (-1: not CDR_LE) and the deserialised message (None when read from the bytes).
Payload = tuple[Publisher, bytes, int, Any]


def hold_timer_period(wait_s: float) -> float:
    """Period [s] of the timer that releases waited-out slips: a tenth of the bound (a slip is
    released at most 10 % late), between 1 ms and 0.1 s."""
    return min(max(wait_s / 10.0, 0.001), 0.1) if wait_s > 0 else 0.1


@dataclass(frozen=True)
class Slot:
    """One loaded model: swapped as a whole, never modified."""

    param_value: str  # tir_file as given
    path: str  # resolved file
    wm: WheelModel
    notes: tuple[str, ...] = ()  # what a lenient read let through

    @property
    def model(self) -> TireModel:
        return self.wm.model

    @classmethod
    def load(cls, value: str, lenient: bool = False) -> Slot:
        path = pn.resolve_tir_path(value)
        model = TireModel.from_file(str(path), lenient=lenient)  # read_tir checks the model
        return cls.checked(value, str(path), model, model.tir.notes)

    @classmethod
    def with_model(cls, value: str, path: str, model: TireModel) -> Slot:
        """A coefficient change: the new model must be a tyre on its operating grid."""
        fault = check_model(model)
        if fault is not None:
            raise ValueError(f"{path}: the model is not a tyre on its operating range: {fault}")
        return cls.checked(value, path, model)

    @classmethod
    def checked(cls, value: str, path: str, model: TireModel, notes: tuple[str, ...] = ()) -> Slot:
        """Evaluate once at the nominal point (finite there, and the kernel compiled before
        the first message)."""
        wm = WheelModel.of(model)
        n = wm.nominal
        out = model.evaluate_one(n.Fz, 0.05, 0.05, 0.0, n.Vx, n.p, n.T)
        if not all(math.isfinite(x) for x in out):
            raise ValueError(f"{path}: the model gives non-finite forces at its nominal point")
        return cls(value, path, wm, notes)


def _load_effects(value: object) -> Effects | None:
    if not isinstance(value, str):
        raise ValueError(f"effects_file: expected a string path, got {value!r}")
    return Effects.read(value) if value else None


def _fail(reason: str) -> SetParametersResult:
    return SetParametersResult(successful=False, reason=reason)


def read_slip(data: bytes) -> tuple[int, float, float, float, int, Any] | None:
    """(header end or -1, kappa, alpha, gamma, stamp [ns], message or None) of a slip
    message; None when it cannot be read (counted by the caller)."""
    parsed = cdr_fast.read_vector(data)
    if parsed is not None:
        end, x, y, z = parsed
        return end, x, y, z, cdr_fast.read_stamp_ns(data), None
    try:  # not CDR_LE: rclpy's deserialiser, which raises RMWError (or else) on garbage
        msg = deserialize_message(data, Vector3Stamped)
    except Exception:
        return None
    v, st = msg.vector, msg.header.stamp
    return -1, v.x, v.y, v.z, st.sec * NS_PER_S + st.nanosec, msg


def read_input(data: bytes, msg_type: type, index: int, field: str) -> tuple[int, float] | None:
    """(stamp [ns], value) of an input message; None when it cannot be read."""
    value = cdr_fast.read_double(data, index)
    if value is not None:
        return cdr_fast.read_stamp_ns(data), value
    try:
        msg = deserialize_message(data, msg_type)
        st = msg.header.stamp
        return st.sec * NS_PER_S + st.nanosec, float(attrgetter(field)(msg))
    except Exception:
        return None


class TireModelCore(Node):
    """Everything of the node but its life cycle: the plain node (:class:`TireModelNode`) and
    the managed one (``TireModelCore`` before ``LifecycleNode`` in its bases) share it.
    ``_init_core`` declares the parameters, ``_setup`` loads the models and makes the topics,
    ``_teardown`` undoes that; ``active`` gates the computation."""

    def _init_core(self) -> None:
        self._syncing = False  # re-declaring coefficients after a file change: no rebuild
        self._redeclare: set[str] = set()
        self._declared: dict[str, list[str]] = {}  # slot -> coefficient parameter names
        self._throttle = Throttle(5.0)
        self._own_pubs: list[Publisher] = []
        self._own_timers: list[Any] = []
        self._own_services: list[Any] = []
        self._own_subs: list[InputSubscription] = []
        self.reloads = 0
        self.param_rejections = 0
        self.last_rejection = ""
        self.active = False
        self.configured = False
        self.slots: dict[str, Slot] = {}
        self.wait_ns = round(pn.DEFAULT_ALIGN_WAIT * NS_PER_S)  # align.wait
        self._hold_timer: Timer | None = None
        # the ROS clock's handle: its now in ns costs ~1 us against ~5 us for Clock.now(), and
        # it is read on every input message with use_sim_time (:meth:`_now_ns`)
        self._clock_handle = self.get_clock().handle
        self._sim_time = False
        self._waited_seen: dict[str, int] = {}  # released_by_wait already logged, per wheel
        declare_node_params(self)
        prefixes = list(self.get_parameter("wheels").value)
        self._keys = pn.wheel_keys(prefixes)
        self.wheels = [WheelState(prefix, key) for prefix, key in self._keys.items()]
        for w in self.wheels:
            self.declare_parameter(
                f"{w.key}.tir_file", "",
                descriptor(f"own .tir of wheel {w.prefix} ('' = the shared tir_file)"),
            )  # fmt: skip
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._post_set_parameters)

    # ---------------------------------------------------------------- set-up and teardown
    def _setup(self) -> None:
        """Load the models, make topics, service and timer (raises ValueError/OSError)."""
        self._read_settings()
        self._load_initial_models()
        g = self.get_parameter
        self.qos = TopicQoS(
            str(g("input_reliability").value),
            str(g("input_history").value),
            str(g("output_reliability").value),
            int(g("qos_depth").value),
        )
        self._make_topics()
        self._own_services.append(self.create_service(Trigger, "~/reload", self._on_reload))
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._own_pubs.append(self._diag_pub)
        self._diag_last: dict[str, dict[str, int]] = {}
        period = float(g("diagnostics_period").value)
        self._own_timers.append(self.create_timer(period, self._publish_diagnostics))
        self._hold_timer = self.create_timer(hold_timer_period(self.wait_ns / NS_PER_S),
                                             self._release_waited)  # fmt: skip
        self._own_timers.append(self._hold_timer)
        self.configured = True
        files = ", ".join(f"{k or 'shared'}={s.path}" for k, s in self.slots.items())
        package = Path(__file__).resolve().parents[1]
        self.get_logger().info(
            f"tire_model_ros from {package}; wheels {[w.prefix for w in self.wheels]}; "
            f"models: {files}; inputs {self.qos.input_reliability}/{self.qos.input_history}, "
            f"outputs {self.qos.output_reliability}"
        )

    def _teardown(self) -> None:
        self.flush_held()  # before the publishers go
        self._hold_timer = None
        for sub in self._own_subs:
            sub.destroy()
        for pub in self._own_pubs:
            self.destroy_publisher(pub)
        for timer in self._own_timers:
            self.destroy_timer(timer)
        for service in self._own_services:
            self.destroy_service(service)
        self._own_subs, self._own_pubs, self._own_timers, self._own_services = [], [], [], []
        self._syncing = True
        try:
            for names in self._declared.values():
                for name in names:
                    if self.has_parameter(name):
                        self.undeclare_parameter(name)
        finally:
            self._syncing = False
        self._declared = {}
        self.slots = {}
        self.configured = False

    # ---------------------------------------------------------------- parameters: declare
    def _declare_coefficients(
        self, slot: str, model: TireModel, overrides: bool
    ) -> dict[str, float]:
        """Declare one parameter per coefficient; returns values that overrides changed."""
        prefix = f"{slot}." if slot else ""
        changed: dict[str, float] = {}
        names = []
        self._syncing = True  # declaring is no change request
        try:
            for key, value in model.params.items():
                name = prefix + key
                got = self.declare_parameter(
                    name, float(value), coefficient_descriptor(key, value),
                    ignore_override=not overrides,
                ).value  # fmt: skip
                names.append(name)
                if got != value:
                    changed[key] = pn.coefficient_value(name, got)
        finally:
            self._syncing = False
        self._declared[slot] = names
        return changed

    def _load_initial_models(self) -> None:
        lenient = bool(self.get_parameter("lenient").value)
        slot = Slot.load(self.get_parameter("tir_file").value, lenient)
        changed = self._declare_coefficients("", slot.model, overrides=True)
        self.slots = {"": self._with_updates(slot, changed)}
        for w in self.wheels:
            value = self.get_parameter(f"{w.key}.tir_file").value
            if value:
                own = Slot.load(value, lenient)
                changed = self._declare_coefficients(w.key, own.model, overrides=True)
                self.slots[w.key] = self._with_updates(own, changed)
                w.slot = w.key
        self._say_notes(self.slots.values())
        self._set_effects(_load_effects(self.get_parameter("effects_file").value))

    def _set_effects(self, effects: Effects | None) -> None:
        """Fresh hidden states for every wheel the effects file serves (none: no effects)."""
        for w in self.wheels:
            fx = effects.for_wheel(w.prefix) if effects is not None else None
            w.effects = EffectState(fx) if fx is not None else None

    @staticmethod
    def _with_updates(slot: Slot, updates: dict[str, float]) -> Slot:
        if not updates:
            return slot
        return Slot.with_model(slot.param_value, slot.path, slot.model.with_params(updates))

    def _read_settings(self) -> None:
        g = self.get_parameter
        self.pressure_is_absolute = bool(g("pressure_is_absolute").value)
        self.ambient_pressure = float(g("ambient_pressure").value)
        policy = g("missing_load").value
        if policy not in pn.MISSING_LOAD_POLICIES:
            raise ValueError(f"missing_load: {policy!r} is not one of {pn.MISSING_LOAD_POLICIES}")
        timeouts = {k: float(g(f"timeout.{k}").value) for k in NODE_INPUTS}
        self.settings = Settings.of(timeouts, bool(g("limits").value), policy == "skip")
        self.wait_ns = round(float(g("align.wait").value) * NS_PER_S)
        self._sim_time = bool(g("use_sim_time").value)

    # ---------------------------------------------------------------- parameters: change
    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        if self._syncing:
            return SetParametersResult(successful=True)
        try:
            settings = self._plan_settings(params)
            if not self.configured:  # a managed node before configure: files load then
                return SetParametersResult(successful=True)
            new_slots, redeclare = self._plan(params)
            effects = [_load_effects(p.value) for p in params if p.name == "effects_file"]
        except (ValueError, OSError) as exc:  # TirError, EffectsError are ValueErrors
            return self._reject(str(exc))
        except Exception as exc:  # a bug in a model build must not stop the node
            return self._reject(f"{type(exc).__name__}: {exc}")
        self._commit(new_slots, redeclare, settings, effects)
        return SetParametersResult(successful=True)

    def _commit(
        self,
        new_slots: dict[str, Slot | None],
        redeclare: set[str],
        settings: dict[str, object],
        effects: list[Effects | None],
    ) -> None:
        """Plain attribute swaps: nothing here can fail half-way."""
        slots = dict(self.slots)
        for slot, value in new_slots.items():
            if value is None:
                slots.pop(slot, None)
            else:
                slots[slot] = value
        self.slots = slots
        for w in self.wheels:
            w.slot = w.key if w.key in slots else ""
        for name, setting in settings.items():
            setattr(self, name, setting)
        if "wait_ns" in settings and self._hold_timer is not None:
            self._hold_timer.timer_period_ns = round(
                hold_timer_period(self.wait_ns / NS_PER_S) * NS_PER_S
            )
        if effects:
            self._set_effects(effects[-1])
            self.reloads += 1
        self._redeclare |= redeclare
        if redeclare:
            self.reloads += 1
            loaded = ", ".join(f"{k or 'shared'}={slots[k].path}" for k in redeclare if k in slots)
            self.get_logger().info(f"model loaded: {loaded or 'wheels back on shared model'}")
            self._say_notes(slots[k] for k in redeclare if k in slots)  # as at start-up

    def _say_notes(self, slots: Iterable[Slot]) -> None:
        """What reading the model files let through (a lenient fill, a vendor's section)."""
        for slot in slots:
            for note in slot.notes:
                self.get_logger().warning(f"model file: {note}")

    def _reject(self, reason: str) -> SetParametersResult:
        self.param_rejections += 1
        self.last_rejection = reason
        self.get_logger().warning(f"parameter change rejected (old model kept): {reason}")
        return _fail(reason)

    def _plan(self, params: list[Parameter]) -> tuple[dict[str, Slot | None], set[str]]:
        """New slots for the request: files loaded, coefficient updates applied and checked."""
        files: dict[str, Slot | None] = {}
        coefs: dict[str, dict[str, float]] = {}
        lenient = bool(self.get_parameter("lenient").value)
        lenient = next((bool(p.value) for p in params if p.name == "lenient"), lenient)
        for p in params:
            what = pn.classify(p.name, self._keys.values())
            if what.kind == "file":
                if not isinstance(p.value, str):
                    raise ValueError(f"{p.name}: expected a string path")
                if what.slot and p.value == "":
                    files[what.slot] = None  # back to the shared model
                else:
                    try:
                        files[what.slot] = Slot.load(p.value, lenient)
                    except (ValueError, OSError) as exc:
                        raise ValueError(f"{p.name}={p.value!r}: {exc}") from exc
            elif what.kind == "coef":
                value = pn.coefficient_value(p.name, p.value)
                coefs.setdefault(what.slot, {})[what.key] = value
        out: dict[str, Slot | None] = dict(files)
        for slot, updates in coefs.items():
            base = files[slot] if slot in files else self.slots.get(slot)
            if base is None:
                raise ValueError(
                    f"wheel {slot!r} uses the shared model: set {slot}.tir_file first "
                    f"(coefficients {sorted(updates)})"
                )
            out[slot] = Slot.with_model(
                base.param_value, base.path, base.model.with_params(updates)
            )
        return out, set(files)

    def _plan_settings(self, params: list[Parameter]) -> dict[str, object]:
        """Validated node settings of the request (attribute name -> value)."""
        out: dict[str, object] = {}
        settings = getattr(self, "settings", None) or Settings.of(pn.DEFAULT_TIMEOUTS, True, False)
        timeouts = dict(settings.timeouts_ns)
        limits, skip = settings.limits, settings.skip_without_load
        for p in params:
            if p.name == "missing_load":
                if p.value not in pn.MISSING_LOAD_POLICIES:
                    raise ValueError(f"missing_load: {p.value!r} not in {pn.MISSING_LOAD_POLICIES}")
                skip = p.value == "skip"
            elif p.name in ("limits", "pressure_is_absolute", "lenient"):
                if not isinstance(p.value, bool):
                    raise ValueError(f"{p.name}: expected a bool")
                if p.name == "limits":
                    limits = p.value
                elif p.name == "pressure_is_absolute":
                    out[p.name] = p.value
            elif p.name == "ambient_pressure":
                out["ambient_pressure"] = float(p.value)
            elif p.name.startswith("timeout."):
                timeouts[p.name.split(".", 1)[1]] = round(float(p.value) * NS_PER_S)
            elif p.name == "align.wait":
                out["wait_ns"] = round(float(p.value) * NS_PER_S)
            elif p.name == "use_sim_time" and isinstance(p.value, bool):  # the waits' clock
                out["_sim_time"] = bool(p.value)
        out["settings"] = Settings(timeouts, limits, skip)
        return out

    def _post_set_parameters(self, params: list[Parameter]) -> None:
        if self._syncing or not self._redeclare:
            return
        slots, self._redeclare = self._redeclare, set()
        self._syncing = True
        try:
            for slot in slots:
                for name in self._declared.pop(slot, []):
                    if self.has_parameter(name):
                        self.undeclare_parameter(name)
        finally:
            self._syncing = False
        for slot in slots:
            if slot in self.slots:
                self._declare_coefficients(slot, self.slots[slot].model, overrides=False)

    def _on_reload(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        names = ["tir_file"] + [f"{k}.tir_file" for k in self.slots if k]
        if self.get_parameter("effects_file").value:
            names.append("effects_file")
        params = [self.get_parameter(n) for n in names]
        result = self.set_parameters_atomically(params)
        response.success = bool(result.successful)
        files = ", ".join(s.path for s in self.slots.values())
        response.message = f"reloaded {files}" if result.successful else result.reason
        return response

    # ---------------------------------------------------------------- topics
    def _make_topics(self) -> None:
        """Raw (serialized) subscriptions: the few doubles are read straight from the CDR
        bytes (``cdr_fast``), and the output is written as CDR bytes with the slip's header;
        rclpy's (de)serialiser is the fallback for any other layout."""
        for w in self.wheels:
            topic = f"{w.prefix}/{FORCES}"
            pub = self.create_publisher(WrenchStamped, topic, self.qos.output(),
                                        event_callbacks=output_events(self, topic))  # fmt: skip
            self._own_pubs.append(pub)
            slip = InputSubscription(
                self, Vector3Stamped, f"{w.prefix}/slip", self._slip_cb(w, pub), self.qos
            )
            self._own_subs.append(slip)
            for name, (msg_type, _, _) in INPUT_TOPICS.items():
                topic = f"{w.prefix}/{name}"
                cb = self._input_cb(w, name)
                self._own_subs.append(InputSubscription(self, msg_type, topic, cb, self.qos))

    def _now_ns(self) -> int:
        """The ROS clock [ns]: the simulator's with use_sim_time, else the system clock (which
        the ROS clock then is; read directly, 20x cheaper, as it is read on every input)."""
        if self._sim_time:
            return int(self._clock_handle.get_now().nanoseconds)
        return time.time_ns()

    def _slip_cb(self, w: WheelState, pub: Publisher) -> Callable[[bytes], None]:
        hold = w.hold

        def on_slip(data: bytes) -> None:
            if not self.active:
                w.inactive()
                return
            parsed = read_slip(data)
            if parsed is None:
                w.malformed("slip")
                self._log_events(w, ["slip_malformed: a slip message could not be read"])
                return
            end, x, y, z, stamp_ns, msg = parsed
            if hold.quick(stamp_ns):  # the usual case: answered now, no clock read
                self._answer(w, x, y, z, stamp_ns, (pub, data, end, msg))
                return
            now = self._now_ns()
            slip = PendingSlip(x, y, z, stamp_ns, now, (pub, data, end, msg))
            self._answer_held(w, hold.arrive(slip, now, self.wait_ns))

        return on_slip

    def _answer(
        self, w: WheelState, x: float, y: float, z: float, stamp_ns: int, payload: object
    ) -> None:
        """Compute one slip sample and publish its forces with the slip's header."""
        res, events = w.compute(x, y, z, stamp_ns, self.slots[w.slot].wm, self.settings)
        if events:
            self._log_events(w, events)
        if res is None:
            return
        pub, data, end, msg = cast(Payload, payload)  # what on_slip keeps
        try:
            if end >= 0:
                pub.publish(cdr_fast.wrench_like(data, end, res))
                return
            out = WrenchStamped()
            out.header = msg.header  # same stamp (and frame) as the slip sample
            f, t = out.wrench.force, out.wrench.torque
            f.x, f.y, f.z, t.x, t.y, t.z = res
            pub.publish(out)
        except _rclpy.RCLError as exc:  # SIGTERM shut the context down under this callback
            w.unpublished(f"publish failed: {exc}")

    def _answer_held(self, w: WheelState, slips: list[PendingSlip]) -> None:
        """Answer slips released by the hold, in order; say (throttled) when the wait ran out."""
        for p in slips:
            self._answer(w, p.kappa, p.alpha, p.gamma, p.stamp_ns, p.payload)
        waited = w.hold.counts["released_by_wait"]
        if waited != self._waited_seen.get(w.key, 0):
            self._waited_seen[w.key] = waited
            self._log_events(w, [
                f"released_by_wait: slips answered without {w.hold.lagging} at their stamp "
                f"(it did not reach them within align.wait {self.wait_ns / NS_PER_S:g} s; "
                "inputs stamped on the slips' clock catch up, align.wait 0 answers on arrival)"
            ])  # fmt: skip

    def _release_waited(self) -> None:
        """Timer: answer the slips whose wait is over (or whose inputs stopped)."""
        now = self._now_ns()
        for w in self.wheels:
            if w.hold.queue:
                self._answer_held(w, w.hold.release(now, self.wait_ns))

    def flush_held(self) -> None:
        """Answer every pending slip with what there is (deactivation, shutdown); publishing
        after SIGTERM fails and is counted (``publish_failed``)."""
        if not self.slots:
            return  # not configured: nothing can be pending
        for w in self.wheels:
            self._answer_held(w, w.hold.flush())

    def _input_cb(self, w: WheelState, name: str) -> Callable[[bytes], None]:
        msg_type, index, field = INPUT_TOPICS[name]
        absolute = name == "pressure"
        hold = w.hold

        def cb(data: bytes) -> None:
            parsed = read_input(data, msg_type, index, field)
            if parsed is None:
                w.malformed(name)
                self._log_events(w, [f"{name}.malformed: a {name} message could not be read"])
                return
            stamp_ns, value = parsed
            if absolute and self.pressure_is_absolute:
                value -= self.ambient_pressure
            rejection = w.set_input(name, stamp_ns, value)
            if rejection is not None:
                self._log_events(w, [f"{name}.rejected: {rejection}"])
            slips = hold.take(name, stamp_ns, self._now_ns(), self.wait_ns)
            if slips:  # held for this input, and now ready
                self._answer_held(w, slips)

        return cb

    def _log_events(self, w: WheelState, events: list[str]) -> None:
        now = self.get_clock().now().nanoseconds / NS_PER_S  # the ROS clock
        for event in events:
            kind = event.split(":", 1)[0]
            suppressed = self._throttle.due(f"{w.key}/{kind}", now)
            if suppressed is not None:
                more = f" (+{suppressed} more since last)" if suppressed else ""
                self.get_logger().warning(f"{w.prefix}: {event}{more}")

    # ---------------------------------------------------------------- diagnostics
    def _publish_diagnostics(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status.append(self._model_status())
        for w in self.wheels:
            counts = w.counters()
            own = [s for s in self._own_subs if s.topic.startswith(w.prefix + "/")]
            counts["resubscribed"] = sum(s.resubscribed for s in own)
            counts["resubscribe_unmatched"] = sum(s.unmatched for s in own)
            last = self._diag_last.get(w.key, {})
            delta = {k: v - last.get(k, 0) for k, v in counts.items()}
            self._diag_last[w.key] = counts
            arr.status.append(wheel_status(
                f"{self.get_name()}: {w.prefix}", w, delta, counts, self.slots[w.slot].path,
                self.settings.limits,
            ))  # fmt: skip
        with contextlib.suppress(_rclpy.RCLError):  # the context shut down: no one to tell
            self._diag_pub.publish(arr)

    def _model_status(self) -> DiagnosticStatus:
        st = DiagnosticStatus(
            name=f"{self.get_name()}: model", hardware_id=self.get_fully_qualified_name()
        )
        st.level = DiagnosticStatus.OK
        st.message = f"{len(self.slots)} model(s) loaded" + ("" if self.active else "; inactive")
        values = {f"tir_file{'.' + k if k else ''}": s.path for k, s in self.slots.items()}
        values.update(
            {
                "effects_file": str(self.get_parameter("effects_file").value),
                "limits": str(self.settings.limits),
                "active": str(self.active),
                "reloads": str(self.reloads),
                "parameter_rejections": str(self.param_rejections),
                "last_rejection": self.last_rejection,
                "lenient_notes": " | ".join(n for s in self.slots.values() for n in s.notes),
            }
        )
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        return st

    def print_final_counts(self) -> None:
        """One ``final counts`` line per wheel on stdout (what the node did not deliver), after
        the pending slips are answered."""
        self.flush_held()
        for w in self.wheels:
            print(final_line(w.prefix, w.counters()), flush=True)


class TireModelNode(TireModelCore):
    """Streams ``P/forces`` for every wheel prefix P; see the module docstring."""

    def __init__(self, **kwargs: Any) -> None:
        Node.__init__(self, NODE_NAME, **kwargs)
        self._init_core()
        self._setup()
        self.active = True


def make_executor(kind: str | None = None, sim_time: bool = False) -> Executor:
    """EventsExecutor (default, ~2.5x the callback rate here) or SingleThreadedExecutor.

    ``TIRE_MODEL_EXECUTOR=single`` selects the single-threaded one (for comparisons). On a
    simulated clock (``use_sim_time``) it is always the single-threaded one: the events
    executor's timer manager (as rclcpp's, ros2/rclcpp#2457) does not follow /clock reliably,
    and the /diagnostics and hold timers run on that clock.
    """
    kind = kind or os.environ.get("TIRE_MODEL_EXECUTOR", "events")
    if kind == "single" or sim_time:
        return SingleThreadedExecutor()
    from rclpy.experimental import EventsExecutor

    return EventsExecutor()


def spin(executor: Executor, done: Callable[[], bool] = lambda: False) -> None:
    """Spin until the context shuts down (SIGINT/SIGTERM: rclpy's handlers shut it down) or
    ``done()``.

    EventsExecutor.spin() does not return on that shutdown here (it keeps a core busy), so it
    is driven by spin_once with a timeout, which checks the context between events.
    """
    while rclpy.ok() and not done():
        executor.spin_once(timeout_sec=0.5)


def tune_process(node: Node) -> None:
    """Scheduling from the node's ``rt_priority``/``cpus``, then freeze the start-up heap."""
    priority = int(node.get_parameter("rt_priority").value)
    try:
        cpus = list(node.get_parameter("cpus").value)
    except rclpy.exceptions.ParameterUninitializedException:
        cpus = []  # unset: all CPUs
    problems = realtime.tune(priority, cpus)
    for problem in problems:
        node.get_logger().warning(f"scheduling: {problem}")
    if (priority or cpus) and not problems:
        node.get_logger().info(f"scheduling: SCHED_FIFO {priority or 'off'}, cpus {cpus or 'all'}")


START_ERRORS = (
    ValueError,
    OSError,
    rclpy.exceptions.ParameterException,
    rclpy.exceptions.NameValidationException,
)


def run(make: Callable[[], Any], done: Callable[[Any], bool] = lambda _n: False) -> int:
    """Start ``make()`` (a node), spin it until SIGINT/SIGTERM or ``done(node)``; exit status.

    The kernels are loaded (or compiled, saying so) first; at the end every wheel's
    ``final counts`` line is printed.
    """
    from tire_model_ros.model.startup import warm_up_announced

    warm_up_announced(lambda text: print(f"{NODE_NAME}: {text}", flush=True))
    node = None
    code = 0
    try:
        node = make()
        executor = make_executor(sim_time=bool(node.get_parameter("use_sim_time").value))
        executor.add_node(node)
        tune_process(node)
        spin(executor, lambda: done(node))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except _rclpy.RCLError:
        if rclpy.ok():
            raise
        # SIGINT/SIGTERM while the node was still being made (seen under load): the signal
        # shut the context down, and the next create_* call failed on it; a shutdown, not a
        # crash
    except START_ERRORS as exc:
        print(f"{NODE_NAME}: error: {exc}", file=sys.stderr)
        code = 1
    finally:
        if node is not None:
            node.print_final_counts()
        with deadline():
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
    return code


def main(args: list[str] | None = None) -> int:
    """Console entry point: run the node until SIGINT/SIGTERM; the exit status."""
    rclpy.init(args=args)
    return run(TireModelNode)


if __name__ == "__main__":
    sys.exit(main())
