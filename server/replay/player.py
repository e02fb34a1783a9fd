"""The replay's session state: one recording open, a playhead, play and pause, stepping.

``ReplayPlayer.open(path)`` reads a recording (``server.recording.reader``), loads the cell it
was recorded on, indexes its timeline (``server.replay.timeline``) and compares each submitted
range with what the robot reported (``server.replay.comparison``). The playhead moves by
``seek``, ``step`` (to the next or previous mark) and ``play`` (a thread advancing it at
``speed`` times real time, 20 times a second, stopping at the end). Listeners hear each new
moment and each newly opened recording; the page and the API are two such clients.

Read-only: nothing here reaches a robot or changes the recording.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from pydantic import BaseModel, Field, ValidationError

from server.recording.reader import Recording, list_recordings, read_recording
from server.replay.comparison import RangeComparison, compare_ranges
from server.replay.timeline import Mark, Moment, Timeline
from shared.cells.cell import Cell
from shared.cells.loader import load_cell
from shared.errors import InputError
from shared.files import name_in_folder, regular_file, shown_name
from shared.paths import PROJECT_DIR

log = logging.getLogger(__name__)

SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0, 10.0)
TICK_S = 0.05


@dataclass(frozen=True)
class OpenedReplay:
    """A recording ready to scrub."""

    path: Path
    recording: Recording
    timeline: Timeline
    cell: Cell
    comparisons: list[RangeComparison]


def open_replay(path: str | Path) -> OpenedReplay:
    """Read ``path`` and everything the replay needs of it (``InputError`` with a sentence when
    it is not a recording, is damaged where the session starts, holds nothing, or its cell cannot
    be loaded). ``path`` is taken as given: a name a client gives goes through
    ``ReplayPlayer.open``, which keeps it inside the replay's folder."""
    path = Path(path)
    recording = read_recording(path)
    start = recording.session
    if start is None:
        if recording.damage:
            raise InputError(f"{path}: damaged recording: {recording.damage}; the session start was in what is lost")
        raise InputError(f"{path}: the recording holds no session start (nothing of the session could be read)")
    cell_path = Path(start.cell_file)
    if not cell_path.is_absolute():
        cell_path = PROJECT_DIR / cell_path
    try:
        regular_file(cell_path, "cell file")  # a recording names its cell: never a FIFO to wait on
        cell = load_cell(cell_path)
    except InputError as exc:
        raise InputError(f"{path}: the cell it was recorded on cannot be loaded: {exc}") from None
    except OSError as exc:
        raise InputError(f"{path}: the cell it was recorded on cannot be loaded: {cell_path}: "
                         f"{exc.strerror or type(exc).__name__}") from None
    try:
        timeline = Timeline(recording)
        comparisons = compare_ranges(recording, cell.world_T_base)
    except ValidationError as exc:  # a record that is valid JSON but not what the console writes
        err = exc.errors()[0]
        where = ".".join(str(p) for p in err.get("loc", ())) or "a record"
        raise InputError(f"{path}: damaged recording: a record is not one the console writes "
                         f"({exc.title}: {where}: {err.get('msg', 'invalid')})") from None
    return OpenedReplay(path, recording, timeline, cell, comparisons)


class MarkOut(BaseModel):
    t_s: float = Field(description="s from the recording's start")
    kind: str
    text: str


class SentOut(BaseModel):
    number: int | None
    text: str
    status: str


class ReplayView(BaseModel):
    """Where the replay stands (``GET /api/replay``)."""

    file: str
    cell: str
    complete: bool = Field(description="the console closed the file (false: cut off, or being written)")
    writing: bool = Field(False, description="a console is writing the file now: not closed yet, not cut off")
    problem: str | None = Field(None, description="what could not be read, in a sentence")
    duration_s: float
    t_s: float = Field(description="the playhead, s from the start")
    playing: bool
    speed: float
    marks: int = Field(description="moments to step between")
    mark: MarkOut | None = Field(None, description="the last mark at or before the playhead")
    remote_state: str | None = None
    remote_age_s: float | None = Field(None, description="age of the state the ghost showed then (s)")
    predicted_points: int = Field(0, description="points of the predicted path shown then")
    sent: list[SentOut] = Field(default_factory=list, description="the sent list as it was then")
    regime: str | None = None
    link: str | None = None
    ranges: list[list[str]] = Field(default_factory=list, description="each submitted range compared, in sentences")


