"""Writing recordings (rosbag2 bags), atomically: whole wheels, decoded topics, or a stream.

Written: rosbag2 version 9 folders (MCAP by default, sqlite3 on request), or a lone ``.mcap`` /
``.db3`` file when the target path has that suffix. MCAP with the vectorised writer of
``mcap_write`` (+ metadata.yaml version 9), sqlite3 through rosbags' Writer, streaming
(``BagWriter``) through the storages of ``streams`` (MCAP: this package's streaming writer);
always into a temp folder beside the target, then renamed. ``write_recording`` uses a wheel's
``meta["t_ns"]`` when it still matches ``t``, so a read/write round trip keeps stamps to the
nanosecond.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import TracebackType

import numpy as np
import numpy.typing as npt

from tire_model_ros.atomic import replace_path
from tire_model_ros.recording import cdr
from tire_model_ros.recording.mcap_write import CHUNK_BYTES, Batch, write_mcap
from tire_model_ros.recording.metadata import TopicStats, rosbag2_metadata
from tire_model_ros.recording.raw import storage_of
from tire_model_ros.recording.series import WheelSeries
from tire_model_ros.recording.streams import STORAGES
from tire_model_ros.vocabulary import (
    FLUID_PRESSURE,
    NS_PER_S,
    OPTIONAL_CHANNELS,
    TEMPERATURE,
    TWIST_STAMPED,
    VECTOR3_STAMPED,
    WRENCH_STAMPED,
)


def _stamps_ns(w: WheelSeries) -> np.ndarray:
    """Exact slip stamps [ns]: ``meta["t_ns"]`` if it still matches ``t``, else from ``t``."""
    t_ns = w.meta.get("t_ns") if isinstance(w.meta, dict) else None
    if t_ns is not None and len(t_ns) == len(w.t):
        t_ns = np.asarray(t_ns, np.int64)
        if np.all(np.abs(t_ns / NS_PER_S - w.t) <= 1e-6):
            return t_ns
    return np.round(np.asarray(w.t) * NS_PER_S).astype(np.int64)


def decimate_mask(t_ns: np.ndarray, rate_hz: float | None) -> np.ndarray:
    """Samples to keep so a channel is logged at most at ``rate_hz``: the first of each period."""
    if rate_hz is None:
        return np.ones(len(t_ns), bool)
    if not rate_hz > 0 or not np.isfinite(rate_hz):
        raise ValueError(f"channel rate must be a positive number of Hz, got {rate_hz}")
    if len(t_ns) == 0:
        return np.ones(0, bool)
    period = (t_ns - t_ns[0]) // round(NS_PER_S / rate_hz)
    mask = np.ones(len(t_ns), bool)
    mask[1:] = period[1:] != period[:-1]
    return mask


def _wheel_channels(w: WheelSeries) -> dict[str, tuple[str, np.ndarray]]:
    """channel -> (type, (n, k) values) of the topics a wheel writes (None channels skipped)."""
    n = len(w)
    zeros = np.zeros(n)
    out = {
        "slip": (VECTOR3_STAMPED, np.column_stack([w.kappa, w.alpha, w.gamma])),
        "load": (WRENCH_STAMPED, np.column_stack([zeros, zeros, w.Fz, zeros, zeros, zeros])),
    }
    if w.p is not None:
        out["pressure"] = (FLUID_PRESSURE, np.column_stack([w.p, zeros]))
    if w.T is not None:
        out["temperature"] = (TEMPERATURE, np.column_stack([w.T, zeros]))
    if w.Vx is not None:
        twist = np.column_stack([w.Vx, zeros, zeros, zeros, zeros, zeros])
        out["velocity"] = (TWIST_STAMPED, twist)
    Fz = w.Fz_meas if w.Fz_meas is not None else w.Fz
    forces = [w.Fx, w.Fy, Fz, w.Mx, w.My, w.Mz]
    if any(f is not None for f in (w.Fx, w.Fy, w.Mx, w.My, w.Mz, w.Fz_meas)):
        cols = [f if f is not None else np.full(n, np.nan) for f in forces]
        out["measured_forces"] = (WRENCH_STAMPED, np.column_stack(cols))
    return out


class BagWriter:
    """Streams messages into a new bag, atomically: a temp folder beside ``path``, renamed on
    ``close()``; ``abort()`` (or an exception inside ``with``) leaves ``path`` untouched.

    ``path`` with a ``.mcap`` / ``.db3`` suffix becomes a lone storage file, else a rosbag2
    folder (metadata.yaml version 9). The storage (``streams.STORAGES``) keeps what was written
    safe from a SIGKILL up to its last flush period if ``flush_due()`` is called often: the temp
    folder ``.<name>.<random>.tmp`` then holds a bag folder that ``read_raw(...,
    salvage=True)`` reads (given the temp folder, or ``path`` itself).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        overwrite: bool = False,
        storage: str = "mcap",
        chunk_bytes: int = CHUNK_BYTES,
    ) -> None:
        self.path = Path(path)
        self.lone = self.path.suffix in (".mcap", ".db3")
        self.storage = storage_of(self.path) if self.lone else storage
        if self.storage not in STORAGES:
            raise ValueError(f"storage must be 'mcap' or 'sqlite3', got {self.storage!r}")
        if (self.path.exists() or self.path.is_symlink()) and not overwrite:
            raise FileExistsError(f"{self.path}: exists already (use overwrite=True / --force)")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.tmpdir = Path(
            tempfile.mkdtemp(prefix=f".{self.path.name}.", suffix=".tmp", dir=self.path.parent)
        )
        self.bag = self.tmpdir / (self.path.stem if self.lone else self.path.name)
        self.topics: dict[str, tuple[str, list[int]]] = {}  # type, [count, first, last]
        self.closed = False
        try:
            self.out = STORAGES[self.storage](self.bag, chunk_bytes)
        except BaseException:
            shutil.rmtree(self.tmpdir, ignore_errors=True)
            raise

    @property
    def counts(self) -> dict[str, int]:
        """Messages written per topic."""
        return {t: stats[0] for t, (_, stats) in self.topics.items()}

    def add_topic(self, topic: str, msgtype: str, msgdef: str | None = None) -> None:
        """Declare a topic (once). ``msgdef``: the type's definition text (ros2msg); default
        from the ROS 2 Jazzy typestore, which must then hold the type."""
        if topic in self.topics:
            raise ValueError(f"topic {topic} added twice")
        if msgdef is None:
            msgdef = cdr.typestore().generate_msgdef(msgtype, ros_version=2)[0]
        self.out.add_topic(topic, msgtype, msgdef)
        self.topics[topic] = (msgtype, [0, 0, 0])

    def write(self, topic: str, log_ns: int, data: bytes | memoryview) -> None:
        """One message: CDR bytes, log time [ns] (this package uses the header stamp)."""
        log_ns = int(log_ns)
        self.out.write(topic, log_ns, data)
        stats = self.topics[topic][1]
        stats[1] = min(stats[1], log_ns) if stats[0] else log_ns
        stats[2] = max(stats[2], log_ns)
        stats[0] += 1

    def flush_due(self) -> None:
        """Put what was written on disk if the storage's flush period has passed (call it
        often, e.g. from a spin loop: messages alone flush only while they come)."""
        self.out.flush_due()

    def close(self) -> None:
        """Finish the bag and move it to ``path`` (replacing it if allowed at creation)."""
        if self.closed:
            return
        self.closed = True
        try:
            self.out.close([TopicStats(t, mt, *st) for t, (mt, st) in self.topics.items()])
            replace_path(self.out.file if self.lone else self.bag, self.path)
        finally:
            shutil.rmtree(self.tmpdir, ignore_errors=True)

    def abort(self) -> None:
        """Drop everything written; ``path`` is left as it was."""
        if self.closed:
            return
        self.closed = True
        with contextlib.suppress(Exception):  # the temp folder is removed anyway
            self.out.abort()
        shutil.rmtree(self.tmpdir, ignore_errors=True)

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def write_topics(
    path: str | os.PathLike[str],
    topics: Mapping[str, tuple[str, np.ndarray, np.ndarray]],
    *,
    overwrite: bool = False,
    storage: str = "mcap",
    slip_last: bool = True,
) -> None:
    """Write decoded topics: ``{topic: (msgtype, stamp_ns, values (n, k))}``, log time = stamp.

    Messages go in stamp order; at equal stamps ``*/slip`` comes after the other topics (what a
    rig driver publishes first), then the order of ``topics``. MCAP is written by the
    vectorised writer of ``mcap_write``; sqlite3 through rosbags.
    """
    path = Path(path)
    ts = cdr.typestore()
    batches = []
    for topic, (msgtype, stamp_ns, values) in topics.items():
        stamps = np.asarray(stamp_ns, np.int64)
        msgdef = ts.generate_msgdef(msgtype, ros_version=2)[0]
        rows = cdr.encode_array(msgtype, stamps, values)
        batches.append(Batch(topic, msgtype, msgdef, "[]", stamps, rows))
    conn_idx = np.concatenate([np.full(len(b.log_ns), i) for i, b in enumerate(batches)])
    msg_idx = np.concatenate([np.arange(len(b.log_ns)) for b in batches])
    stamps = np.concatenate([b.log_ns for b in batches])
    prio = np.concatenate(
        [np.full(len(b.log_ns), int(slip_last and b.topic.endswith("/slip"))) for b in batches]
    )
    order = np.lexsort((conn_idx, prio, stamps))
    lone = path.suffix in (".mcap", ".db3")
    if (storage_of(path) if lone else storage) == "mcap":
        _write_fast_mcap(path, batches, (conn_idx[order], msg_idx[order]), overwrite)
        return
    with BagWriter(path, overwrite=overwrite, storage=storage) as writer:
        for b in batches:
            writer.add_topic(b.topic, b.msgtype)
        for c, m in zip(conn_idx[order].tolist(), msg_idx[order].tolist(), strict=True):
            b = batches[c]
            writer.write(b.topic, int(b.log_ns[m]), b.rows[m].tobytes())


