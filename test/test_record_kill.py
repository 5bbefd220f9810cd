"""A recorder killed with SIGKILL loses at most its last second: a real ``tire-model record``
process records a topic this test publishes (stamped with the wall clock), is killed with -9
mid-recording, and its temporary folder is salvaged (reader, ``info --salvage -o``, ``play
--salvage``): every message stamped more than a second before the kill is there, bit for bit.
"""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, TOOL
from ros_util import NodeProcess, RosClient, ros_env

from tire_model_ros.recording import read_raw

TOPIC = "/kill/wheel/slip"
RATE_HZ = 200.0
BEFORE_KILL_S = 3.0


def stamped(msg_type, t_ns: int, k: int):
    msg = msg_type()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
    msg.vector.x = float(k)
    return msg


@pytest.mark.ros
@pytest.mark.timeout(180)
def test_recorder_killed_with_sigkill_loses_at_most_its_last_second(tmp_path: Path) -> None:
    from geometry_msgs.msg import Vector3Stamped

    client = RosClient("kill_publisher")
    env = ros_env(client.domain_id)
    target = tmp_path / "rec"
    recorder = NodeProcess([*TOOL, "record", "-o", str(target), "--topics", TOPIC], env, str(ROOT))
    try:
        recorder.wait_log("recording 1 topic(s)", 60)
        pub = client.publisher(Vector3Stamped, TOPIC)
        client.wait_matched([pub], 60, recorder)
        sent: list[int] = []
        start = time.monotonic()
        kill_ns = None
        while time.monotonic() - start < BEFORE_KILL_S + 0.3:
            if kill_ns is None and time.monotonic() - start >= BEFORE_KILL_S:
                kill_ns = time.time_ns()
                recorder.proc.send_signal(signal.SIGKILL)
            t_ns = time.time_ns()
            pub.publish(stamped(Vector3Stamped, t_ns, len(sent)))
            sent.append(t_ns)
            time.sleep(1.0 / RATE_HZ)  # the publishing rate, not a wait for an event
        code, log = recorder.stop(timeout=10)
    finally:
        recorder.stop(signal.SIGKILL)
        client.close()
    assert code == -signal.SIGKILL, log
    assert not target.exists()
    [tmpdir] = list(tmp_path.glob(".rec.*.tmp"))

    bag = read_raw(target, salvage=True)
    got = bag.topics[TOPIC]
    stamps = np.asarray(got.log_ns)
    sent_ns = np.asarray(sent)
    assert set(stamps.tolist()) <= set(sent_ns.tolist())
    old = sent_ns[sent_ns < kill_ns - 1_000_000_000]
    missing = np.setdiff1d(old, stamps)
    newest_age_s = (kill_ns - stamps.max()) / 1e9
    print(
        f"sent {len(sent_ns)} ({np.sum(sent_ns < kill_ns)} before the kill), recovered "
        f"{len(stamps)}; the newest recovered message was {newest_age_s:.3f} s old at the kill"
    )
    assert len(old) >= 50  # seconds of messages (fewer than RATE_HZ on a loaded machine)
    assert missing.size == 0, f"{missing.size} messages older than 1 s before the kill lost"
    # the bytes are the messages' own: the index k rides in vector.x
    first = np.frombuffer(got.message(0), np.uint8)
    assert first[-24:-16].view("<f8")[0] == float(np.searchsorted(sent_ns, stamps[0]))
    assert any("without its footer" in d.describe() for d in bag.damages)

    # the CLI: info --salvage writes a whole bag; play --salvage plays what was recovered
    saved = tmp_path / "saved"
    done = subprocess.run([*TOOL, "info", str(tmpdir), "--salvage", "-o", str(saved)], env=env,
                          cwd=ROOT, capture_output=True, text=True, timeout=60)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert f"salvage: recovered {len(stamps)} messages: {TOPIC} {len(stamps)}" in done.stderr
    np.testing.assert_array_equal(read_raw(saved).topics[TOPIC].log_ns, got.log_ns)
    play = [*TOOL, "play", str(target), "--salvage", "--fast", "--wait", "0"]
    played = subprocess.run(play, env=env, cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert played.returncode == 0, played.stderr + played.stdout
    assert f"published {len(stamps)} messages" in played.stdout
    assert "salvage: " in played.stdout and "without its footer" in played.stdout
