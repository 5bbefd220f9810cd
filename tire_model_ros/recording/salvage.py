"""What a salvaging read recovered, written as a new, whole bag.

``salvage_to`` reads a damaged or unclosed bag (``read_raw(..., salvage=True)``: the complete
chunks of an MCAP file without footer, a recorder's temporary folder, every chunk whose CRC
holds) and writes every topic it recovered, message bytes unchanged, into a new bag at
``out`` (atomically; never over an existing path unless ``overwrite``). The new bag reads
without ``salvage``.
"""

from __future__ import annotations

import os

import numpy as np

from tire_model_ros.recording.read import RawBag, read_raw
from tire_model_ros.recording.write import BagWriter


def write_raw(bag: RawBag, out: str | os.PathLike[str], *, overwrite: bool = False) -> None:
    """Every topic of ``bag`` (read with every topic selected) into a new bag at ``out``, in
    log-time order, with each type's definition from the source where it carries one."""
    names = sorted(bag.topics)
    with BagWriter(out, overwrite=overwrite) as writer:
        for topic, (msgtype, _) in sorted(bag.all_topics.items()):
            writer.add_topic(topic, msgtype, bag.msgdefs.get(msgtype))
        if not names:
            return
        log = np.concatenate([bag.topics[t].log_ns for t in names])
        which = np.concatenate([np.full(len(bag.topics[t]), k) for k, t in enumerate(names)])
        index = np.concatenate([np.arange(len(bag.topics[t])) for t in names])
        order = np.lexsort((which, log))  # stable: a topic's messages keep their order
        for k, i in zip(which[order].tolist(), index[order].tolist(), strict=True):
            raw = bag.topics[names[k]]
            start = int(raw.starts[i])
            writer.write(
                names[k], int(raw.log_ns[i]), raw.buf[start : start + int(raw.lens[i])].data
            )


def salvage_to(
    source: str | os.PathLike[str], out: str | os.PathLike[str], *, overwrite: bool = False
) -> RawBag:
    """Read ``source`` salvaging (see ``read_raw``) and write what it recovered to ``out``.

    Returns the salvaged RawBag: its ``salvage_report()`` says what was skipped and recovered.
    """
    bag = read_raw(source, salvage=True)
    write_raw(bag, out, overwrite=overwrite)
    return bag
