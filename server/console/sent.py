"""One statement in the dispatch's sent list: what was sent, its number and status, and its times."""

from __future__ import annotations

from dataclasses import dataclass

from server.console.enums import FINAL_SENT, SentStatus
from server.console.statement_checks import statement_text
from server.console.views import SentView
from shared.language.statements import Statement


@dataclass
class Sent:
    """One statement in the sent list."""

    id: int
    statement: Statement
    status: SentStatus
    submitted_at: float
    comm: int  # console-local communication id
    number: int | None = None
    reason: str | None = None
    answered_at: float | None = None
    started_at: float | None = None
    finished_at: float | None = None
    robot_started_at: float | None = None  # the robot's clock (StatusReport.robot_time)
    robot_finished_at: float | None = None
    before: bool = False  # sent before this console started: the robot's account (server.console.robot_account)

    @property
    def final(self) -> bool:
        return self.status in FINAL_SENT

    def view(self) -> SentView:
        run = self.finished_at - self.started_at if self.finished_at is not None and self.started_at is not None else None
        return SentView(
            id=self.id, number=self.number, text=statement_text(self.statement), statement=self.statement,
            status=self.status, reason=self.reason, submitted_at=self.submitted_at, answered_at=self.answered_at,
            started_at=self.started_at, finished_at=self.finished_at, run_s=run,
            robot_run_s=None if self.robot_finished_at is None or self.robot_started_at is None
            else self.robot_finished_at - self.robot_started_at, before=self.before,
        )
