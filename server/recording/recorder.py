"""The session's recorder: every event, arm change and telemetry frame of a console session into
one MCAP file (topics in ``server.recording.records``).

The listeners run on the console's threads and only queue: anything costly (forward kinematics
for ``/tf``, the scene's meshes, JSON) is a callable the writer's thread runs. The statuses of the
sent list become one ``/statements/status`` record (and a ``/log`` line) per status reached.

Two streams are thinned where they repeat what another holds, so that recording a drag costs
the console little: ``/events/arm`` is written when something other than the pose changes (the
pose of every change is in ``/virtual/arm``: joints, tool pose, version), and ``/events/collision``
whenever the collision report changes (colliding, pairs, triangles, nearest pair, zone, joint
limit) and otherwise at most ``distance_rate_hz`` (its distances change with every move), the
last one always included. ``/tf`` follows each arm at most ``tf_rate_hz``, the last pose always.
"""

from __future__ import annotations

import logging
import os
import re
import threading
from collections.abc import Callable
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from server.console.enums import FINAL_SENT
from server.console.events import (
    ArmChanged,
    CollisionChanged,
    Notice,
    PredictedPathChanged,
    ProgramChanged,
    RangeSubmitted,
    SentChanged,
    SessionEvent,
)
from server.console.views import SentView, VirtualState
from server.recording import foxglove, records
from server.recording.writer import RecordingWriter, WriterStats
from shared.paths import PROJECT_DIR
from shared.wire.telemetry import TelemetryFrame

log = logging.getLogger(__name__)

_COLLISION = "collision"  # the thinned stream of /events/collision
_NOTHING = object()


def recording_name(cell: str, when: float) -> str:
    """``session-20261202-073512-peg_in_hole-1234.mcap``: sortable, one per console process."""
    stamp = datetime.fromtimestamp(when, tz=timezone.utc).strftime("%Y%m%d-%H%M%S")
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "_", cell)[:60] or "cell"
    return f"session-{stamp}-{safe}-{os.getpid()}.mcap"


def _project_relative(path: Path) -> str:
    path = Path(path).resolve()
    try:
        return str(path.relative_to(PROJECT_DIR))
    except ValueError:
        return str(path)


