"""Bags a user can trust: CRCs written and checked, damage named (file, byte offset, topics)
and refused or salvaged, metadata.yaml that disagrees with its files refused, an unclosed
recording salvaged, and a seeded fuzz of single-byte corruptions that never changes data
silently. Real bags on disk, the real CLI; the killed recorder is in test_record_kill.py."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from series_util import assert_same, random_wheel

from tire_model_ros.cli import main
from tire_model_ros.recording import (
    BagWriter,
    DamagedBagError,
    RawBag,
    RecordingError,
    cdr,
    read_raw,
    read_recording,
    write_recording,
)
from tire_model_ros.recording.write import _wheel_channels

CHUNK = 6000  # bytes of records per chunk: a small bag with many chunks


def stream_bag(path: Path, n: int = 200, seed: int = 1, **kwargs: object) -> BagWriter:
    """A one-wheel bag written through BagWriter in stamp order, with small chunks; returned
    open (``close()`` it, or read what a kill would leave)."""
    w = random_wheel("/rig/wheel", n, seed=seed)
    writer = BagWriter(path, chunk_bytes=CHUNK, **kwargs)
    channels = _wheel_channels(w)
    data = {c: cdr.encode(mt, w.meta["t_ns"], v) for c, (mt, v) in channels.items()}
    for c, (msgtype, _) in channels.items():
        writer.add_topic(f"/rig/wheel/{c}", msgtype)
    for i, stamp in enumerate(w.meta["t_ns"].tolist()):
        for c in channels:
            writer.write(f"/rig/wheel/{c}", stamp, data[c][i])
    return writer


def messages(bag: RawBag) -> dict[str, list[tuple[int, bytes]]]:
    """Every message of every topic: (log time, bytes), in bag order."""
    return {
        t: [(int(raw.log_ns[i]), raw.message(i)) for i in range(len(raw))]
        for t, raw in bag.topics.items()
    }


def chunks(path: Path) -> list[tuple[int, int]]:
    """(start, end) byte offsets of every Chunk record, from the file's own summary."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    return sorted(
        (c.chunk_start_offset, c.chunk_start_offset + c.chunk_length) for c in summary.chunk_indexes
    )


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    """A lone .mcap of 1200 messages in about a dozen chunks, closed."""
    stream_bag(tmp_path / "b.mcap").close()
    assert len(chunks(tmp_path / "b.mcap")) >= 8
    return tmp_path / "b.mcap"


def flip(path: Path, pos: int, out: Path, mask: int = 0x20) -> Path:
    data = bytearray(path.read_bytes())
    data[pos] ^= mask
    out.write_bytes(bytes(data))
    return out


# ----------------------------------------------------------------------------- CRCs