def _stats(b: Batch) -> TopicStats:
    n = len(b.log_ns)
    first, last = (int(b.log_ns.min()), int(b.log_ns.max())) if n else (0, 0)
    return TopicStats(b.topic, b.msgtype, n, first, last)


def _write_fast_mcap(
    path: Path,
    batches: Sequence[Batch],
    order: tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]],
    overwrite: bool,
) -> None:
    import yaml

    if (path.exists() or path.is_symlink()) and not overwrite:
        raise FileExistsError(f"{path}: exists already (use overwrite=True / --force)")
    lone = path.suffix == ".mcap"
    file_name = path.name if lone else f"{path.name}.mcap"
    info = rosbag2_metadata(file_name, [_stats(b) for b in batches])
    path.parent.mkdir(parents=True, exist_ok=True)
    tmpdir = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    try:
        new = tmpdir / path.name
        if not lone:
            new.mkdir()
        target = new if lone else new / file_name
        write_mcap(target, batches, order, yaml.safe_dump(info, sort_keys=False).strip())
        if not lone:
            text = yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False)
            (new / "metadata.yaml").write_text(text)
        replace_path(new, path)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)


def _check_wheels(wheels: Sequence[WheelSeries]) -> None:
    seen = set()
    for w in wheels:
        if not isinstance(w, WheelSeries):
            raise ValueError(f"write_recording: expected WheelSeries, got {type(w).__name__}")
        if w.prefix in seen:
            raise ValueError(f"write_recording: wheel prefix {w.prefix!r} given twice")
        if (w.prefix and not w.prefix.startswith("/")) or w.prefix.endswith("/"):
            raise ValueError(
                f"write_recording: prefix {w.prefix!r} must start with '/' and not end with '/'"
            )
        if len(w) == 0:
            raise ValueError(f"write_recording: wheel {w.prefix!r} has no samples")
        if not np.all(np.isfinite(w.t)):
            raise ValueError(f"write_recording: wheel {w.prefix!r}: t has non-finite values")
        seen.add(w.prefix)
    if not wheels:
        raise ValueError("write_recording: no wheels to write")


