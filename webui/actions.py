"""Turning a click into a session call, and a refusal into a sentence on the page.

Every panel calls the session through :class:`Actions.run`: a ``TeleprogError`` (a rule of the
editor, a busy preview, an unreachable pose, no robot) becomes the notice line of the status bar
instead of a traceback in viser's thread pool. Unexpected errors are logged and shown as well,
so a broken click never passes silently.

With a ``NoticeBoard`` (``webui.notice_log``) a refusal is posted there with its action's kind,
and a success ends the notice of that kind posted before the click (a good submit ends the
refusal of the last one).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TypeVar

from server.console import RefusedByRule
from shared.errors import TeleprogError
from webui.notice_log import NoticeBoard, action_kind

log = logging.getLogger(__name__)

T = TypeVar("T")


class Actions:
    """Runs session calls for the panels and reports failures through ``show_notice``."""

    def __init__(self, show_notice: Callable[[str, str, str | None], None], board: NoticeBoard | None = None) -> None:
        self.show_notice = show_notice
        self.board = board

    def _refused(self, what: str, level: str, message: str, rule: str | None) -> None:
        if self.board is None:
            self.show_notice(level, message, rule)
        else:
            self.board.post(level, message, rule, action_kind(what), refused=rule is not None)

    def run(self, what: str, call: Callable[[], T]) -> T | None:
        since = self.board.seq if self.board is not None else 0
        try:
            result = call()
        except TeleprogError as exc:
            refusal = exc.refusal if isinstance(exc, RefusedByRule) else None
            rule = refusal.rule.value if refusal is not None else None
            message = refusal.message if refusal is not None else str(exc)
            self._refused(what, "error", f"{what} refused: {message}", rule)
        except Exception as exc:  # noqa: BLE001 - a view must show, not swallow, a failure
            log.exception("%s failed", what)
            self._refused(what, "error", f"{what} failed: {type(exc).__name__}: {exc}", None)
        else:
            if self.board is not None:
                self.board.succeeded(action_kind(what), since)
            return result
        return None
