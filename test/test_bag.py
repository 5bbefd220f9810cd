"""Recordings: write/read round trips, alignment rules, CDR decoding, real rosbag2 metadata
formats, the QoS pitfall, and every RecordingError. Real bags on disk, no mocks."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from series_util import NS, T0, assert_same, random_wheel

from tire_model_ros.recording import (
    RecordingError,
    WheelSeries,
    cdr,
    read_raw,
    read_recording,
    write_recording,
    write_topics,
)
from tire_model_ros.vocabulary import (
    FLUID_PRESSURE,
    TEMPERATURE,
    TWIST_STAMPED,
    VECTOR3_STAMPED,
    WRENCH_STAMPED,
)


def wheel(prefix="/rig/wheel", n=200, **kwargs) -> WheelSeries:
    return random_wheel(prefix, n, **kwargs)


# ----------------------------------------------------------------------------- round trips


@pytest.mark.parametrize(
    "name,storage",
    [("bag", "mcap"), ("bag", "sqlite3"), ("lone.mcap", "mcap"), ("lone.db3", "mcap")],
)
def test_round_trip(tmp_path, name, storage):
    wheels = [wheel("/car/fl", seed=1), wheel("/car/fr", seed=2, T=False, Vx=False)]
    path = tmp_path / name
    write_recording(path, wheels, storage=storage)
    assert path.is_dir() == ("." not in name)
    assert [p.name for p in tmp_path.iterdir()] == [name], "temp folder left behind"
    got = read_recording(path)
    assert sorted(got) == ["/car/fl", "/car/fr"]
    for w in wheels:
        assert_same(got[w.prefix], w)
        assert got[w.prefix].meta["storage"] == ("sqlite3" if name.endswith(".db3") else storage)
    assert got["/car/fr"].T is None and got["/car/fr"].Vx is None
    # Written again from what was read: identical, stamps to the nanosecond.
    write_recording(path, list(got.values()), overwrite=True, storage=storage)
    again = read_recording(path)
    for w in got.values():
        assert_same(again[w.prefix], w)
        np.testing.assert_array_equal(again[w.prefix].t, w.t)


def test_none_channels_are_not_written(tmp_path):
    w = wheel(p=False, T=False, Vx=False)
    write_recording(tmp_path / "b", [w])
    raw = read_raw(tmp_path / "b")
    assert sorted(raw.all_topics) == [
        "/rig/wheel/load",
        "/rig/wheel/measured_forces",
        "/rig/wheel/slip",
    ]
    got = read_recording(tmp_path / "b")["/rig/wheel"]
    assert got.p is None and got.T is None and got.Vx is None


def test_measured_forces_fz_falls_back_to_load(tmp_path):
    w = wheel()
    w.Fz_meas = None
    write_recording(tmp_path / "b", [w])
    got = read_recording(tmp_path / "b")["/rig/wheel"]
    np.testing.assert_array_equal(got.Fz_meas, w.Fz)


def test_mcap_package_reads_what_we_write(tmp_path):
    from mcap.reader import make_reader

    w = wheel(n=50)
    write_recording(tmp_path / "b", [w], rates={"temperature": 100})
    counts: dict[str, int] = {}
    schemas: dict[str, str] = {}
    with open(tmp_path / "b" / "b.mcap", "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        for schema, channel, message in reader.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            schemas[channel.topic] = schema.name
            assert channel.message_encoding == "cdr" and schema.encoding == "ros2msg"
            assert (
                message.log_time
                == cdr.header_stamps(np.frombuffer(message.data, np.uint8), np.array([0]))[0]
            )
    n_temp = len(np.unique((w.meta["t_ns"] - w.meta["t_ns"][0]) // (NS // 100)))
    assert counts == {
        "/rig/wheel/slip": 50,
        "/rig/wheel/load": 50,
        "/rig/wheel/pressure": 50,
        "/rig/wheel/temperature": n_temp,
        "/rig/wheel/velocity": 50,
        "/rig/wheel/measured_forces": 50,
    }
    assert 1 < n_temp < 50
    assert schemas == {
        "/rig/wheel/slip": VECTOR3_STAMPED,
        "/rig/wheel/load": WRENCH_STAMPED,
        "/rig/wheel/pressure": FLUID_PRESSURE,
        "/rig/wheel/temperature": TEMPERATURE,
        "/rig/wheel/velocity": TWIST_STAMPED,
        "/rig/wheel/measured_forces": WRENCH_STAMPED,
    }


def test_decimated_channels_read_back_as_zero_order_hold(tmp_path):
    n = 1000  # 1 kHz slip, 1 s
    w = wheel(n=n)
    write_recording(tmp_path / "b", [w], rates={"pressure": 10, "temperature": 2.5})
    raw = read_raw(tmp_path / "b")
    assert len(raw.topics["/rig/wheel/pressure"]) == 10
    assert len(raw.topics["/rig/wheel/temperature"]) == 3
    got = read_recording(tmp_path / "b")["/rig/wheel"]
    period = (w.meta["t_ns"] - w.meta["t_ns"][0]) // (NS // 10)
    first = np.searchsorted(period, period)  # index of the first sample of each period
    np.testing.assert_array_equal(got.p, w.p[first])
    np.testing.assert_array_equal(got.Fz, w.Fz)
    with pytest.raises(ValueError, match="unknown channel"):
        write_recording(tmp_path / "c", [w], rates={"slip": 10})
    with pytest.raises(ValueError, match="positive"):
        write_recording(tmp_path / "c", [w], rates={"pressure": -1})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b"], "failed write left files"


def test_write_refuses_existing_path_and_is_atomic(tmp_path):
    w = wheel(n=20)
    write_recording(tmp_path / "b", [w])
    before = sorted(os.listdir(tmp_path / "b"))
    with pytest.raises(FileExistsError, match="exists"):
        write_recording(tmp_path / "b", [w])
    (tmp_path / "x.mcap").write_text("keep me")
    with pytest.raises(FileExistsError):
        write_recording(tmp_path / "x.mcap", [w])
    assert (tmp_path / "x.mcap").read_text() == "keep me"
    assert sorted(os.listdir(tmp_path / "b")) == before
    w2 = wheel(n=30, seed=5)
    write_recording(tmp_path / "b", [w2], overwrite=True)
    assert len(read_recording(tmp_path / "b")["/rig/wheel"]) == 30
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b", "x.mcap"]
    with pytest.raises(ValueError, match="given twice"):
        write_recording(tmp_path / "c", [w, w])
    with pytest.raises(ValueError, match="no samples"):
        write_recording(tmp_path / "c", [wheel(n=0)])


# ----------------------------------------------------------------------------- alignment


def ns(seconds: float) -> int:
    return T0 + round(seconds * NS)


def wrench(fz=None, fx=None):
    n = len(fz if fz is not None else fx)
    out = np.zeros((n, 6))
    if fz is not None:
        out[:, 2] = fz
    if fx is not None:
        out[:, 0] = fx
    return out


def write_raw_bag(path, topics, storage="mcap"):
    """Topics written in the given (bag) order with log time = header stamp + a lag that
    reverses their log order, so a reader that used log times would align differently."""
    from tire_model_ros.recording import BagWriter

    with BagWriter(path, storage=storage) as writer:
        for topic, (msgtype, _, _) in topics.items():
            writer.add_topic(topic, msgtype)
        for topic, (msgtype, stamps, values) in topics.items():
            data = cdr.encode(msgtype, np.array(stamps, np.int64), values)
            for i, (s, d) in enumerate(zip(stamps, data, strict=True)):
                writer.write(topic, s + (len(stamps) - i) * NS, d)


def alignment_topics():
    P = "/w"
    slip_t = [1.3, 1.0, 1.2, 1.4, 1.1]  # bag order is not stamp order
    slip = np.array([[t, -t, 0.01] for t in slip_t])
    return {
        f"{P}/slip": (VECTOR3_STAMPED, [ns(t) for t in slip_t], slip),
        f"{P}/load": (WRENCH_STAMPED, [ns(1.05), ns(1.1), ns(1.25)], wrench([100, 200, 300])),
        f"{P}/pressure": (FLUID_PRESSURE, [ns(1.15), ns(1.35)], np.array([[1e5, 0], [2e5, 0]])),
        # two velocity messages with the same stamp: the one logged later wins (write_raw_bag
        # gives the first written the later log time)
        f"{P}/velocity": (
            TWIST_STAMPED,
            [ns(1.1), ns(1.1), ns(0.5)],
            np.array([[5.0, 0, 0, 0, 0, 0], [6.0, 0, 0, 0, 0, 0], [4.0, 0, 0, 0, 0, 0]]),
        ),
        f"{P}/temperature": (TEMPERATURE, [], np.zeros((0, 2))),  # topic without messages
        f"{P}/measured_forces": (
            WRENCH_STAMPED,
            [ns(1.5), ns(1.1), ns(1.18), ns(1.22), ns(1.32)],
            wrench(fx=[50, 10, 20, 30, 40]),
        ),
        "/other/topic": (VECTOR3_STAMPED, [ns(1.0)], np.zeros((1, 3))),
    }


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_alignment_rules(tmp_path, storage):
    write_raw_bag(tmp_path / "b", alignment_topics(), storage)
    got = read_recording(tmp_path / "b")
    assert list(got) == ["/w"]
    w = got["/w"]
    # slip at 1.0 has no load at or before it: dropped (and counted)
    assert w.meta["dropped_no_load"] == 1 and w.meta["n_slip"] == 5
    np.testing.assert_array_equal(w.meta["t_ns"], [ns(1.1), ns(1.2), ns(1.3), ns(1.4)])
    np.testing.assert_allclose(w.kappa, [1.1, 1.2, 1.3, 1.4])
    np.testing.assert_allclose(w.alpha, [-1.1, -1.2, -1.3, -1.4])
    # latest at or before (inclusive at 1.1)
    np.testing.assert_array_equal(w.Fz, [200, 200, 300, 300])
    # pressure starts at 1.15: the sample at 1.1 takes its first value
    np.testing.assert_array_equal(w.p, [1e5, 1e5, 1e5, 2e5])
    assert w.meta["backfilled"] == {"p": 1, "Vx": 0}
    np.testing.assert_array_equal(w.Vx, [5.0, 5.0, 5.0, 5.0])
    assert w.T is None  # topic present, no messages
    # measured_forces: exact 1.1; 1.2 is a tie 1.18/1.22 -> the earlier; 1.3 -> 1.32;
    # 1.4 -> 1.32 (0.08 s) not 1.5 (0.1 s)
    np.testing.assert_array_equal(w.Fx, [10, 20, 40, 40])
    assert w.meta["forces_exact"] == 1
    assert w.meta["forces_max_dt_s"] == pytest.approx(0.08)


# ----------------------------------------------------------------------------- CDR


@pytest.mark.parametrize("msgtype", sorted(cdr.LAYOUTS))
def test_numpy_cdr_matches_rosbags(msgtype):
    """The vectorised decoder against rosbags' deserialiser (the reference), with frame_id
    lengths 0..12 (every alignment), big-endian messages, and encode == serialize_cdr."""
    ts = cdr.typestore()
    rng = np.random.default_rng(3)
    k = len(cdr.LAYOUTS[msgtype])
    raw, want_stamp, want_vals = [], [], []
    for i in range(26):
        frame = "f" * (i % 13)
        stamp = int(rng.integers(-(2**31), 2**31 - 1)) * NS + int(rng.integers(0, NS))
        vals = rng.normal(size=k)
        data = cdr.encode(msgtype, np.array([stamp]), vals[None], frame_id=frame)[0]
        ref_stamp, ref_vals = cdr.decode_reference(msgtype, data)
        assert ref_stamp == stamp
        np.testing.assert_array_equal(ref_vals, vals)
        msg = ts.deserialize_cdr(bytes(data), msgtype)
        assert bytes(ts.serialize_cdr(msg, msgtype)) == bytes(data)
        if i % 5 == 4:  # big-endian: the fixed layout does not apply, rosbags decodes it
            data = ts.serialize_cdr(msg, msgtype, little_endian=False)
        raw.append(bytes(data))
        want_stamp.append(stamp)
        want_vals.append(vals)
    stamp, values = cdr.decode(msgtype, *cdr.join(raw))
    np.testing.assert_array_equal(stamp, want_stamp)
    np.testing.assert_array_equal(values, np.array(want_vals))


def test_damaged_message_names_topic(tmp_path):
    """A message stored whole (every CRC holds) whose CDR bytes are wrong: the decoder names
    the topic. (Bytes damaged in the file itself are a CRC mismatch: test_bag_trust.)"""
    from tire_model_ros.recording import BagWriter

    w = wheel(n=10)
    write_recording(tmp_path / "b.mcap", [w])
    raw = read_raw(tmp_path / "b.mcap")
    with BagWriter(tmp_path / "c.mcap") as writer:
        for topic, t in raw.topics.items():
            writer.add_topic(topic, t.msgtype)
            for i in range(len(t)):
                data = bytearray(t.message(i))
                if topic == "/rig/wheel/load" and i == 0:
                    # frame_id length -> huge: neither decoder can read it
                    data[12:16] = (10**6).to_bytes(4, "little")
                writer.write(topic, int(t.log_ns[i]), bytes(data))
    with pytest.raises(RecordingError, match=r"c\.mcap: topic /rig/wheel/load: corrupted"):
        read_recording(tmp_path / "c.mcap")


# ----------------------------------------------------------------------------- QoS pitfall

OTHER_QOS = [
    {
        "history": "keep_last",
        "depth": 7,
        "reliability": "best_effort",
        "durability": "volatile",
        "deadline": {"sec": 9223372036, "nsec": 854775807},
        "lifespan": {"sec": 9223372036, "nsec": 854775807},
        "liveliness": "automatic",
        "liveliness_lease_duration": {"sec": 9223372036, "nsec": 854775807},
        "avoid_ros_namespace_conventions": False,
    }
]


def set_metadata_qos(bag: Path, qos) -> None:
    meta_path = bag / "metadata.yaml"
    meta = yaml.safe_load(meta_path.read_text())
    for t in meta["rosbag2_bagfile_information"]["topics_with_message_count"]:
        t["topic_metadata"]["offered_qos_profiles"] = qos
    meta_path.write_text(yaml.safe_dump(meta))


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_metadata_qos_differs_from_storage(tmp_path, storage):
    from rosbags.rosbag2 import Reader

    w = wheel(n=100)
    write_recording(tmp_path / "b", [w], storage=storage)
    set_metadata_qos(tmp_path / "b", OTHER_QOS)
    with Reader(tmp_path / "b") as reader:  # the pitfall itself: rosbags yields nothing
        assert reader.message_count == 600
        assert sum(1 for _ in reader.messages()) == 0
    got = read_recording(tmp_path / "b")["/rig/wheel"]
    assert_same(got, w)
    assert got.meta["messages_read"] == 600
    # sqlite3 goes through rosbags and needs the fallback; MCAP is read by its own index
    assert got.meta["reader_fallback"] == (storage == "sqlite3")


# ----------------------------------------------------------------------------- real formats
# metadata.yaml texts of the rosbag2 project's own test bags (github.com/ros2/rosbag2,
# Apache-2.0), verbatim but for the topic list, file names, counts and times, which are
# replaced by those of the bag written here. The binary .mcap/.db3 fixtures are not available
# here (only text is stored), so the storage files are ours. Their QoS strings differ from the
# storage file's, which exercises the QoS pitfall on every one.

QOS_STR = (
    "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: 0\n"
    "    nsec: 0\n  lifespan:\n    sec: 0\n    nsec: 0\n  liveliness: 1\n"
    "  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n"
    "  avoid_ros_namespace_conventions: false"
)
# rosbag2_py/test/resources/mcap/talker/metadata.yaml (version 4, ROS 2 Foxy)
V4 = {
    "version": 4,
    "compression_format": "",
    "compression_mode": "",
    "topic": {"offered_qos_profiles": QOS_STR},
}
# rosbag2_transport/test/resources/mcap/test_bag_for_seek/metadata.yaml (version 6)
V6 = {
    "version": 6,
    "compression_format": "",
    "compression_mode": "",
    "custom_data": None,
    "topic": {"offered_qos_profiles": ""},
    "files": True,
}
# rosbag2_tests/resources/mcap/cdr_test/metadata.yaml (version 7)
V7 = {
    "version": 7,
    "compression_format": "",
    "compression_mode": "",
    "custom_data": None,
    "topic": {
        "offered_qos_profiles": QOS_STR.replace("depth: 0", "depth: 4"),
        "type_description_hash": "",
    },
    "files": True,
}
# rosbag2_tests/resources/mcap/bag_with_topics_and_service_events/metadata.yaml (version 8)
V8 = {
    "version": 8,
    "compression_format": "",
    "compression_mode": "",
    "custom_data": None,
    "ros_distro": "",
    "topic": {"offered_qos_profiles": QOS_STR, "hash": True},
    "files": True,
}
# version 9 as written by rosbag2 on Jazzy: QoS as a YAML list with named enums
V9 = {
    "version": 9,
    "compression_format": "",
    "compression_mode": "",
    "custom_data": None,
    "ros_distro": "jazzy",
    "topic": {"offered_qos_profiles": OTHER_QOS, "hash": True},
    "files": True,
}


def rewrite_metadata(bag: Path, spec: dict) -> None:
    """Replace a bag's metadata.yaml by one in the format of ``spec``, same topics/counts."""
    ours = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    info = {k: spec[k] for k in spec if k not in ("topic", "files")}
    info.update(
        storage_identifier=ours["storage_identifier"],
        duration=ours["duration"],
        starting_time=ours["starting_time"],
        message_count=ours["message_count"],
        relative_file_paths=ours["relative_file_paths"],
    )
    topics = []
    for t in ours["topics_with_message_count"]:
        md = {
            "name": t["topic_metadata"]["name"],
            "type": t["topic_metadata"]["type"],
            "serialization_format": "cdr",
            "offered_qos_profiles": spec["topic"]["offered_qos_profiles"],
        }
        if "type_description_hash" in spec["topic"]:
            md["type_description_hash"] = spec["topic"]["type_description_hash"]
        if spec["topic"].get("hash"):
            md["type_description_hash"] = t["topic_metadata"]["type_description_hash"]
        topics.append({"topic_metadata": md, "message_count": t["message_count"]})
    info["topics_with_message_count"] = topics
    if spec.get("files"):
        info["files"] = ours["files"]
    (bag / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}))


