"""``tire_model_node``: streams each wheel's forces from the extended Magic Formula (ROS glue:
topics, parameters, services, diagnostics).

Console scripts ``tire-model-node`` and ``tire_model_node`` (``ros2 run tire_model_ros
tire_model_node``), or ``python -m tire_model_ros.ros.node``.

Topics per wheel prefix P (INTERFACE.md): ``P/slip``, ``P/load``, ``P/pressure``,
``P/temperature``, ``P/velocity`` in; ``P/forces`` out, one per slip message with its header.
Input handling and counters (no ROS): :mod:`tire_model_ros.wheel.state`. Parameter names:
:mod:`tire_model_ros.wheel.params`.

Parameters
----------
wheels : string[]            wheel prefixes (read-only), default ["wheel"]
tir_file : string            shared model's .tir (default: the package's config/default.tir)
<wheelkey>.tir_file : string a wheel's own .tir ("" = shared model); ``/car/rl`` -> ``car.rl``
effects_file : string        hidden states of an improved model, written by ``tire-model
                             diagnose`` beside its .tir ("" = none, the default): a hidden
                             tread/gas node stands in for a temperature/pressure that is not
                             fresh, a carcass node and a speed table scale friction, offsets
                             add (per wheel prefix; a one-wheel file serves every wheel)
<NAME>, <wheelkey>.<NAME> : double
                             every numeric coefficient of the shared / a wheel's own model
limits : bool                saturate inputs to the file's ranges, low-speed model (default true)
pressure_is_absolute : bool  P/pressure carries absolute pressure (gauge = p - ambient_pressure)
ambient_pressure : double    [Pa], default 101325
missing_load : string        "nominal" (FNOMIN, default) or "skip" when load is missing/stale
timeout.{load,pressure,temperature,velocity} : double  staleness [s]; 0 = never stale
diagnostics_period : double  [s] period of /diagnostics (read-only), default 1.0
qos_depth : int              depth of the reliable input/output queues (read-only), default 100;
                             at 1000, Fast DDS stalls for ms every few hundred ms (bench_node)
rt_priority : int            SCHED_FIFO priority 1..99 of all the node's threads (read-only);
                             default 0 = normal scheduling (see :mod:`.realtime`)
cpus : int[]                 CPU affinity of the node's threads (read-only); default unset = all

Live changes: a coefficient change builds a new immutable model with ``with_params`` inside the
on-set callback and swaps one reference, so every message is computed with the old or the new
model, never a mix; a failed build rejects the change (the old model keeps running). Setting a
``tir_file`` or ``effects_file`` (even to the same path) reloads that file (a new effects file
restarts the hidden states); coefficients set in the same atomic
request apply on top of the new file; afterwards the coefficient parameters of that model are
re-declared with the file's values. A wheel's ``<wheelkey>.<NAME>`` parameters exist only while
it has its own file (set ``<wheelkey>.tir_file`` first, then its coefficients; setting it back
to "" returns the wheel to the shared model and removes them). ``~/reload`` (std_srvs/Trigger)
re-reads every file in use (edits made through parameters since the last load are replaced by
the file's values).

Executor: rclpy's EventsExecutor (2-3x the message rate of SingleThreadedExecutor here), driven
by ``spin_once`` so that SIGINT/SIGTERM end the process cleanly with exit code 0.

Latency: once started, ``main`` freezes the start-up heap (a full garbage collection of it
would stall messages by 16-54 ms) and applies ``rt_priority`` and ``cpus`` to every thread.
"""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from operator import attrgetter
from pathlib import Path
from typing import Any

import rclpy
import rclpy.exceptions
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from std_srvs.srv import Trigger

from tire_model_ros.model import TireModel
from tire_model_ros.model.states import Effects, EffectState
from tire_model_ros.recording import cdr
from tire_model_ros.ros import cdr_fast, realtime
from tire_model_ros.ros.msg_types import msg_class
from tire_model_ros.ros.teardown import deadline
from tire_model_ros.vocabulary import (
    CHANNEL_TYPES,
    FORCES,
    INPUT_FIELDS,
    NODE_INPUTS,
    STANDARD_ATMOSPHERE_PA,
)
from tire_model_ros.wheel import params as pn
from tire_model_ros.wheel.state import Nominal, Throttle, WheelState

NODE_NAME = "tire_model_node"


def _input_topic(channel: str) -> tuple[type, int, str]:
    """(message class, index of its float64 after the header, field for the slow path)."""
    msgtype = CHANNEL_TYPES[channel]
    field = INPUT_FIELDS[channel]
    return msg_class(msgtype), cdr.LAYOUTS[msgtype].index(field), field


