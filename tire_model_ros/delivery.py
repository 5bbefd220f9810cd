"""No silent loss in play -> node -> record: each stage's report, and the account of one wheel's
slip messages through the three (no ROS import).

Each stage counts what it did not deliver and says so in one report line per subject (a topic
or a wheel), ``<tag> <subject> <JSON counts>``, that :func:`parse_reports` reads back:

- ``play report <topic>``: ``published``; ``acknowledged`` 1 when every reliable subscriber
  acknowledged every message of the topic, 0 when not (they may be lost); ``subscribers`` when
  playing started (0: its messages went to nobody).
- ``final counts <wheel prefix>`` (the node, :mod:`tire_model_ros.wheel.state`): ``slip_in``,
  ``forces_out`` and the reason of every slip not answered.
- ``record report <topic>``: ``recorded``; ``gaps``, messages of the publisher that never reached
  the recorder (gaps in its publication sequence numbers, those before the first one received
  included); ``ignored`` after ``--count``; ``publishers_seen`` (gaps are attributable with one).

:func:`account` puts the three together for one wheel: every slip message played is recorded as
a force message, or is explained by a count of one of the stages; ``unexplained`` is what is left.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass

PLAY = "play report"
NODE = "final counts"
RECORD = "record report"
#: The node's reasons for not answering a slip message (:mod:`tire_model_ros.wheel.state`).
UNANSWERED = (
    "slip_malformed",
    "slip_rejected",
    "skipped_no_load",
    "output_nonfinite",
    "model_errors",
    "slip_inactive",
    "publish_failed",
)


def report_line(tag: str, subject: str, counts: Mapping[str, int]) -> str:
    """One report line: ``<tag> <subject> <counts as JSON>`` (subject without spaces)."""
    return f"{tag} {subject} {json.dumps(dict(counts), sort_keys=True)}"


def parse_reports(text: str, tag: str) -> dict[str, dict[str, int]]:
    """Subject -> counts of every ``tag`` line in ``text`` (a log); the last line wins."""
    out: dict[str, dict[str, int]] = {}
    for line in text.splitlines():
        _, sep, rest = line.partition(tag + " ")
        if sep:
            subject, _, doc = rest.partition(" ")
            try:
                out[subject] = {str(k): int(v) for k, v in json.loads(doc).items()}
            except (ValueError, AttributeError):
                continue  # a line that only looks like one
    return out


@dataclass(frozen=True)
class Account:
    """One wheel's slip messages through play -> node -> record (counts of messages)."""

    played: int  # slip messages play published
    acknowledged: bool  # every reliable subscriber of P/slip acknowledged them all
    taken: int  # slip messages the node took (slip_in)
    answered: int  # force messages the node published (forces_out)
    unanswered: int  # slips the node counted under a reason
    recorded: int  # force messages the recorder wrote
    gaps: int  # force messages the recorder saw missing (publisher sequence gaps)
    ignored: int  # force messages the recorder ignored after --count

    @property
    def unexplained(self) -> int:
        """Messages lost without a stage counting them (0 when every loss is accounted for)."""
        before_node = self.played - self.taken
        in_node = self.taken - self.answered - self.unanswered
        after_node = self.answered - self.recorded - self.gaps - self.ignored
        return abs(0 if not self.acknowledged else before_node) + abs(in_node) + abs(after_node)

    def text(self) -> str:
        return (
            f"played {self.played} slip messages ({'all' if self.acknowledged else 'NOT all'} "
            f"acknowledged); the node took {self.taken}, answered {self.answered}, counted "
            f"{self.unanswered} unanswered; the recorder wrote {self.recorded}, saw "
            f"{self.gaps} missing, ignored {self.ignored}; unexplained loss {self.unexplained}"
        )


def account(
    prefix: str,
    play: Mapping[str, Mapping[str, int]],
    node: Mapping[str, Mapping[str, int]],
    record: Mapping[str, Mapping[str, int]],
) -> Account:
    """The account of wheel ``prefix`` from the three stages' parsed reports.

    Raises
    ------
    KeyError
        naming the stage whose report of this wheel is missing (a stage that says nothing
        cannot be accounted for).
    """
    slip, forces = f"{prefix}/slip", f"{prefix}/forces"
    for stage, reports, key in (("play", play, slip), ("node", node, prefix),
                                ("record", record, forces)):  # fmt: skip
        if key not in reports:
            raise KeyError(f"no {stage} report of {key}")
    p, n, r = play[slip], node[prefix], record[forces]
    return Account(
        played=p["published"],
        acknowledged=bool(p["acknowledged"]) and p["subscribers"] > 0,
        taken=n["slip_in"],
        answered=n["forces_out"],
        unanswered=sum(n.get(k, 0) for k in UNANSWERED),
        recorded=r["recorded"],
        gaps=r["gaps"],
        ignored=r["ignored"],
    )
