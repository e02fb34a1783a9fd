"""Turning a click into a session call, and a refusal into a sentence on the page.

Every panel calls the session through :class:`Actions.run`: a ``TeleprogError`` (a rule of the
editor, a busy preview, an unreachable pose, no robot) becomes the notice line of the status bar
instead of a traceback in viser's thread pool. Unexpected errors are logged and shown as well,
so a broken click never passes silently.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TypeVar

from server.console import RefusedByRule
from shared.errors import TeleprogError

log = logging.getLogger(__name__)

T = TypeVar("T")


class Actions:
    """Runs session calls for the panels and reports failures through ``show_notice``."""

    def __init__(self, show_notice: Callable[[str, str, str | None], None]) -> None:
        self.show_notice = show_notice

    def run(self, what: str, call: Callable[[], T]) -> T | None:
        try:
            return call()
        except TeleprogError as exc:
            refusal = exc.refusal if isinstance(exc, RefusedByRule) else None
            rule = refusal.rule.value if refusal is not None else None
            message = refusal.message if refusal is not None else str(exc)
            self.show_notice("error", f"{what} refused: {message}", rule)
        except Exception as exc:  # noqa: BLE001 - a view must show, not swallow, a failure
            log.exception("%s failed", what)
            self.show_notice("error", f"{what} failed: {type(exc).__name__}: {exc}", None)
        return None