#: Input channel -> what the node reads from it (INTERFACE.md, :mod:`tire_model_ros.vocabulary`).
INPUT_TOPICS = {channel: _input_topic(channel) for channel in NODE_INPUTS}


@dataclass(frozen=True)
class Slot:
    """One loaded model: swapped as a whole, never modified."""

    param_value: str  # tir_file as given
    path: str  # resolved file
    model: TireModel
    nominal: Nominal

    @classmethod
    def load(cls, value: str) -> Slot:
        path = pn.resolve_tir_path(value)
        model = TireModel.from_file(str(path))
        return cls.with_model(value, str(path), model)

    @classmethod
    def with_model(cls, value: str, path: str, model: TireModel) -> Slot:
        """Check the model once at its nominal point (this also compiles the kernel, so the
        first message is not delayed); a model that is not finite there is refused."""
        nominal = Nominal.from_params(model.params)
        out = model.evaluate_one(nominal.Fz, 0.05, 0.05, 0.0, nominal.Vx, nominal.p, nominal.T)
        if not all(math.isfinite(x) for x in out):
            raise ValueError(f"{path}: the model gives non-finite forces at its nominal point")
        return cls(value, path, model, nominal)


def _load_effects(value: object) -> Effects | None:
    if not isinstance(value, str):
        raise ValueError(f"effects_file: expected a string path, got {value!r}")
    return Effects.read(value) if value else None


def _fail(reason: str) -> SetParametersResult:
    return SetParametersResult(successful=False, reason=reason)


def _descriptor(description: str, *, read_only: bool = False, **kw: Any) -> ParameterDescriptor:
    return ParameterDescriptor(description=description, read_only=read_only, **kw)


