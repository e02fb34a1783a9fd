"""The console's enumerations: regimes (thesis §4.2.1), display modes (§4.3.7) and the statuses of
a sent statement."""

from __future__ import annotations

from enum import Enum


class Regime(str, Enum):
    """Segmented composite control (§4.2.1): how statements reach the robot."""

    FREE = "free"  # online: generated statements stream to the robot as they are made
    QUASI = "quasi"  # offline: program, preview, confirm, send
    OPERATION = "operation"  # single step: one motion at a time, each ended by its UNTIL or on a clear path


class DisplayMode(str, Enum):
    """Display modes of §4.3.7."""

    TELEPROGRAMMING = "teleprogramming"  # the operator drives the virtual arm
    TASK_PREVIEW = "task_preview"  # the simulator plays statements on the virtual arm
    TELEPRESENCE = "telepresence"  # the remote scene rebuilt from telemetry


class SentStatus(str, Enum):
    """Status of a submitted statement; the last five are final."""

    SENDING = "sending"  # handed to the link, the robot has not answered yet
    RECEIVED = "received"
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"
    SKIPPED = "skipped"
    ABORTED = "aborted"
    REJECTED = "rejected"  # the robot refused the whole communication (e.g. its buffer was full)
    UNKNOWN = "unknown"  # the robot restarted before its final status: it may or may not have run


FINAL_SENT = frozenset(
    {SentStatus.DONE, SentStatus.FAILED, SentStatus.SKIPPED, SentStatus.ABORTED, SentStatus.REJECTED, SentStatus.UNKNOWN}
)
