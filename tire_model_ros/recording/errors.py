"""What can be wrong with a recording: ``RecordingError`` and the ``Damage`` a reader found.

A reader either refuses a damaged bag (``DamagedBagError``, one line naming the file, the byte
offset and the topics concerned) or, asked to salvage, skips the damaged part and lists it as
``Damage`` entries on the ``RawBag`` it returns.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


class RecordingError(ValueError):
    """A recording that cannot be read or written; the message names the file and topic."""


@dataclass(frozen=True)
class Damage:
    """One damaged, missing or disagreeing part of a bag.

    Attributes
    ----------
    file : the storage file (or metadata.yaml) concerned.
    what : the part: "chunk", "message index", "data section", "summary", "end of file",
        "record", "metadata", "file".
    reason : what is wrong, e.g. "CRC mismatch (stored 0x..., computed 0x...)".
    offset : byte offset of the part in ``file`` (None where a byte offset means nothing).
    topics : topics whose messages the part holds, where known.
    lost : messages per topic in a skipped part, where an index says (None: unknown).
    """

    file: Path
    what: str
    reason: str
    offset: int | None = None
    topics: tuple[str, ...] = ()
    lost: dict[str, int] | None = field(default=None, compare=False)

    def describe(self) -> str:
        """``<file>: <what> at byte <offset> (topics ...): <reason>``."""
        at = f" at byte {self.offset}" if self.offset is not None else ""
        topics = f" (topics {', '.join(self.topics)})" if self.topics else ""
        part = "" if self.what in ("file", "metadata") else f"{self.what}{at}{topics}: "
        return f"{self.file}: {part}{self.reason}"

    def lost_text(self) -> str:
        """Messages per topic skipped with this part, or what is known of them."""
        if self.lost is None:
            return "messages lost: unknown (no index of them)"
        if not self.lost:
            return "no messages lost"
        return "messages lost: " + ", ".join(f"{t} {n}" for t, n in sorted(self.lost.items()))


class DamagedBagError(RecordingError):
    """A bag refused because part of it is damaged; ``damages`` lists what was found."""

    def __init__(self, damages: list[Damage]) -> None:
        first = damages[0].describe()
        more = f" (and {len(damages) - 1} more damaged part(s))" if len(damages) > 1 else ""
        super().__init__(f"{first}{more}; refused (--salvage skips what is damaged)")
        self.damages = damages