@pytest.mark.parametrize("spec", [V4, V6, V7, V8, V9], ids=["v4", "v6", "v7", "v8", "v9"])
@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_real_rosbag2_metadata_versions(tmp_path, spec, storage):
    w = wheel(n=40)
    write_recording(tmp_path / "b", [w], storage=storage)
    rewrite_metadata(tmp_path / "b", spec)
    assert_same(read_recording(tmp_path / "b")["/rig/wheel"], w)


# rosbag2_tests/resources/test/metadata.yaml (the oldest format: topic_and_type), verbatim
V1_TEXT = """rosbag2_bagfile_information:
  storage_identifier: sqlite3
  encoding: cdr
  relative_file_paths:
    - test.db3
  combined_bag_size: 0
  duration:
    nanoseconds: 155979811
  starting_time:
    nanoseconds_since_epoch: 1537282604241440135
  message_count: 7
  topics_with_message_count:
    - topic_and_type:
        name: /test_topic
        type: test_msgs/Primitives
      message_count: 3
    - topic_and_type:
        name: /array_topic
        type: test_msgs/StaticArrayPrimitives
      message_count: 4"""


def test_real_fixture_formats_refused_clearly(tmp_path):
    # the oldest metadata format, with a real (here empty) test.db3 beside it
    bag = tmp_path / "v1"
    bag.mkdir()
    (bag / "metadata.yaml").write_text(V1_TEXT)
    (bag / "test.db3").write_bytes(b"")
    with pytest.raises(RecordingError, match=r"v1: cannot read the bag.*metadata key"):
        read_recording(bag)
    # the real cdr_test metadata (version 7) whose storage file is not present
    w = wheel(n=10)
    write_recording(tmp_path / "c", [w])
    rewrite_metadata(tmp_path / "c", V7)
    os.remove(tmp_path / "c" / "c.mcap")
    with pytest.raises(RecordingError, match=r"c: cannot read the bag.*c\.mcap"):
        read_recording(tmp_path / "c")


