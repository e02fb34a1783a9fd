"""The notice line and the log of past notices (issue 16: every notice clears when its condition
ends; the page keeps a short scrollable log instead).

A notice is a sentence for the operator: a refused click (``webui.actions``) or something the
session said (a robot's answer, a rejected communication, a generated statement held back). The
line under the status bar shows the current one until

* a newer notice replaces it, or
* an action of the same kind succeeds after it (a good submit ends "submit refused: ..."; any
  successful edit ends an edit's refusal), or
* its condition ends: what a notice says about the robot's state (a recovery's answer,
  "nothing to stop (robot idle)", a refused resume) ends when the robot's state changes; a
  plain "info" note ends at the next successful action of any kind.

Every notice also goes to the log: the last :data:`LOG_SIZE`, newest first, with the wall-clock
time and the level, in a scroll box of its own. The rules here are display rules only: which
notice still stands; the session's rules stay in ``server/console``.
"""

from __future__ import annotations

import html
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

LOG_SIZE = 50

RECOVERY = "recovery"
EDIT = "edit"
PREVIEW = "preview"
DRIVE = "drive"
SUBMIT = "submit"
NOTE = "note"  # an info note: any later successful action ends it

_EDITS = {"insert", "modify", "delete", "select", "undo", "redo", "load", "save", "clear with/until", "automatic generation"}
_RECOVERIES = {"stop", "resume", "skip", "abort", "back away"}
_DRIVES = {"drive", "release"}

# what the session's own notices are about, read from how they begin (they carry no kind)
_SESSION_KINDS: tuple[tuple[str, str], ...] = (
    ("robot applied ", RECOVERY), ("robot did not apply ", RECOVERY), ("stop failed", RECOVERY),
    ("resume failed", RECOVERY), ("skip failed", RECOVERY), ("abort failed", RECOVERY),
    ("back away", RECOVERY), ("backing away", RECOVERY),
    ("generated ", DRIVE), ("held back", DRIVE), ("streaming refused", SUBMIT),
    ("submission failed", SUBMIT),
)

LEVEL_MARK = {"error": "Error", "warning": "Warning", "info": "Note"}
LEVEL_COLOUR = {"error": "#c92a2a", "warning": "#e67700", "info": "#495057"}


def action_kind(what: str) -> str:
    """The kind of a panel's action (``Actions.run``'s ``what``): related clicks share one."""
    name = what.lower()
    if name in _EDITS:
        return EDIT
    if name in _RECOVERIES:
        return RECOVERY
    if name.startswith("preview"):
        return PREVIEW
    if name in _DRIVES or name.startswith("turn j"):
        return DRIVE
    return name


def session_kind(level: str, message: str) -> str:
    """The kind of a notice the session published (see ``_SESSION_KINDS``); an unmatched info
    note is a ``NOTE``, an unmatched warning or error is about submitting (a rejected
    communication, a robot restart: a good submit is the next thing that shows it is over)."""
    text = message.lower()
    for prefix, kind in _SESSION_KINDS:
        if text.startswith(prefix):
            return kind
    return NOTE if level == "info" else SUBMIT


@dataclass(frozen=True)
class LoggedNotice:
    seq: int
    at: float  # wall clock (s)
    level: str
    message: str
    rule: str | None
    kind: str
    robot_state: str | None  # the robot's state when it was posted

    def line(self, refused: bool = False) -> str:
        mark = "Refused" if refused else LEVEL_MARK.get(self.level, self.level)
        text = f"**{mark}:** {self.message}"
        if self.rule:
            text += f" (rule `{self.rule}`)"
        return text


class NoticeBoard:
    """The current notice and the log; thread-safe (events arrive on several threads).
    ``on_change()`` is called after every change, outside the board's lock."""

    def __init__(self, on_change: Callable[[], None] = lambda: None, wall_clock: Callable[[], float] = time.time) -> None:
        self._lock = threading.Lock()
        self._log: deque[LoggedNotice] = deque(maxlen=LOG_SIZE)
        self._current: LoggedNotice | None = None
        self._refused = False
        self._seq = 0
        self._robot_state: str | None = None
        self._on_change = on_change
        self._clock = wall_clock

    # -- reading -----------------------------------------------------------------------------
    @property
    def current(self) -> LoggedNotice | None:
        with self._lock:
            return self._current

    @property
    def seq(self) -> int:
        """The number of the newest notice (an action notes it when it begins)."""
        with self._lock:
            return self._seq

    def entries(self) -> list[LoggedNotice]:
        """The log, newest first."""
        with self._lock:
            return list(reversed(self._log))

    def line_markdown(self) -> str:
        with self._lock:
            return self._current.line(self._refused) if self._current is not None else ""

    def log_html(self) -> str:
        """The log as a scroll box: one line per notice, newest first, time and level."""
        rows = []
        for n in self.entries():
            stamp = time.strftime("%H:%M:%S", time.localtime(n.at))
            colour = LEVEL_COLOUR.get(n.level, "#495057")
            rule = f" (rule {html.escape(n.rule)})" if n.rule else ""
            rows.append(f'<div data-notice-level="{html.escape(n.level)}"><span style="color:#868e96">{stamp}</span> '
                        f'<b style="color:{colour}">{html.escape(n.level)}</b> {html.escape(n.message)}{rule}</div>')
        body = "".join(rows) or '<div style="color:#868e96">no notices yet</div>'
        return (f'<div data-notice-log="{len(rows)}" style="max-height:140px;overflow-y:auto;font-size:12px;'
                f'line-height:1.35;border:1px solid #dee2e6;border-radius:4px;padding:4px 6px">{body}</div>')

    # -- changing ----------------------------------------------------------------------------
    def post(self, level: str, message: str, rule: str | None, kind: str, refused: bool = False) -> None:
        with self._lock:
            self._seq += 1
            notice = LoggedNotice(self._seq, self._clock(), level, message, rule, kind, self._robot_state)
            self._log.append(notice)
            self._current, self._refused = notice, refused
        self._on_change()

    def succeeded(self, kind: str, since: int) -> None:
        """An action of ``kind`` that began when the newest notice was ``since`` succeeded: the
        current notice ends if it is of that kind, or an info note, and came before it began."""
        with self._lock:
            n = self._current
            if n is None or n.seq > since or (n.kind != kind and n.kind != NOTE):
                return
            self._current = None
        self._on_change()

    def robot_state(self, state: str | None) -> None:
        """The robot's state as the link reports it: a notice about the robot's state ends when
        the state it was posted in ends."""
        with self._lock:
            changed = state != self._robot_state
            self._robot_state = state
            n = self._current
            if not changed or n is None or n.kind != RECOVERY or n.robot_state == state:
                return
            self._current = None
        self._on_change()