def test_damaged_chunk_named_refused_and_salvaged(bag: Path, tmp_path: Path) -> None:
    original = read_raw(bag)
    start, end = chunks(bag)[3]
    bad = flip(bag, (start + end) // 2, tmp_path / "bad.mcap")
    with pytest.raises(DamagedBagError) as refused:
        read_raw(bad)
    line = str(refused.value)
    assert "\n" not in line
    assert line.startswith(f"{bad}: chunk at byte {start} (topics /rig/wheel/load, ")
    assert re.search(r"CRC mismatch \(stored 0x[0-9a-f]{8}, computed 0x[0-9a-f]{8}\)", line)
    assert line.endswith("refused (--salvage skips what is damaged)")
    with pytest.raises(RecordingError, match=re.escape(f"{bad}: chunk at byte {start} ")):
        read_recording(bad)

    got = read_raw(bad, salvage=True)
    [damage] = got.damages
    assert (damage.what, damage.offset, damage.file) == ("chunk", start, bad)
    before, after = messages(original), messages(got)
    assert damage.lost is not None
    for topic, msgs in before.items():
        assert set(after[topic]) <= set(msgs), f"{topic}: salvage invented a message"
        assert len(after[topic]) + damage.lost[topic] == len(msgs), topic
        assert got.all_topics[topic][1] == len(after[topic])
    assert sum(damage.lost.values()) > 0
    report = got.salvage_report()
    assert report[0].startswith(f"skipped {bad}: chunk at byte {start}")
    assert "messages lost: /rig/wheel/load " in report[0]
    assert report[-1].startswith(f"recovered {got.messages_read} messages: /rig/wheel/load ")
    wheels = read_recording(bad, salvage=True)
    assert wheels["/rig/wheel"].meta["damages"] == [damage.describe()]


@pytest.mark.parametrize("part", ["summary", "message index", "schema"])
def test_damage_outside_the_chunks_named(bag: Path, tmp_path: Path, part: str) -> None:
    """The summary CRC and the data section CRC cover what the chunk CRCs do not: a byte
    there is refused, and salvage reads every chunk, all messages intact."""
    data = bag.read_bytes()
    last_chunk_end = chunks(bag)[-1][1]
    pos = {
        "summary": len(data) - 200,  # a chunk index or the statistics
        "message index": last_chunk_end + 20,  # a (log time, offset) pair of the last chunk
        "schema": data.index(b"geometry_msgs/msg/WrenchStamped") + 5,
    }[part]
    bad = flip(bag, pos, tmp_path / "bad.mcap", mask=0x01)
    with pytest.raises(DamagedBagError) as refused:
        read_raw(bad)
    named = {"summary": "summary", "message index": "message index", "schema": "data section"}
    assert str(refused.value).startswith(f"{bad}: {named[part]} at byte ")
    if part == "message index":  # checked against the records it points at
        assert "(topics /rig/wheel/slip): message index and message records disagree" in str(
            refused.value
        )
    else:
        assert "CRC mismatch" in str(refused.value)
    got = read_raw(bad, salvage=True)
    assert messages(got) == messages(read_raw(bag))
    assert got.all_topics == read_raw(bag).all_topics
    assert [d.what for d in got.damages] == [named[part]]


def test_cli_refuses_damage_and_salvages_into_a_new_bag(
    bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    start, _ = chunks(bag)[2]
    bad = flip(bag, start + 100, tmp_path / "bad.mcap")
    assert main(["info", str(bad)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"chunk at byte {start} (topics" in err
    assert main(["info", str(bad), "--salvage", "-o", str(tmp_path / "saved")]) == 0
    out, err = capsys.readouterr()
    assert f"salvage: skipped {bad}: chunk at byte {start}" in err
    assert "salvage: recovered " in err and f"wrote {tmp_path / 'saved'}" in err
    assert f"damage:    {bad}: chunk at byte {start}" in out
    salvaged, saved = read_raw(bad, salvage=True), read_raw(tmp_path / "saved")
    assert saved.damages == [] and messages(saved) == messages(salvaged)
    assert saved.all_topics == salvaged.all_topics
    assert main(["info", str(bad), "-o", str(tmp_path / "x")]) == 1  # -o needs --salvage
    assert "give --salvage too" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_fit_and_diagnose_refuse_a_damaged_recording_fit_salvages(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The sample session with one chunk damaged: fit and diagnose refuse it with the line
    and write nothing; with --salvage both use the rest and say what they skipped."""
    from conftest import DEFAULT_TIR, ROOT

    session = tmp_path / "session"
    shutil.copytree(ROOT / "bags" / "flat_trac_nominal", session)
    mcap = session / "flat_trac_nominal.mcap"
    start, _ = chunks(mcap)[1]
    flip(mcap, start + 5000, mcap)
    out = tmp_path / "out.tir"
    for cmd in (
        ["fit", str(session), "--tir", str(DEFAULT_TIR), "-o", str(out), "--quiet"],
        ["diagnose", str(session), "--tir", str(DEFAULT_TIR), "--json", str(tmp_path / "d.json")],
    ):
        assert main(cmd) == 1
        err = capsys.readouterr().err
        assert f"{mcap}: chunk at byte {start} (topics " in err and "refused" in err
        assert list(tmp_path.iterdir()) == [session]
    assert main(["fit", str(session), "--tir", str(DEFAULT_TIR), "-o", str(out), "--salvage"]) == 0
    err = capsys.readouterr().err
    assert f"salvage: skipped {mcap}: chunk at byte {start}" in err
    said = r"metadata\.yaml: message_count is 35928, \d+ were recovered \(the rest was skipped\)"
    assert len(re.findall(said, err)) == 1 and "message_count is 5988" not in err
    assert out.is_file()
    report = tmp_path / "d.json"
    cmd = ["diagnose", str(session), "--tir", str(DEFAULT_TIR), "--json", str(report)]
    assert main([*cmd, "--salvage"]) == 0
    err = capsys.readouterr().err
    assert f"salvage: skipped {mcap}: chunk at byte {start}" in err
    assert "salvage: recovered " in err and report.is_file()


# ----------------------------------------------------------------------------- metadata.yaml


def edit_metadata(folder: Path, edit) -> None:
    path = folder / "metadata.yaml"
    meta = yaml.safe_load(path.read_text())
    edit(meta["rosbag2_bagfile_information"])
    path.write_text(yaml.safe_dump(meta))


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_metadata_listing_a_file_twice_is_refused(tmp_path: Path, storage: str) -> None:
    w = random_wheel("/rig/wheel", 100, seed=3)
    write_recording(tmp_path / "b", [w], storage=storage)
    name = f"b.{'db3' if storage == 'sqlite3' else 'mcap'}"
    edit_metadata(tmp_path / "b", lambda m: m["relative_file_paths"].append(name))
    meta = tmp_path / "b" / "metadata.yaml"
    with pytest.raises(
        RecordingError,
        match=rf"^{re.escape(str(meta))}: lists the data file {re.escape(name)} 2 times",
    ):
        read_recording(tmp_path / "b")
    got = read_raw(tmp_path / "b", salvage=True)
    assert got.messages_read == 600  # read once, not doubled
    assert_same(read_recording(tmp_path / "b", salvage=True)["/rig/wheel"], w)
    assert any(f"lists the data file {name} 2 times" in d.describe() for d in got.damages)


@pytest.mark.parametrize(
    "edit, says",
    [
        (lambda m: m.update(message_count=700), "message_count is 700, the data files hold 600"),
        (
            lambda m: m["topics_with_message_count"][0].update(message_count=99),
            "topic /rig/wheel/slip: message_count is 99, the data files hold 100",
        ),
        (
            lambda m: m["files"][0].update(message_count=1),
            "file b.mcap: message_count is 1, it holds 600",
        ),
    ],
    ids=["total", "topic", "file"],
)
def test_metadata_counts_that_disagree_are_refused(tmp_path: Path, edit, says: str) -> None:
    w = random_wheel("/rig/wheel", 100, seed=4)
    write_recording(tmp_path / "b", [w])
    edit_metadata(tmp_path / "b", edit)
    meta = tmp_path / "b" / "metadata.yaml"
    with pytest.raises(RecordingError, match=rf"^{re.escape(str(meta))}: {says}$"):
        read_recording(tmp_path / "b")
    got = read_raw(tmp_path / "b", salvage=True)
    assert [d.describe() for d in got.damages] == [f"{meta}: {says} (the files' counts are used)"]
    assert_same(read_recording(tmp_path / "b", salvage=True)["/rig/wheel"], w)


# ----------------------------------------------------------------------------- unclosed bags


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_unclosed_writer_left_readable_complete_chunks(
    tmp_path: Path, storage: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """What a killed writer leaves (its temporary folder; an MCAP file without footer) is
    refused with a line saying so, and salvaged: everything flushed is there."""
    from ros_util import wait_for

    target = tmp_path / "rec"
    writer = stream_bag(target, n=300, storage=storage)
    stream_bag(tmp_path / "twin", n=300, storage=storage).close()  # the same, closed
    full = messages(read_raw(tmp_path / "twin"))
    if storage == "sqlite3":  # committed by a flush period: wait on it, bounded
        wait_for(lambda: (writer.flush_due(), read_raw(target, salvage=True).messages_read)[1],
                 10, "the first commit")  # fmt: skip
    with pytest.raises(RecordingError, match=rf"{target}: no such file or directory; an "
                       rf"interrupted recording left {re.escape(str(writer.tmpdir))}"):  # fmt: skip
        read_raw(target)
    with pytest.raises(RecordingError, match=r"no metadata.yaml\); it holds 1 storage file"):
        read_raw(writer.tmpdir)
    if storage == "mcap":
        with pytest.raises(DamagedBagError, match=r"rec\.mcap: end of file at byte \d+: "
                           r"truncated: .*without its footer"):  # fmt: skip
            read_raw(writer.out.file)
    for source in (target, writer.tmpdir, writer.bag):
        got = read_raw(source, salvage=True)
        for topic, msgs in messages(got).items():
            assert msgs == full[topic][: len(msgs)], topic  # a prefix of what was written
        assert got.messages_read >= (1500 if storage == "mcap" else 1800)
    assert main(["info", str(target), "--salvage", "-o", str(tmp_path / "saved.mcap")]) == 0
    assert "salvage: recovered " in capsys.readouterr().err
    saved = read_raw(tmp_path / "saved.mcap")
    assert messages(saved) == messages(read_raw(target, salvage=True))
    writer.abort()
    assert not writer.tmpdir.exists()


# ----------------------------------------------------------------------------- fuzz


def _contains(damage, pos: int, spans: list[tuple[int, int]], data: bytes) -> bool:
    """Whether ``damage`` names a part of the original file ``data`` that holds byte ``pos``."""
    import struct

    data_end = struct.unpack_from("<Q", data, len(data) - 37 + 9)[0] - 13
    if damage.what == "message index":
        size = 15 + struct.unpack_from("<I", data, damage.offset + 11)[0]
        return damage.offset <= pos < damage.offset + size
    if damage.what == "chunk":
        return any(a == damage.offset and a <= pos < z for a, z in spans)
    if damage.what == "data section":
        return pos < data_end
    if damage.what == "summary":
        return pos >= damage.offset
    if damage.what == "record":
        return damage.offset is None or damage.offset <= pos
    return damage.what == "end of file"


@pytest.mark.parametrize("writer", ["ours", "rosbag2-like"])
def test_fuzz_single_byte_corruptions_never_change_data_silently(
    bag: Path, tmp_path: Path, writer: str
) -> None:
    """300 seeded single-byte corruptions of a small bag: each read equals the original or is
    refused naming the damaged part; each salvaging read gives a subset of the original's
    messages, equal unless a damage is listed, and one listed damage holds the flipped byte.

    ours: every CRC (chunks, data section, summary); rosbag2-like: written by the ``mcap``
    package as rosbag2's C++ writer does, chunk and summary CRCs but no data section CRC (the
    message indexes are then checked against the records alone)."""
    if writer == "rosbag2-like":
        from mcap.writer import CompressionType
        from test_bag import write_with_mcap_package

        bag = tmp_path / "rosbag2.mcap"
        w = random_wheel("/rig/wheel", 200, seed=1)
        write_with_mcap_package(bag, w, chunk_size=CHUNK, compression=CompressionType.NONE)
    data = bag.read_bytes()
    spans = chunks(bag)
    original = messages(read_raw(bag))
    rng = np.random.default_rng(20261202 + len(writer))
    outcome = {"equal": 0, "refused": 0, "salvaged whole": 0, "salvaged part": 0}
    for k in range(300):
        pos = int(rng.integers(len(data)))
        mutant = flip(bag, pos, tmp_path / "m.mcap", mask=int(rng.integers(1, 256)))
        try:
            same = messages(read_raw(mutant)) == original
            assert same, f"mutant {k}: byte {pos} changed the data silently"
            outcome["equal"] += 1
        except DamagedBagError as exc:
            assert str(exc).startswith(str(mutant)), exc
            assert any(_contains(d, pos, spans, data) for d in exc.damages), (pos, str(exc))
            outcome["refused"] += 1
        except RecordingError as exc:  # not even salvage can read it (a header or footer)
            assert str(exc).startswith(str(mutant)), exc
            outcome["refused"] += 1
        try:
            got = read_raw(mutant, salvage=True)
        except RecordingError as exc:
            assert str(exc).startswith(str(mutant)), exc
            continue
        found = messages(got)
        for topic, msgs in found.items():
            assert set(msgs) <= set(original.get(topic, [])), f"mutant {k}: byte {pos}: {topic}"
        if found == original:
            outcome["salvaged whole"] += 1
        else:
            assert got.damages, f"mutant {k}: byte {pos}: messages lost without a word"
            assert any(_contains(d, pos, spans, data) for d in got.damages), pos
            outcome["salvaged part"] += 1
    print(f"300 single-byte corruptions of a {len(data)}-byte bag ({writer}): {outcome}")
    assert outcome["refused"] >= 270 and outcome["salvaged part"] > 50
