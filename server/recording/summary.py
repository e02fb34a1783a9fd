"""What a recording says in a few lines: how much of each channel, how long, and every statement
submitted with the statuses it went through (``teleprog record summary``)."""

from __future__ import annotations

from typing import TypeVar

from pydantic import BaseModel, Field, ValidationError

from server.recording import records
from server.recording.reader import RecordedMessage, Recording
from shared.errors import InputError

_M = TypeVar("_M", bound=BaseModel)


def _record(recording: Recording, model: type[_M], m: RecordedMessage) -> _M:
    """A message as the record the console wrote; ``InputError`` (damaged recording) when it is not one."""
    try:
        return model.model_validate(m.data)
    except ValidationError as exc:
        err = exc.errors()[0]
        where = ".".join(str(p) for p in err.get("loc", ())) or "the message"
        raise InputError(f"{recording.path}: damaged recording: a {m.topic} message is not one the console writes "
                         f"({where}: {err.get('msg', 'invalid')})") from None


class StatementSummary(BaseModel):
    id: int = Field(description="console-local id (SentView.id)")
    number: int | None = Field(description="the robot's number; None when it never answered")
    text: str
    final: str | None = Field(description="the final status; None when the recording ends before one")
    statuses: list[str] = Field(description="every status reached, in order")
    reason: str | None = None


class RecordingSummary(BaseModel):
    file: str
    complete: bool = Field(description="the console closed the file")
    writing: bool = Field(False, description="a console is writing the file now (not closed yet, not cut off)")
    problem: str | None = Field(None, description="what could not be read")
    cell: str | None = None
    robot: str | None = None
    start: float | None = Field(None, description="first message, Unix s")
    duration_s: float
    messages: int
    channels: dict[str, int] = Field(description="messages per topic")
    dropped: int = Field(0, description="messages the writer dropped while recording")
    statements: list[StatementSummary]


def summarize(recording: Recording) -> RecordingSummary:
    by_id: dict[int, StatementSummary] = {}
    for m in recording.on(records.STATUS):
        s = _record(recording, records.StatementStatus, m)
        have = by_id.get(s.id)
        if have is None:
            have = by_id[s.id] = StatementSummary(id=s.id, number=s.number, text=s.text, final=None, statuses=[])
        if s.number is not None:
            have.number = s.number
        if not have.statuses or have.statuses[-1] != s.status:
            have.statuses.append(s.status)
        if s.final:
            have.final = s.status
            have.reason = s.reason
    start = recording.session
    dropped = recording.on(records.DROPPED)
    return RecordingSummary(
        file=str(recording.path), complete=recording.complete, writing=recording.writing, problem=recording.problem,
        cell=start.cell if start else None, robot=start.robot if start else None,
        start=recording.start_ns * 1e-9 if recording.messages else None, duration_s=recording.duration_s,
        messages=len(recording.messages), channels=recording.counts(),
        dropped=_record(recording, records.Dropped, dropped[-1]).total if dropped else 0,
        statements=[by_id[k] for k in sorted(by_id)],
    )


def summary_lines(summary: RecordingSummary) -> list[str]:
    """The summary for a person."""
    lines = [f"{summary.file}: {summary.cell or '?'} / {summary.robot or '?'}, {summary.duration_s:.1f} s, "
             f"{summary.messages} messages" + ("" if summary.complete else " (being written)" if summary.writing else " (cut off)")]
    if summary.problem:
        lines.append(f"  note: {summary.problem}")
    if summary.dropped:
        lines.append(f"  {summary.dropped} messages dropped while recording")
    width = max((len(t) for t in summary.channels), default=0)
    lines += [f"  {topic:<{width}}  {n}" for topic, n in summary.channels.items()]
    if summary.statements:
        lines.append("  statements:")
        for s in summary.statements:
            number = f"#{s.number}" if s.number is not None else "  -"
            lines.append(f"    {number:>4} {s.text}: {s.final or 'no final status (' + s.statuses[-1] + ')'}")
    return lines