class ReplayPlayer:
    """See the module docstring. Thread-safe; listeners are called outside the lock."""

    def __init__(self, opened: OpenedReplay, folder: Path) -> None:
        self.folder = Path(folder)
        self._given = opened.path  # the file named on the command line, wherever it is
        self._lock = threading.RLock()
        self._opened = opened
        self._t_ns = opened.timeline.start
        self._playing = False
        self._speed = 1.0
        self._moment_listeners: list[Callable[[Moment], None]] = []
        self._open_listeners: list[Callable[[OpenedReplay], None]] = []
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread = threading.Thread(target=self._run, name="replay-clock", daemon=True)
        self._thread.start()

    # -- what is open ---------------------------------------------------------------------------
    @property
    def opened(self) -> OpenedReplay:
        return self._opened

    def moment(self) -> Moment:
        with self._lock:
            return self._opened.timeline.at(self._t_ns)

    def on_moment(self, listener: Callable[[Moment], None]) -> None:
        self._moment_listeners.append(listener)

    def on_open(self, listener: Callable[[OpenedReplay], None]) -> None:
        self._open_listeners.append(listener)

    def path_of(self, name: str | Path) -> Path:
        """Where the recording a client names is: inside ``folder`` only (a name, or a path that
        leads into it; ``..``, another absolute path or a symlink leading out is refused), or the
        file given on the command line, by its own name. ``InputError`` names what is refused."""
        name = str(name)
        own = name == self._given.name  # the command line's file, by its name
        try:
            path = name_in_folder(self.folder, name, "recording")
        except InputError:
            if own:
                return self._given
            raise
        if not path.exists():
            if own:
                return self._given
            names = [r.name for r in list_recordings(self.folder)]
            listed = ", ".join(names[:10]) + (f" (and {len(names) - 10} more)" if len(names) > 10 else "")
            raise InputError(f"no recording {shown_name(name)} in {self.folder.resolve()}; valid: {listed or '(none)'}")
        return path

    def open(self, name: str | Path) -> OpenedReplay:
        """Open another recording by its name in the folder (``path_of``); raises ``InputError``
        (a name outside the folder, a special file, a damaged or foreign file)."""
        path = self.path_of(name)
        opened = open_replay(path)
        with self._lock:
            self._opened = opened
            self._t_ns = opened.timeline.start
            self._playing = False
        log.info("replaying %s", path)
        for listener in list(self._open_listeners):
            listener(opened)
        self._publish()
        return opened

    # -- the playhead ---------------------------------------------------------------------------
    def seek(self, t_s: float, *, pause: bool = False) -> Moment:
        """Move the playhead to ``t_s`` (s from the start, clamped); ``pause``: stop playing too."""
        with self._lock:
            self._t_ns = self._opened.timeline.t_ns(float(t_s))
            if pause:
                self._playing = False
        return self._publish()

    def step(self, direction: int) -> Mark | None:
        """To the next (``direction`` > 0) or previous mark; pauses. None: no mark that way (the
        playhead goes to the end or the start)."""
        with self._lock:
            self._playing = False
            timeline = self._opened.timeline
            mark = timeline.next_mark(self._t_ns) if direction > 0 else timeline.previous_mark(self._t_ns)
            if mark is not None:
                self._t_ns = mark.t_ns
            else:
                self._t_ns = timeline.end if direction > 0 else timeline.start
        self._publish()
        return mark

    def play(self, speed: float | None = None) -> None:
        with self._lock:
            if speed is not None:
                self.set_speed(speed)
            timeline = self._opened.timeline
            if self._t_ns >= timeline.end:
                self._t_ns = timeline.start  # at the end, play starts over
            self._playing = True
        self._wake.set()
        self._publish()

    def pause(self) -> None:
        with self._lock:
            self._playing = False
        self._publish()

    def set_speed(self, speed: float) -> None:
        speed = float(speed)
        if not 0.01 <= speed <= 100.0:
            raise InputError(f"replay speed {speed:g}: must be between 0.01 and 100 times real time")
        with self._lock:
            self._speed = speed

    @property
    def playing(self) -> bool:
        return self._playing

    def close(self) -> None:
        self._stop.set()
        self._wake.set()
        self._thread.join(timeout=2.0)

    # -- views ----------------------------------------------------------------------------------
    def view(self) -> ReplayView:
        with self._lock:
            opened, playing, speed = self._opened, self._playing, self._speed
            m = opened.timeline.at(self._t_ns)
        r = opened.recording
        sent = [SentOut(number=s.number, text=s.text, status=s.status.value) for s in (m.sent.items if m.sent else [])]
        mark = None
        if m.last_mark is not None:
            mark = MarkOut(t_s=(m.last_mark.t_ns - opened.timeline.start) * 1e-9, kind=m.last_mark.kind, text=m.last_mark.text)
        return ReplayView(
            file=str(opened.path), cell=opened.cell.name, complete=r.complete, writing=r.writing, problem=r.problem,
            duration_s=opened.timeline.duration_s, t_s=m.t_s, playing=playing, speed=speed,
            marks=len(opened.timeline.marks), mark=mark, remote_state=m.remote_state, remote_age_s=m.remote_age_s,
            predicted_points=len(m.predicted), sent=sent, regime=m.regime, link=m.link_status,
            ranges=[c.lines() for c in opened.comparisons],
        )

    def marks(self) -> list[MarkOut]:
        timeline = self._opened.timeline
        return [MarkOut(t_s=(k.t_ns - timeline.start) * 1e-9, kind=k.kind, text=k.text) for k in timeline.marks]

    # -- inside ---------------------------------------------------------------------------------
    def _publish(self) -> Moment:
        moment = self.moment()
        for listener in list(self._moment_listeners):
            try:
                listener(moment)
            except Exception:  # noqa: BLE001 - one broken view never stops the replay
                log.exception("a replay listener failed")
        return moment

    def _run(self) -> None:
        last = time.monotonic()
        while not self._stop.is_set():
            if not self._playing:
                self._wake.wait(0.5)
                self._wake.clear()
                last = time.monotonic()
                continue
            time.sleep(TICK_S)
            now = time.monotonic()
            with self._lock:
                if not self._playing:
                    continue
                timeline = self._opened.timeline
                self._t_ns = min(timeline.end, self._t_ns + round((now - last) * self._speed * 1e9))
                if self._t_ns >= timeline.end:
                    self._playing = False
            last = now
            self._publish()