# ----------------------------------------------------------------------------- errors


def test_error_missing_path_and_not_a_bag(tmp_path):
    with pytest.raises(RecordingError, match=r"nope: no such file"):
        read_recording(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(RecordingError, match=r"empty: not a rosbag2 folder \(no metadata.yaml\)"):
        read_recording(tmp_path / "empty")
    (tmp_path / "x.csv").write_text("a,b\n")
    with pytest.raises(RecordingError, match=r"x\.csv: not a bag"):
        read_recording(tmp_path / "x.csv")
    (tmp_path / "junk.mcap").write_bytes(b"this is not an mcap file at all")
    with pytest.raises(RecordingError, match=r"junk\.mcap: cannot read the bag"):
        read_recording(tmp_path / "junk.mcap")
    (tmp_path / "junk.db3").write_bytes(b"SQLite format 3\0" + b"\xff" * 300)
    with pytest.raises(RecordingError, match=r"junk\.db3: cannot read the bag"):
        read_recording(tmp_path / "junk.db3")
    write_recording(tmp_path / "y", [wheel(n=5)])
    (tmp_path / "y" / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    with pytest.raises(RecordingError, match=r"y: cannot read the bag.*YAML"):
        read_recording(tmp_path / "y")


def test_bag_module_does_not_import_ros():
    import subprocess
    import sys

    code = (
        "import sys, tire_model_ros.recording, tire_model_ros.recording.info; "
        "print([m for m in sys.modules if m.startswith(('rclpy', 'rosidl'))])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("name", ["b.mcap", "b.db3", "dir"])
def test_error_truncated_bag(tmp_path, name):
    write_recording(tmp_path / name, [wheel(n=300)])
    target = tmp_path / name / "dir.mcap" if name == "dir" else tmp_path / name
    data = target.read_bytes()
    target.write_bytes(data[: len(data) // 2])
    # MCAP: no footer, the end named (test_bag_trust salvages it); sqlite3: rosbags' error
    with pytest.raises(
        RecordingError,
        match=rf"{name}\b.*: (end of file at byte \d+: )?"
        "(cannot read the bag, )?truncated",
    ):
        read_recording(tmp_path / name)


def test_error_corrupted_mcap_index(tmp_path):
    from mcap.reader import make_reader

    write_recording(tmp_path / "b.mcap", [wheel(n=300)])
    data = bytearray((tmp_path / "b.mcap").read_bytes())
    slip = read_raw(tmp_path / "b.mcap").topics["/rig/wheel/slip"]
    record = data.find(slip.message(7)) - 31  # the Message record: opcode, length, channel..
    assert data[record] == 0x05
    data[record + 1 : record + 9] = (2**40).to_bytes(8, "little")  # absurd record length
    (tmp_path / "b.mcap").write_bytes(bytes(data))
    with pytest.raises(
        RecordingError,
        match=r"b\.mcap: chunk at byte \d+ \(topics .*"
        r"/rig/wheel/slip.*\): CRC mismatch",
    ):
        read_recording(tmp_path / "b.mcap")
    # A writer without CRCs (rosbags writes none): the index and the records disagree.
    with open(tmp_path / "b.mcap", "rb") as f:
        chunk = make_reader(f).get_summary().chunk_indexes[0].chunk_start_offset
    data[chunk + 9 + 24 : chunk + 9 + 28] = b"\0" * 4  # chunk CRC: not written
    data_end = data.rfind(b"\x0f\x04" + b"\0" * 7)
    data[data_end + 9 : data_end + 13] = b"\0" * 4  # data section CRC: not written
    (tmp_path / "b.mcap").write_bytes(bytes(data))
    with pytest.raises(
        RecordingError,
        match=r"b\.mcap: message index at byte \d+ "
        r"\(topics /rig/wheel/slip\): message index and message records disagree",
    ):
        read_recording(tmp_path / "b.mcap")


def test_error_missing_topics_named(tmp_path):
    t = [ns(0.1), ns(0.2)]
    write_raw_bag(
        tmp_path / "b",
        {
            "/a/slip": (VECTOR3_STAMPED, t, np.zeros((2, 3))),
            "/a/load": (WRENCH_STAMPED, t, np.zeros((2, 6))),
            "/b/measured_forces": (WRENCH_STAMPED, t, np.zeros((2, 6))),
        },
    )
    with pytest.raises(
        RecordingError,
        match=r"no wheel found.*wheel /a lacks /a/measured_forces"
        r".*wheel /b lacks /b/slip, /b/load",
    ):
        read_recording(tmp_path / "b")
    write_recording(tmp_path / "c", [wheel(n=5)])
    with pytest.raises(RecordingError, match=r"wheel /car/fl: missing topic\(s\) /car/fl/slip"):
        read_recording(tmp_path / "c", wheels=["/car/fl"])
    write_raw_bag(
        tmp_path / "d",
        {
            "/a/slip": (VECTOR3_STAMPED, t, np.zeros((2, 3))),
            "/a/load": (WRENCH_STAMPED, [ns(0.5)], np.zeros((1, 6))),
            "/a/measured_forces": (WRENCH_STAMPED, t, np.zeros((2, 6))),
        },
    )
    with pytest.raises(RecordingError, match=r"no /a/slip message at or after the first /a/load"):
        read_recording(tmp_path / "d")
    write_raw_bag(
        tmp_path / "e",
        {
            "/a/slip": (VECTOR3_STAMPED, t, np.zeros((2, 3))),
            "/a/load": (WRENCH_STAMPED, t, np.zeros((2, 6))),
            "/a/measured_forces": (WRENCH_STAMPED, [], np.zeros((0, 6))),
        },
    )
    with pytest.raises(RecordingError, match=r"topic /a/measured_forces has no messages"):
        read_recording(tmp_path / "e")


def test_error_wrong_message_type(tmp_path):
    t = [ns(0.1), ns(0.2)]
    topics = {
        "/a/slip": (VECTOR3_STAMPED, t, np.zeros((2, 3))),
        "/a/load": (VECTOR3_STAMPED, t, np.zeros((2, 3))),
        "/a/measured_forces": (WRENCH_STAMPED, t, np.zeros((2, 6))),
    }
    write_topics(tmp_path / "b.mcap", topics)
    with pytest.raises(
        RecordingError,
        match=r"b\.mcap: topic /a/load has message type "
        r"geometry_msgs/msg/Vector3Stamped, expected "
        r"geometry_msgs/msg/WrenchStamped",
    ):
        read_recording(tmp_path / "b.mcap")
    topics["/a/load"] = (WRENCH_STAMPED, t, np.zeros((2, 6)))
    topics["/a/temperature"] = (FLUID_PRESSURE, t, np.zeros((2, 2)))
    write_topics(tmp_path / "c.db3", topics)
    with pytest.raises(
        RecordingError,
        match=r"c\.db3: topic /a/temperature has message type "
        r"sensor_msgs/msg/FluidPressure",
    ):
        read_recording(tmp_path / "c.db3")


def test_read_is_vectorised_and_fast_enough(tmp_path):
    """A smoke figure (the real benchmark is bench/bench_recording.py): 60k messages."""
    import time

    write_recording(tmp_path / "b", [wheel(n=10_000)])
    t0 = time.perf_counter()
    got = read_recording(tmp_path / "b")
    assert len(got["/rig/wheel"]) == 10_000
    assert time.perf_counter() - t0 < 2.0
    shutil.rmtree(tmp_path / "b")


# ----------------------------------------------------------------------------- other writers


def write_with_mcap_package(path: Path, w: WheelSeries, **options) -> None:
    """An MCAP as rosbag2's C++ plugin lays it out (ros2 profile, ros2msg schemas, cdr
    channels with QoS metadata), written by the independent ``mcap`` package."""
    from mcap.writer import Writer

    from tire_model_ros.recording.write import _wheel_channels

    t_ns = w.meta["t_ns"]
    with open(path, "wb") as f:
        writer = Writer(f, **options)
        writer.start(profile="ros2", library="test")
        rows = []
        for channel, (msgtype, values) in _wheel_channels(w).items():
            msgdef, _ = cdr.typestore().generate_msgdef(msgtype, ros_version=2)
            schema = writer.register_schema(msgtype, "ros2msg", msgdef.encode())
            cid = writer.register_channel(
                f"{w.prefix}/{channel}", "cdr", schema, {"offered_qos_profiles": ""}
            )
            for i, data in enumerate(cdr.encode(msgtype, t_ns, values, frame_id="wheel_fl")):
                rows.append((int(t_ns[i]), channel == "slip", cid, bytes(data)))
        for seq, (stamp, _, cid, data) in enumerate(sorted(rows, key=lambda r: r[:2])):
            writer.add_message(cid, log_time=stamp, data=data, publish_time=stamp, sequence=seq)
        writer.finish()


@pytest.mark.parametrize(
    "options",
    [
        {"compression": "ZSTD", "chunk_size": 4096},
        {"compression": "LZ4", "chunk_size": 4096, "enable_data_crcs": True},
        {"compression": "NONE", "chunk_size": 2048},
        {"compression": "NONE", "use_chunking": False},  # no chunk index: rosbags scans
        {"compression": "ZSTD", "index_types": "NONE"},  # no message index: rosbags reads
    ],
    ids=["zstd", "lz4", "none", "unchunked", "unindexed"],
)
def test_mcap_from_another_writer(tmp_path, options):
    from mcap.writer import CompressionType, IndexType

    options = dict(options)
    options["compression"] = CompressionType[options["compression"]]
    if "index_types" in options:
        options["index_types"] = IndexType[options["index_types"]]
    w = wheel(n=300)
    write_with_mcap_package(tmp_path / "x.mcap", w, **options)
    assert_same(read_recording(tmp_path / "x.mcap")["/rig/wheel"], w)


# ----------------------------------------------------------------------------- info


def test_info_summary_and_cli(tmp_path, capsys):
    import json

    from tire_model_ros.cli import main
    from tire_model_ros.recording.info import summarize

    w = wheel(n=150, T=False)
    write_recording(tmp_path / "b", [w], rates={"pressure": 10})
    info = summarize(tmp_path / "b")
    assert info["topics"]["/rig/wheel/slip"]["count"] == 150
    assert info["topics"]["/rig/wheel/pressure"]["type"] == FLUID_PRESSURE
    assert info["topics"]["/rig/wheel/pressure"]["count"] == 2  # 0.149 s of data at 10 Hz
    assert info["topics"]["/rig/wheel/slip"]["rate_hz"] == pytest.approx(1000, rel=0.01)
    assert info["duration_s"] == pytest.approx(w.t[-1] - w.t[0], abs=1e-6)
    wi = info["wheels"]["/rig/wheel"]
    assert wi["samples"] == 150 and wi["absent"] == ["T"]
    assert wi["channels"]["Fx"]["range"] == [w.Fx.min(), w.Fx.max()]
    assert wi["channels"]["kappa"]["range"] == [w.kappa.min(), w.kappa.max()]
    assert main(["info", str(tmp_path / "b"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(json.dumps(info))
    assert main(["info", str(tmp_path / "b")]) == 0
    text = capsys.readouterr().out
    assert "/rig/wheel: 150 samples" in text and "not recorded: T" in text
    # a bag without a complete wheel still lists its topics and says what is missing
    write_topics(tmp_path / "c.mcap", {"/a/slip": (VECTOR3_STAMPED, [1, 2], np.zeros((2, 3)))})
    info = summarize(tmp_path / "c.mcap")
    assert info["wheels"] == {} and "/a lacks load, measured_forces" in info["wheels_error"]
    assert main(["info", str(tmp_path / "nope")]) == 1
    assert "nope: no such file" in capsys.readouterr().err


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_split_bag_several_storage_files(tmp_path, storage):
    """A bag split into several files (rosbag2 --max-bag-size): topics span the files."""
    w = wheel(n=200)
    ext = ".db3" if storage == "sqlite3" else ".mcap"
    write_recording(tmp_path / "b", [w], storage=storage)
    os.remove(tmp_path / "b" / f"b{ext}")
    half = np.arange(200) < 120
    for k, mask in enumerate([half, ~half]):
        part = w.select(mask)
        part.meta = {"t_ns": w.meta["t_ns"][mask]}
        write_recording(tmp_path / "b" / f"b_{k}{ext}", [part])
    meta_path = tmp_path / "b" / "metadata.yaml"
    meta = yaml.safe_load(meta_path.read_text())
    info = meta["rosbag2_bagfile_information"]
    info["relative_file_paths"] = [f"b_0{ext}", f"b_1{ext}"]
    entry = info["files"][0]
    info["files"] = [
        {**entry, "path": f"b_{k}{ext}", "message_count": n} for k, n in [(0, 720), (1, 480)]
    ]
    meta_path.write_text(yaml.safe_dump(meta))
    got = read_recording(tmp_path / "b")["/rig/wheel"]
    assert_same(got, w)
    assert got.meta["messages_read"] == 1200


def _summary_crc_holds(path: Path) -> bool:
    """The Footer's summary CRC, computed here as the MCAP spec defines it."""
    import struct
    import zlib

    data = path.read_bytes()
    footer = len(data) - 8 - 29
    summary_start, _offsets, stored = struct.unpack_from("<QQI", data, footer + 9)
    return stored != 0 and zlib.crc32(data[summary_start or footer : footer + 25]) == stored


def test_mcap_writers_are_valid_for_independent_readers(tmp_path):
    """The vectorised MCAP writer (several chunks) and the streaming one (BagWriter) against
    the mcap package's streaming reader with its CRC checks (chunks, data section), the
    summary CRC as the spec defines it, rosbags' reader and deserialiser, and rosbags' own
    writer's messages."""
    from mcap.records import Chunk, DataEnd
    from mcap.stream_reader import StreamReader
    from rosbags.rosbag2 import Reader, Writer

    from tire_model_ros.recording.write import BagWriter, _wheel_channels

    w = wheel(n=4000)
    write_recording(tmp_path / "fast", [w], rates={"temperature": 50})

    def encoded():
        for channel, (msgtype, values) in _wheel_channels(w).items():
            t_ns = w.meta["t_ns"]
            if channel == "temperature":
                keep = np.ones(len(t_ns), bool)
                keep[1:] = np.diff((t_ns - t_ns[0]) // (NS // 50)) != 0
                t_ns, values = t_ns[keep], values[keep]
            yield f"/rig/wheel/{channel}", msgtype, t_ns, cdr.encode(msgtype, t_ns, values)

    # the same messages through this package's streaming writer and rosbags' writer
    with BagWriter(tmp_path / "stream", chunk_bytes=100_000) as writer:
        for topic, msgtype, t_ns, data in encoded():
            writer.add_topic(topic, msgtype)
            for s, d in zip(t_ns, data, strict=True):
                writer.write(topic, int(s), d)
    with Writer(tmp_path / "rosbags", version=9) as writer:
        for topic, msgtype, t_ns, data in encoded():
            conn = writer.add_connection(topic, msgtype, typestore=cdr.typestore())
            for s, d in zip(t_ns, data, strict=True):
                writer.write(conn, int(s), d)
    for name in ("fast", "stream"):
        with open(tmp_path / name / f"{name}.mcap", "rb") as f:
            kinds: dict[str, int] = {}
            for rec in StreamReader(f, validate_crcs=True).records:
                kinds[type(rec).__name__] = kinds.get(type(rec).__name__, 0) + 1
                if isinstance(rec, Chunk):
                    assert rec.uncompressed_crc != 0, name  # written, and checked above
                if isinstance(rec, DataEnd):
                    assert rec.data_section_crc != 0, name
        assert kinds["ChunkIndex"] >= 2
        # the vectorised writer interleaves the topics in time; this stream wrote topic by topic
        per_chunk = kinds["MessageIndex"] / kinds["ChunkIndex"]
        assert per_chunk == 6 if name == "fast" else 1 <= per_chunk < 6
        assert kinds["Message"] == 5 * 4000 + len(
            np.unique((w.meta["t_ns"] - w.meta["t_ns"][0]) // (NS // 50))
        )
        assert _summary_crc_holds(tmp_path / name / f"{name}.mcap"), name

    def messages(path):
        with Reader(path) as reader:
            out = {}
            for conn, log_ns, data in reader.messages():
                msg = cdr.typestore().deserialize_cdr(bytes(data), conn.msgtype)
                assert msg.header.stamp.sec * NS + msg.header.stamp.nanosec == log_ns
                out.setdefault(conn.topic, []).append((log_ns, bytes(data)))
            return {t: sorted(v) for t, v in out.items()}, reader.message_count

    reference = messages(tmp_path / "rosbags")
    assert messages(tmp_path / "fast") == reference
    assert messages(tmp_path / "stream") == reference
    for name in ("fast", "stream"):
        assert_same(
            read_recording(tmp_path / name)["/rig/wheel"],
            read_recording(tmp_path / "rosbags")["/rig/wheel"],
        )
