"""``tire-model play`` / ``tire-model record``: a real player process publishes a bag into a
real recorder process (rclpy, separate processes, loopback only); the recorded bag equals the
original, stamps and values. The play schedule is checked without ROS."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, TOOL
from ros_util import exited_cleanly
from series_util import NS, assert_same, random_wheel

from tire_model_ros.delivery import PLAY, RECORD, account, parse_reports, report_line
from tire_model_ros.recording import (
    RecordingError,
    WheelSeries,
    read_raw,
    read_recording,
    write_recording,
)
from tire_model_ros.ros.play import load_schedule, select_topics
from tire_model_ros.vocabulary import NODE_INPUTS

INPUTS = ("slip", *NODE_INPUTS)


def wheel(prefix: str, n: int, seed: int) -> WheelSeries:
    return random_wheel(prefix, n, seed=seed, dt_ns=10_000_000)


# ----------------------------------------------------------------------------- no ROS


def test_play_gives_its_writers_a_fast_heartbeat_only_where_it_may(tmp_path, monkeypatch):
    """Fast DDS acknowledges a reliable writer's samples at its heartbeat (3 s by default), so
    play's waits took 3 s each: while play makes its own participant, Fast DDS reads a profile
    beating every 20 ms; the variable is gone after. A user's profiles, another rmw or a
    context made before are left alone (a user's is said)."""
    import xml.etree.ElementTree as ET

    from tire_model_ros.ros.play import FASTDDS_PROFILES_ENV, writer_heartbeat

    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(FASTDDS_PROFILES_ENV, raising=False)
    monkeypatch.delenv("RMW_IMPLEMENTATION", raising=False)
    said: list[str] = []
    with writer_heartbeat(True, said.append):
        root = ET.parse(Path(os.environ[FASTDDS_PROFILES_ENV])).getroot()
    ns = {"d": "http://www.eprosima.com"}
    period = root.find("d:profiles/d:data_writer/d:times/d:heartbeatPeriod", ns)
    assert period is not None and period.findtext("d:nanosec", namespaces=ns) == "20000000"
    assert root.find("d:profiles/d:data_writer", ns).get("is_default_profile") == "true"
    assert FASTDDS_PROFILES_ENV not in os.environ and not said
    for own, rmw in ((False, None), (True, "rmw_cyclonedds_cpp")):
        if rmw:
            monkeypatch.setenv("RMW_IMPLEMENTATION", rmw)
        with writer_heartbeat(own, said.append):
            assert FASTDDS_PROFILES_ENV not in os.environ
    monkeypatch.delenv("RMW_IMPLEMENTATION")
    monkeypatch.setenv(FASTDDS_PROFILES_ENV, "mine.xml")
    with writer_heartbeat(True, said.append):
        assert os.environ[FASTDDS_PROFILES_ENV] == "mine.xml"
    assert len(said) == 1 and FASTDDS_PROFILES_ENV in said[0]


def test_schedule_order_and_topic_choice(tmp_path):
    w = wheel("/car/fl", 20, 1)
    write_recording(tmp_path / "b", [w, wheel("/car/fr", 20, 2)], rates={"temperature": 20})
    topics = list(read_raw(tmp_path / "b", lambda _t: False).all_topics)
    chosen = select_topics(topics, None, measured=False)
    assert chosen == sorted(f"/car/{s}/{c}" for s in ("fl", "fr") for c in INPUTS)
    assert "/car/fl/measured_forces" in select_topics(topics, ["/car/fl"], measured=True)
    assert all(t.startswith("/car/fl/") for t in select_topics(topics, ["/car/fl"], False))
    with pytest.raises(RecordingError, match="no wheel /car/rr"):
        select_topics(topics, ["/car/rr"], False)

    sched = load_schedule(tmp_path / "b", wheels=["/car/fl"])
    assert len(sched) == 20 * 4 + len(read_raw(tmp_path / "b").topics["/car/fl/temperature"])
    assert np.all(np.diff(sched.stamp_ns) >= 0), "not in header-stamp order"
    names = [sched.topics[i].rpartition("/")[2] for i in sched.topic_idx]
    # every stamp group ends with its slip: the node sees load, p, T, Vx first
    for k, stamp in enumerate(w.meta["t_ns"]):
        group = [names[i] for i in np.flatnonzero(sched.stamp_ns == stamp)]
        assert group[-1] == "slip" and group.count("slip") == 1, (k, group)
        assert set(group[:-1]) <= set(NODE_INPUTS)
        assert {"load", "pressure", "velocity"} <= set(group[:-1])
    # the bytes are the bag's own: the first message decodes to the first stamp
    first = np.frombuffer(sched.raw_of(0), np.uint8)
    sec, nsec = first[4:12].copy().view("<u4")
    assert int(sec) * NS + int(nsec) == w.meta["t_ns"][0]


def test_recorder_counts_publisher_sequence_gaps():
    from tire_model_ros.ros.record import TopicCount

    c = TopicCount()
    for seq in (21, 22, 23, 26, 27):  # 20 sent before it listened, 24 and 25 lost on the way
        c.seen(seq)
    assert (c.gaps, c.publishers_seen) == (22, 1)
    c.seen(1)  # a restarted publisher
    c.seen(2)
    assert (c.gaps, c.publishers_seen) == (22, 2)
    c.seen(None)  # an rmw without sequence numbers: nothing to count
    assert c.gaps == 22


def test_account_explains_every_loss_or_says_how_much_it_cannot():
    play = {"/w/slip": {"published": 100, "acknowledged": 1, "subscribers": 1}}
    node = {"/w": {"slip_in": 100, "forces_out": 97, "slip_rejected": 2, "model_errors": 1}}
    rec = {"/w/forces": {"recorded": 90, "gaps": 5, "ignored": 2, "publishers_seen": 1}}
    acc = account("/w", play, node, rec)
    assert acc.unexplained == 0 and "unexplained loss 0" in acc.text()
    node_short = {"/w": {"slip_in": 96, "forces_out": 93, "slip_rejected": 2, "model_errors": 1}}
    assert account("/w", play, node_short, rec).unexplained == 4 + 4  # before and after node
    unacked = {"/w/slip": {"published": 100, "acknowledged": 0, "subscribers": 1}}
    rec_ok = {"/w/forces": {"recorded": 86, "gaps": 5, "ignored": 2, "publishers_seen": 1}}
    assert account("/w", unacked, node_short, rec_ok).unexplained == 0  # play said so
    with pytest.raises(KeyError, match="record report of /w/forces"):
        account("/w", play, node, {})
    text = "noise\n" + report_line(PLAY, "/w/slip", play["/w/slip"]) + "\n"
    assert parse_reports(text, PLAY) == play


# ----------------------------------------------------------------------------- ROS


@pytest.fixture
def ros_env():
    """A ROS domain of our own on loopback (test/ros_util.py: lock per domain id)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import ros_util

    return ros_util.ros_env(ros_util.claim_domain_id())


def start(args, env, log: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [*TOOL, *args], env=env, cwd=ROOT, stdout=log.open("w"), stderr=subprocess.STDOUT
    )


def wait_for_line(log: Path, text: str, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if text in log.read_text():
            return
        time.sleep(0.05)
    raise AssertionError(f"{text!r} not in {log}:\n{log.read_text()}")


def finish(proc: subprocess.Popen, log: Path, timeout: float = 30) -> str:
    try:
        rc = proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGABRT)  # PYTHONFAULTHANDLER: the log gets every thread's stack
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        raise AssertionError(f"timed out:\n{log.read_text()}") from None
    out = log.read_text()
    assert exited_cleanly(rc, out), out
    return out


@pytest.mark.ros
@pytest.mark.timeout(60)
def test_play_into_recorder_timed(tmp_path, ros_env):
    """Timed playback at 4x into a recorder that stops after --count messages."""
    wheels = [wheel("/car/fl", 60, 1), wheel("/car/fr", 60, 2)]  # 0.6 s of data
    write_recording(tmp_path / "src", wheels, rates={"temperature": 20})
    n_msgs = sum(len(t) for t in read_raw(tmp_path / "src").topics.values())
    rec_log, play_log = tmp_path / "rec.log", tmp_path / "play.log"
    rec = start(
        [
            "record",
            "-o",
            str(tmp_path / "out"),
            "--count",
            str(n_msgs),
            "--topics",
            *[f"/car/{s}/{c}" for s in ("fl", "fr") for c in (*INPUTS, "measured_forces")],
        ],
        ros_env,
        rec_log,
    )
    wait_for_line(rec_log, "recording 12 topic(s)", 30)
    t0 = time.monotonic()
    player = start(
        ["play", str(tmp_path / "src"), "--rate", "4", "--measured", "--wait", "10"],
        ros_env,
        play_log,
    )
    assert f"published {n_msgs} messages" in finish(player, play_log)
    played_s = time.monotonic() - t0
    assert "recorded" in finish(rec, rec_log)
    assert played_s >= 0.59 / 4  # the timing was kept (scaled), not a burst
    got = read_recording(tmp_path / "out")
    assert sorted(got) == ["/car/fl", "/car/fr"]
    for w in wheels:
        assert_same(got[w.prefix], read_recording(tmp_path / "src")[w.prefix])
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")], "temp dir left"


@pytest.mark.ros
@pytest.mark.timeout(60)
def test_play_fast_recorder_stopped_by_sigint(tmp_path, ros_env):
    """--fast playback of one wheel's inputs; the recorder, stopped by SIGINT, closes its
    lone .mcap file atomically with every message."""
    w = wheel("/rig/wheel", 100, 3)
    write_recording(tmp_path / "src.mcap", [w, wheel("/rig/other", 10, 4)])
    rec_log, play_log = tmp_path / "rec.log", tmp_path / "play.log"
    rec = start(
        [
            "record",
            "-o",
            str(tmp_path / "out.mcap"),
            "--topics",
            *[f"/rig/wheel/{c}" for c in INPUTS],
        ],
        ros_env,
        rec_log,
    )
    wait_for_line(rec_log, "recording 5 topic(s)", 30)
    player = start(
        ["play", str(tmp_path / "src.mcap"), "--fast", "--wheels", "/rig/wheel", "--wait", "10"],
        ros_env,
        play_log,
    )
    assert "published 500 messages" in finish(player, play_log)
    time.sleep(0.5)  # acknowledged by the end of play; let the recorder drain its queue
    assert not (tmp_path / "out.mcap").exists(), "bag visible before the recorder closed it"
    rec.send_signal(signal.SIGINT)
    out = finish(rec, rec_log)
    assert "/rig/wheel/slip: 100" in out
    raw = read_raw(tmp_path / "out.mcap")
    assert sorted(raw.all_topics) == sorted(f"/rig/wheel/{c}" for c in INPUTS)
    src = read_raw(tmp_path / "src.mcap")
    for topic, t in raw.topics.items():
        mine = sorted(t.message(i) for i in range(len(t)))
        theirs = sorted(src.topics[topic].message(i) for i in range(len(src.topics[topic])))
        assert mine == theirs, topic  # bit for bit
        stamps = np.sort(np.asarray(t.log_ns))  # log time = header stamp
        np.testing.assert_array_equal(stamps, w.meta["t_ns"])


@pytest.mark.ros
@pytest.mark.timeout(90)
def test_play_stopped_by_sigterm_mid_stream_ends_cleanly(tmp_path, ros_env):
    """SIGTERM stops play between messages: its report and count are printed and it exits 0,
    the context still valid for the acknowledgement wait (rclpy's own handler had shut it
    down under it: a traceback)."""
    w = wheel("/rig/wheel", 1000, 5)  # 10 s at rate 1
    write_recording(tmp_path / "src.mcap", [w])
    rec_log, play_log = tmp_path / "rec.log", tmp_path / "play.log"
    rec = start(["record", "-o", str(tmp_path / "out.mcap"), "--topics",
                 *[f"/rig/wheel/{c}" for c in INPUTS]], ros_env, rec_log)  # fmt: skip
    wait_for_line(rec_log, "recording 5 topic(s)", 30)
    player = start(["play", str(tmp_path / "src.mcap"), "--wait", "20"], ros_env, play_log)
    wait_for_line(play_log, "playing ", 30)
    time.sleep(1.0)  # into the stream (the assertions hold wherever the signal lands)
    player.send_signal(signal.SIGTERM)
    out = finish(player, play_log)
    published = int(out.rsplit("published ", 1)[1].split()[0])
    assert published < 5000 and "Traceback" not in out, out
    rec.send_signal(signal.SIGINT)
    finish(rec, rec_log)


@pytest.mark.ros
@pytest.mark.timeout(60)
def test_record_duration_and_errors(tmp_path, ros_env):
    log = tmp_path / "rec.log"
    t0 = time.monotonic()
    finish(
        start(
            ["record", "-o", str(tmp_path / "empty"), "--wheels", "/car/fl", "--duration", "0.5"],
            ros_env,
            log,
        ),
        log,
    )
    assert time.monotonic() - t0 >= 0.5
    assert read_raw(tmp_path / "empty").all_topics == {
        "/car/fl/forces": ("geometry_msgs/msg/WrenchStamped", 0)
    }
    # SIGTERM closes the bag like SIGINT
    rec = start(["record", "-o", str(tmp_path / "term.mcap"), "--wheels", "/car/fl"], ros_env, log)
    wait_for_line(log, "recording 1 topic(s)", 30)
    rec.send_signal(signal.SIGTERM)
    assert "/car/fl/forces: 0" in finish(rec, log)
    assert "/car/fl/forces" in read_raw(tmp_path / "term.mcap").all_topics
    # refuses an existing output, an unknown topic type, and a bag without wheels to play
    for args, message in [
        (
            ["record", "-o", str(tmp_path / "empty"), "--wheels", "/a", "--duration", "1"],
            "exists already",
        ),
        (["record", "-o", str(tmp_path / "x"), "--topics", "/a/odd"], "unknown type"),
        (["play", str(tmp_path / "empty")], "no input topics to play"),
        (["play", str(tmp_path / "missing")], "no such file"),
    ]:
        proc = subprocess.run(
            [*TOOL, *args], env=ros_env, cwd=ROOT, capture_output=True, text=True, timeout=30
        )
        assert proc.returncode == 1 and message in proc.stderr, (args, proc.stderr)
        assert "Traceback" not in proc.stderr
    assert not (tmp_path / "x").exists()


@pytest.mark.ros
@pytest.mark.timeout(90)
def test_recorder_reports_what_never_reached_it_and_play_what_went_to_nobody(tmp_path, ros_env):
    """20 forces published before the recorder listens, 30 after: it records 30 and reports
    the 20 as missing (the publisher's sequence numbers). A play with no subscriber says that
    its messages went to nobody."""
    import ros_util
    from geometry_msgs.msg import WrenchStamped

    client = ros_util.RosClient("test_gap_client")
    try:
        pub = client.publisher(WrenchStamped, "/gap/forces")
        for _ in range(20):
            pub.publish(WrenchStamped())
        log = tmp_path / "rec.log"
        rec = start(["record", "-o", str(tmp_path / "gap"), "--wheels", "/gap", "--count", "30"],
                    ros_env, log)  # fmt: skip
        client.wait_matched([pub], 30)
        for _ in range(30):
            pub.publish(WrenchStamped())
        out = finish(rec, log)
    finally:
        client.close()
    got = parse_reports(out, RECORD)["/gap/forces"]
    assert (got["recorded"], got["gaps"], got["ignored"]) == (30, 20, 0), out
    assert "never reached the recorder" in out
    write_recording(tmp_path / "src", [wheel("/w", 5, 1)])
    done = subprocess.run([*TOOL, "play", str(tmp_path / "src"), "--wait", "0.2"], env=ros_env,
                          cwd=ROOT, capture_output=True, text=True, timeout=60)  # fmt: skip
    assert done.returncode == 0 and "went to nobody" in done.stdout, done.stdout + done.stderr
    assert parse_reports(done.stdout, PLAY)["/w/slip"] == {
        "published": 5, "acknowledged": 1, "subscribers": 0}  # fmt: skip