def write_recording(
    path: str | os.PathLike[str],
    wheels: Sequence[WheelSeries],
    *,
    overwrite: bool = False,
    storage: str = "mcap",
    rates: Mapping[str, float] | None = None,
) -> None:
    """Write wheels as a rosbag2 recording with the INTERFACE.md topics.

    Parameters
    ----------
    path : target. A ``.mcap`` / ``.db3`` suffix writes a lone storage file, anything else a
        rosbag2 folder (metadata.yaml version 9 + ``<name>.mcap`` / ``.db3``).
    wheels : one WheelSeries per wheel; ``header.stamp`` = log time = ``t``. Channels that are
        None are not written; measured_forces from Fx, Fy, Fz_meas (else Fz), Mx, My, Mz
        (written if any of them is given; a missing component is NaN).
    overwrite : replace an existing ``path`` (otherwise FileExistsError).
    storage : "mcap" (default) or "sqlite3". A lone-file suffix decides by itself.
    rates : channel -> maximum logging rate [Hz], e.g. ``{"pressure": 10, "temperature": 10}``
        (channels: load, pressure, temperature, velocity, measured_forces; slip is never
        decimated): the first sample of each 1/rate period is written.

    The bag is written into a temporary folder beside ``path`` and renamed into place.
    """
    rates = dict(rates or {})
    if unknown := set(rates) - {"load", *OPTIONAL_CHANNELS, "measured_forces"}:
        raise ValueError(
            f"write_recording: rates for unknown channel(s) {sorted(unknown)} (slip is never "
            "decimated; channels: load, pressure, temperature, velocity, measured_forces)"
        )
    _check_wheels(wheels)
    topics = {}
    for w in wheels:
        t_ns = _stamps_ns(w)
        for channel, (msgtype, values) in _wheel_channels(w).items():
            keep = decimate_mask(t_ns, rates.get(channel))
            topics[f"{w.prefix}/{channel}"] = (msgtype, t_ns[keep], values[keep])
    write_topics(path, topics, overwrite=overwrite, storage=storage)