class TireModelNode(Node):
    """Streams ``P/forces`` for every wheel prefix P; see the module docstring."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._syncing = False  # re-declaring coefficients after a file change: no rebuild
        self._redeclare: set[str] = set()
        self._declared: dict[str, list[str]] = {}  # slot -> coefficient parameter names
        self._throttle = Throttle(5.0)
        self.reloads = 0
        self.param_rejections = 0
        self.last_rejection = ""
        self._declare_node_params()
        prefixes = list(self.get_parameter("wheels").value)
        self._keys = pn.wheel_keys(prefixes)
        self.wheels = [WheelState(prefix, key) for prefix, key in self._keys.items()]
        self.slots: dict[str, Slot] = {}
        self._load_initial_models()
        self._read_settings()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._post_set_parameters)
        self._make_topics()
        self.create_service(Trigger, "~/reload", self._on_reload)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._diag_last: dict[str, dict[str, int]] = {}
        period = float(self.get_parameter("diagnostics_period").value)
        self.create_timer(period, self._publish_diagnostics)
        files = ", ".join(f"{k or 'shared'}={s.path}" for k, s in self.slots.items())
        package = Path(__file__).resolve().parents[1]
        self.get_logger().info(f"tire_model_ros from {package}; wheels {prefixes}; models: {files}")

    # ---------------------------------------------------------------- parameters: declare
    def _declare_node_params(self) -> None:
        nonneg = FloatingPointRange(from_value=0.0, to_value=86400.0, step=0.0)
        self.declare_parameter(
            "wheels", ["wheel"], _descriptor("wheel topic prefixes", read_only=True)
        )
        self.declare_parameter(
            "tir_file",
            pn.default_tir_path(),
            _descriptor("shared .tir file (absolute, relative to cwd, or to config/)"),
        )
        self.declare_parameter(
            "effects_file",
            "",
            _descriptor("effects file of `tire-model diagnose` (hidden states; '' = none)"),
        )
        self.declare_parameter(
            "limits", True, _descriptor("saturate inputs to the file's limits, low-speed model")
        )
        self.declare_parameter(
            "pressure_is_absolute",
            False,
            _descriptor("P/pressure is absolute (gauge = value - ambient_pressure)"),
        )
        self.declare_parameter(
            "ambient_pressure",
            STANDARD_ATMOSPHERE_PA,
            _descriptor(
                "ambient pressure [Pa] for pressure_is_absolute",
                floating_point_range=[FloatingPointRange(from_value=0.0, to_value=2e5)],
            ),
        )
        self.declare_parameter(
            "missing_load",
            "nominal",
            _descriptor(
                "load missing or stale: 'nominal' = use FNOMIN, 'skip' = publish nothing",
                additional_constraints="one of: nominal, skip",
            ),
        )
        for name, value in pn.DEFAULT_TIMEOUTS.items():
            self.declare_parameter(
                f"timeout.{name}",
                value,
                _descriptor(
                    f"{name} older than this [s] -> nominal value; 0 = never stale",
                    floating_point_range=[nonneg],
                ),
            )
        self.declare_parameter(
            "diagnostics_period", 1.0, _descriptor("/diagnostics period [s]", read_only=True)
        )
        self.declare_parameter(
            "qos_depth", 100, _descriptor("depth of the reliable topic queues", read_only=True)
        )
        self.declare_parameter(
            "rt_priority",
            0,
            _descriptor(
                "SCHED_FIFO priority of the node's threads (1..99, needs root/CAP_SYS_NICE); "
                "0 = normal scheduling",
                read_only=True,
                integer_range=[IntegerRange(from_value=0, to_value=realtime.MAX_RT_PRIORITY)],
            ),
        )
        self.declare_parameter(
            "cpus",
            Parameter.Type.INTEGER_ARRAY,
            _descriptor("CPUs the node's threads may run on; unset = all", read_only=True),
        )

    def _declare_coefficients(
        self, slot: str, model: TireModel, overrides: bool
    ) -> dict[str, float]:
        """Declare one parameter per coefficient; returns values that overrides changed."""
        prefix = f"{slot}." if slot else ""
        changed: dict[str, float] = {}
        names = []
        for key, value in model.params.items():
            name = prefix + key
            got = self.declare_parameter(
                name, float(value), self._coef_descriptor(key, value), ignore_override=not overrides
            ).value
            names.append(name)
            if got != value:
                changed[key] = pn.coefficient_value(name, got)
        self._declared[slot] = names
        return changed

    @staticmethod
    def _coef_descriptor(key: str, value: float) -> ParameterDescriptor:
        d = _descriptor(pn.coefficient_description(key), dynamic_typing=True)
        d.type = ParameterType.PARAMETER_DOUBLE
        rng = pn.coefficient_range(key)
        if rng is not None and rng[0] <= value <= rng[1]:  # a file outside it keeps no range
            # Closed range for ROS; a strict minimum (e.g. FNOMIN > 0) is enforced on set.
            d.floating_point_range = [
                FloatingPointRange(from_value=rng[0], to_value=rng[1], step=0.0)
            ]
            d.additional_constraints = f"{'>' if rng[2] else '>='} {rng[0]:g}, <= {rng[1]:g}"
        return d

    def _load_initial_models(self) -> None:
        slot = Slot.load(self.get_parameter("tir_file").value)
        changed = self._declare_coefficients("", slot.model, overrides=True)
        self.slots[""] = self._with_updates(slot, changed)
        for w in self.wheels:
            value = self.declare_parameter(
                f"{w.key}.tir_file",
                "",
                _descriptor(f"own .tir of wheel {w.prefix} ('' = the shared tir_file)"),
            ).value
            if value:
                own = Slot.load(value)
                changed = self._declare_coefficients(w.key, own.model, overrides=True)
                self.slots[w.key] = self._with_updates(own, changed)
                w.slot = w.key
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
        self.limits = bool(g("limits").value)
        self.pressure_is_absolute = bool(g("pressure_is_absolute").value)
        self.ambient_pressure = float(g("ambient_pressure").value)
        policy = g("missing_load").value
        if policy not in pn.MISSING_LOAD_POLICIES:
            raise ValueError(f"missing_load: {policy!r} is not one of {pn.MISSING_LOAD_POLICIES}")
        self.skip_without_load = policy == "skip"
        self.timeouts = {k: float(g(f"timeout.{k}").value) for k in NODE_INPUTS}

    # ---------------------------------------------------------------- parameters: change
    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        if self._syncing:
            return SetParametersResult(successful=True)
        try:
            new_slots, redeclare = self._plan(params)
            settings = self._plan_settings(params)
            effects = [_load_effects(p.value) for p in params if p.name == "effects_file"]
        except (ValueError, OSError) as exc:  # TirError, EffectsError are ValueErrors
            return self._reject(str(exc))
        except Exception as exc:  # a bug in a model build must not stop the node
            return self._reject(f"{type(exc).__name__}: {exc}")
        # Commit: plain attribute swaps, nothing here can fail half-way.
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
        if effects:
            self._set_effects(effects[-1])
            self.reloads += 1
        self._redeclare |= redeclare
        if redeclare:
            self.reloads += 1
            loaded = ", ".join(f"{k or 'shared'}={slots[k].path}" for k in redeclare if k in slots)
            self.get_logger().info(f"model loaded: {loaded or 'wheels back on shared model'}")
        return SetParametersResult(successful=True)

    def _reject(self, reason: str) -> SetParametersResult:
        self.param_rejections += 1
        self.last_rejection = reason
        self.get_logger().warning(f"parameter change rejected (old model kept): {reason}")
        return _fail(reason)

    def _plan(self, params: list[Parameter]) -> tuple[dict[str, Slot | None], set[str]]:
        """New slots for the request: files loaded, coefficient updates applied."""
        files: dict[str, Slot | None] = {}
        coefs: dict[str, dict[str, float]] = {}
        for p in params:
            what = pn.classify(p.name, self._keys.values())
            if what.kind == "file":
                if not isinstance(p.value, str):
                    raise ValueError(f"{p.name}: expected a string path")
                if what.slot and p.value == "":
                    files[what.slot] = None  # back to the shared model
                else:
                    try:
                        files[what.slot] = Slot.load(p.value)
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
            try:
                out[slot] = Slot.with_model(
                    base.param_value, base.path, base.model.with_params(updates)
                )
            except ValueError as exc:
                raise ValueError(f"{base.path}: {exc}") from exc
        return out, set(files)

    def _plan_settings(self, params: list[Parameter]) -> dict[str, object]:
        """Validated node settings of the request (attribute name -> value)."""
        out: dict[str, object] = {}
        timeouts = dict(self.timeouts)
        for p in params:
            if p.name == "missing_load":
                if p.value not in pn.MISSING_LOAD_POLICIES:
                    raise ValueError(f"missing_load: {p.value!r} not in {pn.MISSING_LOAD_POLICIES}")
                out["skip_without_load"] = p.value == "skip"
            elif p.name in ("limits", "pressure_is_absolute"):
                if not isinstance(p.value, bool):
                    raise ValueError(f"{p.name}: expected a bool")
                out[p.name] = p.value
            elif p.name == "ambient_pressure":
                out["ambient_pressure"] = float(p.value)
            elif p.name.startswith("timeout."):
                timeouts[p.name.split(".", 1)[1]] = float(p.value)
                out["timeouts"] = timeouts
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
                if slot in self.slots:
                    self._declare_coefficients(slot, self.slots[slot].model, overrides=False)
        finally:
            self._syncing = False

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
        depth = int(self.get_parameter("qos_depth").value)
        qos = QoSProfile(
            depth=depth, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST
        )
        for w in self.wheels:
            pub = self.create_publisher(WrenchStamped, f"{w.prefix}/{FORCES}", qos)
            self.create_subscription(
                Vector3Stamped, f"{w.prefix}/slip", self._slip_cb(w, pub), qos, raw=True
            )
            for name, (msg_type, _, _) in INPUT_TOPICS.items():
                self.create_subscription(
                    msg_type, f"{w.prefix}/{name}", self._input_cb(w, name), qos, raw=True
                )

    def _slip_cb(self, w: WheelState, pub: Publisher) -> Callable[[bytes], None]:
        def on_slip(data: bytes) -> None:
            now = time.monotonic()
            parsed = cdr_fast.read_vector(data)
            if parsed is None:  # not CDR_LE: the general path
                msg = deserialize_message(data, Vector3Stamped)
                end, x, y, z = -1, msg.vector.x, msg.vector.y, msg.vector.z
                stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            else:
                end, x, y, z = parsed
                stamp = cdr_fast.read_stamp(data)
            slot = self.slots[w.slot]
            res, events = w.compute(
                x, y, z, now, slot.model, slot.nominal, self.timeouts, self.limits,
                self.skip_without_load, stamp,
            )  # fmt: skip
            if events:
                self._log_events(w, events, now)
            if res is None:
                return
            if end >= 0:
                pub.publish(cdr_fast.wrench_like(data, end, res))
                return
            out = WrenchStamped()
            out.header = msg.header  # same stamp (and frame) as the slip sample
            f, t = out.wrench.force, out.wrench.torque
            f.x, f.y, f.z, t.x, t.y, t.z = res
            pub.publish(out)

        return on_slip

    def _input_cb(self, w: WheelState, name: str) -> Callable[[bytes], None]:
        msg_type, index, field = INPUT_TOPICS[name]
        setter = getattr(w, f"set_{name}")
        absolute = name == "pressure"

        def cb(data: bytes) -> None:
            value = cdr_fast.read_double(data, index)
            if value is None:  # not CDR_LE: the general path
                value = float(attrgetter(field)(deserialize_message(data, msg_type)))
            if absolute and self.pressure_is_absolute:
                value -= self.ambient_pressure
            rejection = setter(value, time.monotonic())
            if rejection is not None:
                self._log_events(w, [f"input_rejected: {rejection}"], time.monotonic())

        return cb

    def _log_events(self, w: WheelState, events: list[str], now: float) -> None:
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
        now = time.monotonic()
        for w in self.wheels:
            arr.status.append(self._wheel_status(w, now))
        self._diag_pub.publish(arr)

    def _model_status(self) -> DiagnosticStatus:
        st = DiagnosticStatus(
            name=f"{self.get_name()}: model", hardware_id=self.get_fully_qualified_name()
        )
        st.level = DiagnosticStatus.OK
        st.message = f"{len(self.slots)} model(s) loaded"
        values = {f"tir_file{'.' + k if k else ''}": s.path for k, s in self.slots.items()}
        values.update(
            {
                "effects_file": str(self.get_parameter("effects_file").value),
                "limits": str(self.limits),
                "reloads": str(self.reloads),
                "parameter_rejections": str(self.param_rejections),
                "last_rejection": self.last_rejection,
            }
        )
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        return st

    def _wheel_status(self, w: WheelState, now: float) -> DiagnosticStatus:
        counts = w.counters()
        last = self._diag_last.get(w.key, {})
        delta = {k: v - last.get(k, 0) for k, v in counts.items()}
        self._diag_last[w.key] = counts
        lost = [
            k
            for k in ("slip_rejected", "skipped_no_load", "output_nonfinite", "model_errors")
            if delta[k]
        ]
        warn = [
            k
            for k, d in delta.items()
            if d and (k.endswith((".rejected", ".stale")) or k == "fallback.load.never")
        ]
        st = DiagnosticStatus(name=f"{self.get_name()}: {w.prefix}", hardware_id=w.prefix)
        if lost and delta["forces_out"] == 0:
            st.level = DiagnosticStatus.ERROR
        elif lost or warn:
            st.level = DiagnosticStatus.WARN
        else:
            st.level = DiagnosticStatus.OK
        parts = [f"{k} +{delta[k]}" for k in lost + warn]
        st.message = "; ".join(parts) if parts else "ok"
        values = {"tir_file": self.slots[w.slot].path, **{k: str(v) for k, v in counts.items()}}
        for name in NODE_INPUTS:
            ch = getattr(w, name)
            values[f"{name}.value"] = "never received" if ch.value is None else repr(ch.value)
            values[f"{name}.age_s"] = "" if ch.value is None else f"{now - ch.t_rx:.3f}"
        if w.effects is not None:  # the hidden states, as an engineer would watch them
            values["effects.tread_C"] = f"{w.effects.temperature_C:.2f}"
            values.update({f"effects.{k}": f"{v:.4g}" for k, v in w.effects.y.items()})
        if w.last_error:
            values["last_model_error"] = w.last_error
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        return st


def make_executor(kind: str | None = None) -> Executor:
    """EventsExecutor (default, ~2.5x the callback rate here) or SingleThreadedExecutor.

    ``TIRE_MODEL_EXECUTOR=single`` selects the single-threaded one (for comparisons).
    """
    kind = kind or os.environ.get("TIRE_MODEL_EXECUTOR", "events")
    if kind == "single":
        return SingleThreadedExecutor()
    from rclpy.experimental import EventsExecutor

    return EventsExecutor()


def spin(executor: Executor) -> None:
    """Spin until the context shuts down (SIGINT/SIGTERM: rclpy's handlers shut it down).

    EventsExecutor.spin() does not return on that shutdown here (it keeps a core busy), so it
    is driven by spin_once with a timeout, which checks the context between events.
    """
    if isinstance(executor, SingleThreadedExecutor):
        executor.spin()
        return
    while rclpy.ok():
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


def main(args: list[str] | None = None) -> int:
    """Console entry point: run the node until SIGINT/SIGTERM; the exit status."""
    rclpy.init(args=args)
    node = None
    code = 0
    try:
        node = TireModelNode()
        executor = make_executor()
        executor.add_node(node)
        tune_process(node)
        spin(executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (
        ValueError,
        OSError,
        rclpy.exceptions.ParameterException,
        rclpy.exceptions.NameValidationException,
    ) as exc:
        print(f"{NODE_NAME}: error: {exc}", file=sys.stderr)
        code = 1
    finally:
        with deadline():
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
    return code


if __name__ == "__main__":
    sys.exit(main())