class SessionRecorder:
    """Records one ``server.console.Session`` (see the module docstring)."""

    def __init__(
        self,
        session,
        path: Path,
        *,
        cell_file: Path,
        robot_url: str | None = None,
        delay_s: float | None = None,
        on_error: Callable[[str], None] | None = None,
        tf_rate_hz: float = 30.0,
        distance_rate_hz: float = 10.0,
        **writer_options,
    ) -> None:
        """``tf_rate_hz``: most ``/tf`` messages per second and arm (every change of both arms is in
        ``/virtual/arm`` and ``/remote/telemetry``; the transforms Foxglove draws follow at this
        rate, the last pose always included); ``distance_rate_hz``: most ``/events/collision``
        messages per second that differ from the last one in distances only."""
        self.session = session
        self.path = Path(path)
        self._cell_file = cell_file
        self._robot_url, self._delay_s = robot_url, delay_s
        self.writer = RecordingWriter(self.path, on_error=on_error, idle=self._due, **writer_options)
        tf_period = int(1e9 / tf_rate_hz)
        self._period_ns = {records.VIRTUAL_PREFIX: tf_period, records.REMOTE_PREFIX: tf_period,
                           _COLLISION: int(1e9 / distance_rate_hz)}
        # per thinned stream (an arm's /tf, the collision distances): when the last went out and
        # what it was; the newest one held back, which the writer's idle call sends when due
        self._put_at: dict[str, int] = {}
        self._put_value: dict[str, object] = {}
        self._held: dict[str, tuple[tuple[str, int, object], object]] = {}
        self._arm_extra: tuple | None = None
        self._unsubscribe: list[Callable[[], None]] = []
        self._status_seen: dict[int, tuple[str, int | None]] = {}
        self._objects_seen: dict[str, list[list[float]]] | None = None
        self._lock = threading.Lock()
        robot = session.robot
        self._robot = robot
        self._world_T_base = np.asarray(session.cell.world_T_base, dtype=float)
        self._tool_T_tcp = np.asarray(session.frames.tool_T_tcp, dtype=float)
        self._fk_data = robot.new_data()  # the writer thread's own: pinocchio data is not shared

    # -- life ----------------------------------------------------------------------------------
    def start(self) -> None:
        """Open the file, write what the session is, and listen (raises ``OSError`` when the file
        cannot be made)."""
        s = self.session
        self.writer.start()
        now = self._now()
        self.writer.put(records.SESSION, now, records.SessionStart(
            cell=s.cell.name, cell_file=_project_relative(self._cell_file), robot=s.robot.name, dof=s.robot.dof,
            started_at=now * 1e-9, robot_url=self._robot_url, delay_s=self._delay_s,
        ))
        poses = {name: np.asarray(p, dtype=float) for name, p in s.arm.object_poses().items()}
        cell = s.cell
        self.writer.put(records.SCENE, now, lambda: foxglove.scene_update(cell, poses, now))
        state = s.arm.state
        self.on_arm(state)
        snap = s.snapshot()
        for event in (ProgramChanged(program=snap.program), SentChanged(sent=snap.sent)):
            self.on_event(event)
        self._unsubscribe = [s.bus.events.add(self.on_event), s.bus.arm.add(self.on_arm), s.bus.telemetry.add(self.on_telemetry)]
        log.info("recording the session to %s", self.path)

    def close(self) -> WriterStats:
        for remove in self._unsubscribe:
            remove()
        self._unsubscribe = []
        for item in self._due(force=True):
            self.writer.put(*item)
        stats = self.writer.close()
        log.info("recording %s closed: %d messages, %d dropped", self.path, stats.written, stats.dropped)
        return stats

    def _now(self) -> int:
        return int(self.session.wall_clock() * 1e9)

    # -- listeners (console threads: queue only) -----------------------------------------------
    def on_arm(self, state: VirtualState) -> None:
        t = self._now()
        q = np.array(state.q, dtype=float)
        world_T_tool = np.array(state.world_T_tcp, dtype=float)
        put = self.writer.put
        put(records.VIRTUAL_ARM, t, lambda: records.VirtualArm(q=q.tolist(), world_T_tool=world_T_tool.tolist(), version=state.version))
        self._arm_moved(records.VIRTUAL_PREFIX, q, q.tobytes(), t)

    def on_telemetry(self, frame: TelemetryFrame) -> None:
        t = self._now()
        put = self.writer.put
        put(records.TELEMETRY, t, lambda: records.Telemetry(
            robot_time=frame.time, frame=frame.frame, state=frame.state.name.lower(), mode=frame.mode.name.lower(),
            statement=frame.statement, q=list(frame.q), base_p_tool=list(frame.position), base_rpy_tool=list(frame.rpy),
            gripper=frame.gripper, wrench=list(frame.wrench),
        ))
        self._arm_moved(records.REMOTE_PREFIX, np.array(frame.q, dtype=float), tuple(frame.q), t)

    def on_event(self, event: SessionEvent) -> None:
        t = self._now()
        put = self.writer.put
        if isinstance(event, ArmChanged):  # the drag's two events first: every move has them
            self._objects_moved(event, t)
            arm = event.arm
            extra = (arm.blocked, arm.message, arm.held, arm.object_poses)
            with self._lock:
                if extra == self._arm_extra:
                    return  # the pose alone changed: /virtual/arm has it
                self._arm_extra = extra
        elif isinstance(event, CollisionChanged):
            c = event.collision
            report = (c.colliding, c.pairs, c.triangles, c.nearest, c.zone, c.zone_object, c.joint_limit)
            self._thinned(_COLLISION, (records.event_topic(event.type), t, event), report, changed=True)
            return
        elif isinstance(event, SentChanged):
            put(records.SENT, t, event.sent)
            for item in self._new_statuses(event.sent.items):
                put(records.STATUS, t, item)
                level = "info" if item.status in ("done", "received", "running", "sending") else "warning"
                number = f"#{item.number}" if item.number is not None else f"(id {item.id})"
                reason = f": {item.reason}" if item.reason else ""
                put(records.LOG, t, foxglove.log_message(t, level, f"{number} {item.text}: {item.status}{reason}", "statements"))
            return
        elif isinstance(event, ProgramChanged):
            put(records.PROGRAM, t, event.program)
            return
        elif isinstance(event, RangeSubmitted):
            put(records.SUBMITTED, t, lambda: self._submitted(event))
            put(records.LOG, t, foxglove.log_message(t, "info", "submitted: " + "; ".join(event.texts), "statements"))
            return
        elif isinstance(event, PredictedPathChanged):
            points = np.asarray(event.predicted.points, dtype=float).reshape(-1, 3)
            put(records.PREDICTED_PATH, t, lambda: foxglove.poses_in_frame(points, t))
        elif isinstance(event, Notice):
            put(records.LOG, t, foxglove.log_message(t, event.level, event.message, "console"))
        put(records.event_topic(event.type), t, event)

    # -- thinned streams: at a bounded rate, the last one always --------------------------------
    def _arm_moved(self, prefix: str, q: np.ndarray, same_q: object, t: int) -> None:
        """``same_q``: ``q`` as a value that compares cheaply (its bytes, its tuple)."""
        self._thinned(prefix, (records.TF, t, lambda: self._transforms(q, prefix, t)), same_q, changed=False)

    def _thinned(self, key: str, item: tuple[str, int, object], value, *, changed: bool) -> None:
        """Put ``item`` of the stream ``key`` now when the stream's last one is a period old, else
        hold it back as the stream's newest. ``value``: what the item shows (an arm's ``q``: one
        equal to the last one put is dropped, the arm stands still), or with ``changed``: what
        must not be thinned (one that differs from the last one put goes out at once, after the
        one held back). Values compare with ``==``: hand in bytes or tuples, not arrays."""
        t = item[1]
        first = None
        with self._lock:
            last = self._put_value.get(key, _NOTHING)
            if not changed and value == last:
                self._held.pop(key, None)  # standing still: nothing new to draw
                return
            if changed and last is not _NOTHING and value != last:
                held = self._held.pop(key, None)
                first = held[0] if held is not None else None
            elif t - self._put_at.get(key, -self._period_ns[key]) < self._period_ns[key]:
                self._held[key] = (item, value)  # the writer's idle call sends it when due
                return
            self._put_at[key], self._put_value[key] = t, value
            self._held.pop(key, None)
        if first is not None:
            self.writer.put(*first)
        self.writer.put(*item)

    def _due(self, force: bool = False) -> list[tuple[str, int, object]]:
        """The held-back newest of each thinned stream that is due (the writer's thread, often)."""
        if not self._held:
            return []
        now = self._now()
        due = []
        with self._lock:
            for key, (item, value) in list(self._held.items()):
                if force or now - self._put_at.get(key, -self._period_ns[key]) >= self._period_ns[key]:
                    self._put_at[key], self._put_value[key] = item[1], value
                    del self._held[key]
                    due.append(item)
        return due

    # -- derived (small, on the caller's thread) -----------------------------------------------
    def _new_statuses(self, items: list[SentView]) -> list[records.StatementStatus]:
        out = []
        with self._lock:
            for s in items:
                key = (s.status.value, s.number)
                if self._status_seen.get(s.id) == key:
                    continue
                self._status_seen[s.id] = key
                out.append(records.StatementStatus(
                    id=s.id, number=s.number, text=s.text, status=s.status.value, final=s.status in FINAL_SENT,
                    reason=s.reason, submitted_at=s.submitted_at, answered_at=s.answered_at,
                    started_at=s.started_at, finished_at=s.finished_at,
                ))
        return out

    def _objects_moved(self, event: ArmChanged, t: int) -> None:
        poses = event.arm.object_poses
        with self._lock:
            if poses == self._objects_seen:
                return
            first = self._objects_seen is None
            self._objects_seen = poses
        if first:
            return  # the scene at the start has them
        arrays = {name: np.asarray(p, dtype=float) for name, p in poses.items()}
        cell = self.session.cell
        self.writer.put(records.SCENE, t, lambda: foxglove.object_entities(cell, arrays, t))

    # -- on the writer's thread ----------------------------------------------------------------
    def _transforms(self, q: np.ndarray, prefix: str, t: int) -> dict:
        return foxglove.frame_transforms(self._robot, q, self._world_T_base, prefix, t, tool_T_tcp=self._tool_T_tcp,
                                         data=self._fk_data)

    def _submitted(self, event: RangeSubmitted) -> records.RangeSubmitted:
        plan = None
        if event.start_q is not None and event.plan_q:
            frames = self.session.frames
            q = np.asarray(event.plan_q, dtype=float)
            tool = np.array([(frames.world_T_base @ self._robot.fk(row, self._fk_data) @ frames.tool_T_tcp)[:3, 3] for row in q])
            plan = records.PlannedPath(
                t=event.plan_t, q=event.plan_q, world_p_tool=tool.tolist(), statement_starts=event.statement_starts,
                statement_ends=event.statement_ends, complete=event.complete,
            )
        return records.RangeSubmitted(ids=event.ids, texts=event.texts, start_q=event.start_q, plan=plan)


def record_session(session, settings, *, started_link: bool) -> SessionRecorder | None:
    """Start recording ``session`` as ``settings`` say (``ConsoleSettings.record``,
    ``record_dir``); None when recording is off or the file cannot be made (logged and shown as a
    notice: the console runs on unrecorded)."""
    if not settings.record:
        return None
    when = session.wall_clock()
    path = Path(settings.record_dir) / recording_name(session.cell.name, when)

    def failed(message: str) -> None:
        session.bus.emit([Notice(level="error", message=f"{message}; the session goes on unrecorded")])

    recorder = SessionRecorder(
        session, path, cell_file=Path(settings.cell), robot_url=settings.robot_url,
        delay_s=settings.delay_ms / 1000.0 if started_link else None, on_error=failed,
        queue_size=settings.record_queue, flush_s=settings.record_flush_s,
    )
    try:
        recorder.start()
    except OSError as exc:
        failed(f"cannot record to {path}: {exc.strerror or exc}")
        log.error("cannot record to %s: %s", path, exc)
        return None
    return recorder
