"""The console's session: everything one operator console knows and does (thesis §4.2, §4.3).

One ``Session`` per console process holds

* the virtual arm the operator drives (``state``: a ``VirtualState``) and the virtual world's
  moved objects (what the gripper holds);
* the program editor (``shared.program.editor.Editor``) and the automatic generator
  (``shared.program.generator.ProgramGenerator``) fed from the arm's motion: every jog is a
  sample; ``release()`` (the operator lets go) flushes the open segment;
* the preview player (``shared.motion.plan_program`` from the program's start state; play,
  pause, step, seek; collision and joint-limit warnings from ``shared.collision``);
* the sent list, STOP/resume/skip/abort and the link to the robot (a ``RobotClient`` running on
  the app's asyncio loop, attached with ``attach_robot``);
* the remote arm from telemetry, the predicted path of submitted-not-done statements, the
  collision report and control zone of the virtual arm, the regime (§4.2.1), the display mode
  (§4.3.7), divergence detection and re-sync (§4.2.3), and one control lock.

Threading: methods may be called from any thread (viser's handlers, uvicorn's worker threads,
the asyncio loop's callbacks). State changes happen under one re-entrant lock, never held
across an ``await`` or while listeners run; events are published after the lock is released.
Calls that reach the robot are scheduled on the loop with ``run_coroutine_threadsafe`` and never
waited for, so a 3 s link never blocks the page.

Listeners: ``subscribe(fn(VirtualState))`` is the fast path for the 3D scene (every arm change);
``subscribe_events(fn(SessionEvent))`` receives typed events (``server.console_models``).

Errors: ``shared.errors.InputError`` for malformed input (HTTP 400), ``ConflictError`` /
``RefusedByRule`` when the state forbids an action now (409), other ``TeleprogError`` (e.g. a joint
limit) 422. Every mutating method takes ``client``: the caller (``server.console_models.Caller``:
the name it declares and the control token it presents; a bare name or ``None``, the page served
by this console, presents none). While a client holds the control lock, only calls presenting its
token change anything (STOP excepted); everybody else observes. The token is returned to the
holder alone; views and events name the holder by its label.
"""

from __future__ import annotations

import asyncio
import copy
import logging
import secrets
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import PurePath

import numpy as np

from server.console_models import (
    ArmChanged,
    ArmView,
    CollisionChanged,
    Caller,
    CollisionView,
    ConflictError,
    ControlChanged,
    ControlGrant,
    ControlLockError,
    ControlTakeover,
    ControlView,
    DisplayMode,
    DisplayModeChanged,
    DivergenceChanged,
    DivergenceView,
    FINAL_SENT,
    LinkChanged,
    LinkView,
    LocatedView,
    NotConnectedError,
    Notice,
    PlacementChanged,
    PlacementView,
    PredictedPathChanged,
    PredictedPathView,
    PreviewChanged,
    PreviewView,
    PreviewWarning,
    ProgramChanged,
    ProgramView,
    RefusedByRule,
    Regime,
    RegimeChanged,
    RegimeView,
    RemoteArmChanged,
    RemoteArmView,
    SentChanged,
    SentListView,
    SentStatus,
    SentView,
    SessionEvent,
    SessionSnapshot,
    StatementView,
    TerrainChanged,
    TerrainView,
)
from server.robot_client import RobotRestarted
from server.terrain_layer import TerrainLayer
from shared.cells.cell import Cell
from shared.collision import SceneModel, zone
from shared.errors import InputError, TeleprogError, UnknownNameError
from shared.language.formatter import format_program, format_statement
from shared.language.parser import parse_json, parse_program, parse_statement
from shared.language.statements import (
    Draw, Frame, Mode, SetMode, Speed, SpeedUnit, Statement, TaskCall, Until, is_action, program_to_json,
)
from shared.motion import Plan, plan_program
from shared.program.editor import KEEP, Editor, ProgramState, Refusal
from shared.program.generator import ControlMode, GeneratorSettings, ProgramGenerator, RobotSample
from shared.robots.jog import JogFrames, JogResult, jog_joint, jog_tool, jog_tool_to, world_T_tcp
from shared.spatial import invert, matrix_to_rpy, pose_to_transform
from shared.vision.pose import locate_object as locate_object_pose
from shared.wire.messages import RobotState

log = logging.getLogger(__name__)

__all__ = ["Session", "SessionSettings", "VirtualState"]

_ZONE_RANK = {"free": 0, "quasi": 1, "operation": 2}


@dataclass(frozen=True)
class _Pair:
    """Two touching bodies (as the collision report names them)."""

    a: str
    b: str


@dataclass(frozen=True)
class VirtualState:
    """A snapshot of the virtual robot: joint vector (rad), tool point pose in the world, and
    the last jog's outcome."""

    q: np.ndarray
    world_T_tcp: np.ndarray
    last_jog: JogResult | None = None
    version: int = 0


Listener = Callable[[VirtualState], None]
EventListener = Callable[[SessionEvent], None]


@dataclass(frozen=True)
class SessionSettings:
    """Thresholds and rates of the session (SI)."""

    divergence_joint: float = np.radians(1.0)
    """rad: a joint differing more than this between virtual/predicted and reported arm diverges."""
    divergence_tool: float = 0.002
    """m: a tool point further than this from where it should be diverges."""
    locate_max_residual_px: float = 3.0
    """pixels: picked image points that reproject worse than this do not locate an object."""
    preview_dt: float = 0.05
    """s: spacing of the preview samples checked for collisions and joint limits."""
    preview_max_samples: int = 600
    player_rate_hz: float = 30.0
    """how often a playing preview advances and is published."""
    remote_event_hz: float = 10.0
    """how often telemetry is published as a ``RemoteArmChanged`` event."""
    link_poll_s: float = 0.25
    predicted_points: int = 60
    gripper_closed_below: float = 0.03
    """m: a reported gripper opening below this counts as holding."""
    back_away_distance: float = 0.03
    """m: how far "back away" moves the tool out of a contact."""
    back_away_speed: float = 0.01
    """m/s: the tool speed of a back-away motion."""
    generator: GeneratorSettings = field(default_factory=GeneratorSettings)


@dataclass
class _Sent:
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

    def view(self) -> SentView:
        run = self.finished_at - self.started_at if self.finished_at is not None and self.started_at is not None else None
        return SentView(
            id=self.id, number=self.number, text=_statement_text(self.statement), statement=self.statement,
            status=self.status, reason=self.reason, submitted_at=self.submitted_at, answered_at=self.answered_at,
            started_at=self.started_at, finished_at=self.finished_at, run_s=run,
        )


def _statement_text(statement: Statement) -> str:
    """The statement as text; one that cannot be written (a value no statement may hold) is
    named by its kind and why, so the sent list can always be shown."""
    try:
        return format_statement(statement)
    except Exception as exc:  # noqa: BLE001 - a list of what was sent must never fail to render
        return f"{getattr(statement, 'kind', type(statement).__name__)} (cannot be written: {exc})"


@dataclass
class _Preview:
    start: int
    stop: int
    plan: Plan
    t0: float  # program time where the range starts
    duration: float
    warnings: list[PreviewWarning]
    refusal: str | None
    t: float = 0.0
    playing: bool = False
    rate: float = 1.0


def _as_caller(client: Caller | str | None) -> Caller:
    """A ``Caller`` from what the session's methods accept as ``client``."""
    if isinstance(client, Caller):
        return client
    return Caller(name=client or None)


def _plan(statements: list[Statement], robot, cell: Cell, start_q: np.ndarray) -> Plan:
    """``plan_program`` from ``start_q``; a numerical failure of the planner on what it was given
    (an overflow, a NaN reaching an index) is refused as ``InputError`` naming it, never raised
    as itself."""
    try:
        with np.errstate(all="ignore"):
            return plan_program(statements, robot, cell, start_q=start_q)
    except TeleprogError:
        raise
    except (ArithmeticError, ValueError, IndexError, np.linalg.LinAlgError) as exc:
        log.warning("planning %d statement(s) failed: %r", len(statements), exc)
        raise InputError(f"the statements cannot be planned: {type(exc).__name__}: {exc}") from None


def _locate_or_refuse(camera, keypoints: np.ndarray, px: np.ndarray):
    """``shared.vision.pose.locate_object``, with pixels that cannot determine a pose refused as
    ``InputError`` instead of a numerical failure (SVD not converging, a NaN pose)."""
    if not np.all(np.isfinite(px)):
        raise InputError("pixels are degenerate: every u and v must be a finite number")
    distinct = len({(float(u), float(v)) for u, v in px})
    if distinct < len(px):
        raise InputError(f"pixels are degenerate: {len(px) - distinct + 1} of the {len(px)} points are at the same pixel")
    try:
        with np.errstate(all="ignore"):
            located = locate_object_pose(camera, keypoints, px)
    except (np.linalg.LinAlgError, ArithmeticError, ValueError) as exc:
        raise InputError(f"pixels are degenerate: no pose fits them ({exc})") from None
    if not (np.all(np.isfinite(located.world_T_object)) and np.isfinite(located.residual_px)):
        raise InputError("pixels are degenerate: no finite pose fits them")
    return located


def _copy_editor(editor: Editor) -> Editor:
    """An editor with the same state and its own copy of the undo/redo history (the states in
    it are immutable), to try an operation on."""
    trial = copy.copy(editor)
    trial._undo = list(editor._undo)  # noqa: SLF001 - the editor's own lists, copied not changed
    trial._redo = list(editor._redo)  # noqa: SLF001
    return trial


def _checked_statement(statement: Statement) -> Statement:
    """``statement`` validated again by its own model and formatted once; ``InputError`` (a
    validation error) or the formatter's error names what is wrong."""
    from pydantic import ValidationError

    try:
        checked = type(statement).model_validate(statement.model_dump())
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first.get("loc", ()))
        raise InputError(f"{statement.kind}: {where + ': ' if where else ''}{first.get('msg', 'invalid')}") from None
    format_statement(checked)  # raises InputError for what cannot be written (a NaN, say)
    return checked


def _m(a: np.ndarray) -> list[list[float]]:
    return np.asarray(a, dtype=float).tolist()


def _link_problems(h, children: dict[str, str]) -> list[str]:
    """What is wrong with the link, one line each, for the status bar (``h``: ``ChannelHealth``)."""
    out = [f"{name} {what}" for name, what in children.items() if not what.startswith("running")]
    if h.command == "down":
        out.append("link down")
    elif h.command == "silent":
        out.append(f"robot silent for {h.heard_ago_s:.1f} s")
    if h.telemetry == "stale":
        out.append(f"telemetry stale ({h.telemetry_ago_s:.1f} s)")
    if h.halted:
        out.append(f"robot halted by itself: {h.halted}")
    if h.buffer_full:
        out.append(f"robot buffer full: {h.buffer_full}")
    if h.errors:
        out.append(f"{h.errors} error(s) handling the robot's messages; last: {h.last_error}")
    return out


class Session:
    """One operator console's state and actions (see the module docstring)."""

    def __init__(
        self,
        cell: Cell,
        settings: SessionSettings | None = None,
        clock: Callable[[], float] = time.monotonic,
        scene: SceneModel | None = None,
    ) -> None:
        """``scene``: the cell's collision model when the caller already built it (it is immutable
        and takes seconds to build); ``clock``: monotonic seconds, for the generator's samples."""
        self.cell = cell
        self.robot = cell.robot
        self.settings = settings or SessionSettings()
        self.frames = JogFrames(cell.world_T_base, cell.frame("work"), cell.flange_T_tcp)
        self._clock = clock
        self._lock = threading.RLock()
        self._listeners: list[Listener] = []
        self._event_listeners: list[EventListener] = []
        q0 = cell.q_home.copy()
        self._state = VirtualState(q0, world_T_tcp(self.robot, q0, self.frames))
        # a terrain cell's ground is checked by its own tree (server.terrain_layer), not the scene
        self.terrain = TerrainLayer.for_cell(cell)
        self._terrain_view: TerrainView | None = None
        exclude = (TerrainLayer.NAME,) if self.terrain is not None else ()
        self._scene = scene if scene is not None else SceneModel.from_cell(cell, exclude=exclude)
        self._scene_data = self._scene.new_data()
        self._tool_body = f"link{self.robot.dof}"
        # virtual world: held object and moved objects (world_T_object)
        self._held: str | None = None
        self._tcp_T_held: np.ndarray | None = None
        self._object_poses: dict[str, np.ndarray] = {}
        # program
        self._editor = Editor()
        self._auto = False
        self._generator = ProgramGenerator(self.settings.generator, world_T_base=cell.world_T_base, world_T_work=cell.frame("work"))
        self._gen_mode: ControlMode | None = None
        self._start_q = q0.copy()
        self._start_source: str = "model"
        self._start_unknown = False  # the predicted end lies after a task whose end only the robot knows
        self._confirmed: tuple[int, int, tuple] | None = None
        # preview
        self._preview: _Preview | None = None
        self._player: threading.Thread | None = None
        self._player_wake = threading.Event()
        self._closing = False
        # regime, display, lock
        self._override: Regime | None = None
        self._display = DisplayMode.TELEPROGRAMMING
        self._display_before_preview = DisplayMode.TELEPROGRAMMING
        self._holder: str | None = None
        self._holder_since: float | None = None
        self._holder_token: str | None = None
        self._takeover: ControlTakeover | None = None
        # robot link
        self._client = None  # server.robot_client.RobotClient
        self._loop: asyncio.AbstractEventLoop | None = None
        self._url: str | None = None
        self._sent: list[_Sent] = []
        self._by_number: dict[int, _Sent] = {}
        self._early_reports: dict[int, list] = {}
        self._comm_counter = 0
        self._robot_mode = Mode.POSITION
        self._rtts: list[float] = []
        self._recovery_pending: dict[int, str] = {}
        self._recovery_counter = 0
        self._telemetry = None
        self._telemetry_at: float | None = None
        self._last_remote_emit = 0.0
        self._remote_held: str | None = None
        self._remote_tcp_T_held: np.ndarray | None = None
        self._remote_poses: dict[str, np.ndarray] = {}  # where released objects were left
        self._remote_data = self.robot.new_data()
        self._predicted = PredictedPathView()
        self._divergence = DivergenceView(threshold_joint=self.settings.divergence_joint, threshold_tool=self.settings.divergence_tool)
        self._last_link: LinkView | None = None
        self._children: Callable[[], dict[str, str]] | None = None
        self._collision = self._compute_collision(self._state)
        self._zone = self._collision.zone

    # =========================================================================== reading
    @property
    def state(self) -> VirtualState:
        """The virtual arm now."""
        with self._lock:
            return self._state

    @property
    def editor_state(self) -> ProgramState:
        with self._lock:
            return self._editor.state

    @property
    def display_mode(self) -> DisplayMode:
        return self._display

    def subscribe(self, listener: Listener) -> None:
        """Call ``listener(VirtualState)`` after every change of the virtual arm (fast path)."""
        with self._lock:
            self._listeners.append(listener)

    def subscribe_events(self, listener: EventListener) -> Callable[[], None]:
        """Call ``listener(event)`` for every ``SessionEvent``; returns a function that unsubscribes."""
        with self._lock:
            self._event_listeners.append(listener)

        def unsubscribe() -> None:
            with self._lock:
                if listener in self._event_listeners:
                    self._event_listeners.remove(listener)

        return unsubscribe

    def snapshot(self) -> SessionSnapshot:
        """Every view at once."""
        with self._lock:
            return SessionSnapshot(
                cell=self.cell.name, robot=self.robot.name, dof=self.robot.dof, arm=self.arm_view(),
                program=self.program_view(), preview=self.preview_view(), sent=self.sent_view(),
                link=self.link_view(), remote=self.remote_view(), predicted=self._predicted,
                collision=self._collision, regime=self.regime_view(), display=self._display,
                divergence=self._divergence, control=self.control_view(),
            )

    def arm_view(self) -> ArmView:
        with self._lock:
            s = self._state
            jog = s.last_jog
            return ArmView(
                q=s.q.tolist(), q_deg=np.degrees(s.q).tolist(), world_T_tcp=_m(s.world_T_tcp),
                tool_xyz_mm=(s.world_T_tcp[:3, 3] * 1e3).tolist(),
                tool_rpy_deg=np.degrees(matrix_to_rpy(s.world_T_tcp[:3, :3])).tolist(),
                blocked=jog.blocked if jog else None, message=jog.message if jog else "", version=s.version,
                held=self._held, object_poses={k: _m(v) for k, v in self._object_poses.items()},
            )

    def program_view(self) -> ProgramView:
        with self._lock:
            st = self._editor.state
            entries = [
                StatementView(index=i, kind=s.kind, text=format_statement(s), statement=s) for i, s in enumerate(st.statements)
            ]
            entries.append(StatementView(index=st.empty_index, kind="EMPTY", text="", statement=None))
            return ProgramView(
                entries=entries, selected=st.selected_index, empty_index=st.empty_index, preview=st.preview,
                can_undo=self._editor.can_undo, can_redo=self._editor.can_redo, undo_label=self._editor.undo_label,
                redo_label=self._editor.redo_label, auto_generate=self._auto, start_q=self._start_q.tolist(),
                start_source=self._start_source, confirmed=self._confirmed_range(),
            )

    def preview_view(self) -> PreviewView:
        with self._lock:
            p = self._preview
            if p is None:
                return PreviewView()
            q = self._preview_q(p)
            ts = p.plan.start_times
            current = int(np.searchsorted(ts, p.t0 + p.t, side="right") - 1) if len(ts) else None
            if current is not None:
                current = min(max(current, p.start), p.stop - 1)
            report = self._scene.check(q, object_poses=self._object_poses or None, distances="none", skip=self._held_skip(), data=self._scene_data)
            tris = {b: report.interfering_triangles(b).tolist() for b in {n for pr in report.pairs for n in (pr.a, pr.b)}}
            on_ground = bool(self.terrain.touches(q)) if self.terrain is not None else False
            return PreviewView(
                active=True, start=p.start, stop=p.stop, playing=p.playing, t=p.t, duration=p.duration, rate=p.rate,
                current=current, q=q.tolist(), warnings=list(p.warnings), colliding_now=report.colliding or on_ground, triangles=tris,
                refusal=p.refusal,
            )

    def sent_view(self) -> SentListView:
        with self._lock:
            return SentListView(items=[s.view() for s in self._sent], pending=sum(s.status not in FINAL_SENT for s in self._sent))

    def link_view(self) -> LinkView:
        with self._lock:
            client = self._client
            now = self._clock()
            rtt = float(np.median(self._rtts[-5:])) if self._rtts else None
            delay = rtt / 2 if rtt is not None else None
            ago = now - self._telemetry_at if self._telemetry_at is not None else None
            frame = self._telemetry
            recovery = list(self._recovery_pending.values())
        children = self._children_status()
        if client is None:
            return LinkView(configured=self._url is not None, url=self._url, children=children,
                            problems=[f"{name} {what}" for name, what in children.items() if not what.startswith("running")])
        h = client.health()
        fresh = frame is not None and h.telemetry == "live"
        problems = _link_problems(h, children)
        return LinkView(
            configured=True, url=self._url, connected=h.connected,
            delay_s=delay, round_trip_s=rtt, telemetry_received_ago_s=ago,
            telemetry_age_s=None if ago is None else ago + (delay or 0.0),
            reconnects=client.reconnects,
            robot_state=frame.state.name.lower() if fresh else None,
            recovery_pending=recovery, status=h.command, heard_ago_s=h.heard_ago_s, silence_limit_s=h.silence_limit_s,
            telemetry=h.telemetry, halted=h.halted, errors=h.errors, last_error=h.last_error, refused=h.refused,
            buffer_full=h.buffer_full, robot_session=h.session_id, robot_restarts=h.restarts, children=children,
            problems=problems,
        )

    def watch_children(self, status: Callable[[], dict[str, str]]) -> None:
        """``status()`` names the processes ``teleprog up`` started and how each is (shown in
        the link view)."""
        with self._lock:
            self._children = status

    def _children_status(self) -> dict[str, str]:
        fn = self._children
        if fn is None:
            return {}
        try:
            return dict(fn())
        except Exception:  # noqa: BLE001 - the link view must always answer
            log.exception("reading the children's status failed")
            return {"children": "status unknown"}

    def remote_view(self) -> RemoteArmView | None:
        """The remote arm from the newest telemetry frame, or ``None`` before the first one."""
        with self._lock:
            frame = self._telemetry
            if frame is None:
                return None
            q = np.array(frame.q, dtype=float)
            link = self.link_view()
            world_T_tcp_remote = self._remote_tcp(q)
            poses = {k: v for k, v in self._remote_poses.items()}
            if self._remote_held is not None and self._remote_tcp_T_held is not None:
                poses[self._remote_held] = world_T_tcp_remote @ self._remote_tcp_T_held
            return RemoteArmView(
                q=q.tolist(), world_T_tcp=_m(world_T_tcp_remote), age_s=link.telemetry_age_s,
                state=frame.state.name.lower(), statement=frame.statement, gripper=frame.gripper,
                force_n=list(frame.wrench[:3]), held=self._remote_held, object_poses={k: _m(v) for k, v in poses.items()},
            )

    def predicted_view(self) -> PredictedPathView:
        with self._lock:
            return self._predicted

    def collision_view(self) -> CollisionView:
        with self._lock:
            return self._collision

    def regime_view(self) -> RegimeView:
        with self._lock:
            return RegimeView(regime=self._override or self._zone, zone=self._zone, override=self._override)

    @property
    def regime(self) -> Regime:
        with self._lock:
            return self._override or self._zone

    def divergence_view(self) -> DivergenceView:
        with self._lock:
            return self._divergence

    def control_view(self) -> ControlView:
        """Who holds control, as everybody may see it: the holder's label, never its token."""
        with self._lock:
            return ControlView(holder=self._holder, since=self._holder_since, last_takeover=self._takeover)

    # =========================================================================== control lock
    def request_control(self, client: Caller | str) -> ControlGrant:
        """Take the control lock for the caller (a non-empty name); the grant holds the token that
        later calls present. Refused while another holds it; asking again with the token gives
        the same grant."""
        caller = _as_caller(client)
        if not caller.name:
            raise InputError("a client name is needed to take control (header X-Teleprog-Client)")
        with self._lock:
            if self._holder is not None:
                if self._presents_token(caller):
                    return self._grant()
                raise ControlLockError(
                    f"control is held by {self._holder!r}; ask it to release control, or take over "
                    "explicitly with POST /api/control/takeover"
                )
            self._holder, self._holder_since = caller.name, time.time()
            self._holder_token = secrets.token_urlsafe(16)
            grant = self._grant()
        log.info("control taken by %r", caller.name)
        self._emit([ControlChanged(control=self.control_view())])
        return grant

    def takeover_control(self, client: Caller | str) -> ControlGrant:
        """Take the control lock whoever holds it (an explicit, logged take-over): the former
        holder's token stops working, and the control view and a notice say who took over when."""
        caller = _as_caller(client)
        if not caller.name:
            raise InputError("a client name is needed to take over control (header X-Teleprog-Client)")
        with self._lock:
            if self._holder is not None and self._presents_token(caller):
                return self._grant()
            former = self._holder
            now = time.time()
            if former is not None:
                self._takeover = ControlTakeover(by=caller.name, former=former, at=now)
            self._holder, self._holder_since = caller.name, now
            self._holder_token = secrets.token_urlsafe(16)
            grant = self._grant()
        events: list[SessionEvent] = [ControlChanged(control=self.control_view())]
        if former is not None:
            log.warning("control taken over by %r from %r", caller.name, former)
            events.append(Notice(level="warning", message=f"control taken over by {caller.name!r} from {former!r}"))
        else:
            log.info("control taken by %r (nobody held it)", caller.name)
        self._emit(events)
        return grant

    def release_control(self, client: Caller | str | None) -> ControlView:
        """Give the lock back; it needs the holder's token. Releasing when nobody holds control
        changes nothing."""
        caller = _as_caller(client)
        with self._lock:
            if self._holder is None:
                return self.control_view()
            if not self._presents_token(caller):
                raise ControlLockError(self._lock_message(caller, "release control"))
            former = self._holder
            self._holder = self._holder_since = self._holder_token = None
        log.info("control released by %r", former)
        view = self.control_view()
        self._emit([ControlChanged(control=view)])
        return view

    def _grant(self) -> ControlGrant:
        assert self._holder_token is not None
        return ControlGrant(holder=self._holder, since=self._holder_since, last_takeover=self._takeover, token=self._holder_token)

    def _presents_token(self, caller: Caller) -> bool:
        return (
            self._holder_token is not None
            and caller.token is not None
            and secrets.compare_digest(caller.token.encode(), self._holder_token.encode())
        )

    def _holder_caller(self) -> Caller:
        """The holder as a caller (for what the session does on its behalf, e.g. streaming)."""
        return Caller(self._holder, self._holder_token)

    def _lock_message(self, caller: Caller, what: str) -> str:
        who = "this page" if caller.name is None else repr(caller.name)
        if caller.token is None:
            return (f"control is held by {self._holder!r}: {who} can only observe "
                    f"(to {what}, present the holder's token in the X-Teleprog-Token header)")
        takeover = self._takeover
        since = f"; {takeover.by!r} took over from {takeover.former!r}" if takeover is not None else ""
        return f"control is held by {self._holder!r} and the token {who} presented is not its token{since}: cannot {what}"

    def _check_control(self, client: Caller | str | None) -> None:
        """Refuse a call that changes state unless nobody holds control or the caller presents
        the holder's token. ``client`` is a ``Caller``; a bare name (or ``None``, the page)
        presents no token."""
        if self._holder is None:
            return
        caller = _as_caller(client)
        if not self._presents_token(caller):
            raise ControlLockError(self._lock_message(caller, "change anything"))

    # =========================================================================== driving
    def set_q(self, q: np.ndarray, *, client: str | None = None) -> VirtualState:
        """Put the virtual robot at ``q`` (rad; checked against the joint ranges)."""
        q = self.robot.as_q(q)
        self.robot.check_limits(q)
        return self._apply(lambda _: q, ControlMode.JOINT, client)

    def jog_joint(self, joint: int, delta: float, *, client: str | None = None) -> VirtualState:
        """Turn joint ``joint`` (1-based) by ``delta`` rad about its own z axis, stopping at its limit."""
        return self._apply(lambda q: jog_joint(self.robot, q, joint, delta), ControlMode.JOINT, client)

    def set_joint(self, joint: int, value: float, *, client: str | None = None) -> VirtualState:
        """Turn joint ``joint`` (1-based) to ``value`` rad, stopping at its limit."""
        if not 1 <= joint <= self.robot.dof:
            raise InputError(f"joint {joint} does not exist: the robot has joints 1..{self.robot.dof}")
        return self._apply(lambda q: jog_joint(self.robot, q, joint, value - q[joint - 1]), ControlMode.JOINT, client)

    def jog_tool(self, *, frame: str, constraint: str, motion: str, displacement: np.ndarray, client: str | None = None) -> VirtualState:
        """Move the tool point by ``displacement`` (m, or a rotation vector in rad) in ``frame``
        along the axis or plane ``constraint``."""
        return self._apply(
            lambda q: jog_tool(self.robot, q, frames=self.frames, frame=frame, constraint=constraint, motion=motion, displacement=displacement),
            ControlMode.TOOL, client,
        )

    def jog_tool_to(self, world_T_goal: np.ndarray, *, frame: str, constraint: str, motion: str, client: str | None = None) -> VirtualState:
        """Move the tool point toward ``world_T_goal`` (the gizmo's pose) under the constraint."""
        return self._apply(
            lambda q: jog_tool_to(self.robot, q, world_T_goal, frames=self.frames, frame=frame, constraint=constraint, motion=motion),
            ControlMode.TOOL, client,
        )

    def release(self, *, client: str | None = None) -> ProgramView:
        """The operator let go of the gizmo or slider: close the open generated segment."""
        with self._lock:
            self._check_control(client)
            statements = self._generator.flush() if self._auto else []
            self._gen_mode = None  # the next stroke starts with the state it starts from
        self._take_generated(statements)
        return self.program_view()

    def _apply(self, step: Callable[[np.ndarray], JogResult | np.ndarray], mode: ControlMode, client: str | None) -> VirtualState:
        """Compute the next joint vector from the current one and publish it, atomically: two
        callers on different threads never lose each other's step."""
        with self._lock:
            self._check_control(client)
            if self._preview is not None:
                p = self._preview
                raise ConflictError(
                    f"cannot drive the arm while statements {p.start + 1}..{p.stop} are being previewed; end the preview first"
                )
            out = step(self._state.q)
            result = out if isinstance(out, JogResult) else None
            q = out.q if isinstance(out, JogResult) else out
            generated: list[Statement] = []
            if self._auto:
                now = self._clock()
                if self._gen_mode is not None and self._gen_mode is not mode:
                    generated += self._generator.flush()
                if self._gen_mode is not mode:
                    # a fresh stroke: the state before it is the stroke's first sample
                    generated += self._generator.feed(self._sample(now - 1e-3, self._state.q, self._state.world_T_tcp, mode))
                    self._gen_mode = mode
            self._state = VirtualState(q.copy(), world_T_tcp(self.robot, q, self.frames), result, self._state.version + 1)
            self._move_held()
            if self._auto:
                generated += self._generator.feed(self._sample(self._clock(), q, self._state.world_T_tcp, mode))
            state, listeners = self._state, list(self._listeners)
            events = self._after_arm_change()
        for listener in listeners:
            try:
                listener(state)
            except Exception:  # a broken view must not break the session
                log.exception("session listener failed")
        self._emit(events)
        self._take_generated(generated)
        return state

    def _sample(self, t: float, q: np.ndarray, world_T: np.ndarray, mode: ControlMode) -> RobotSample:
        return RobotSample(t=t, q=q.copy(), mode=mode, world_T_tool=world_T)

    def _after_arm_change(self) -> list[SessionEvent]:
        """Collision report, zone and regime of the new arm state (under the lock)."""
        events: list[SessionEvent] = [ArmChanged(arm=self.arm_view())]
        self._collision = self._compute_collision(self._state)
        events.append(CollisionChanged(collision=self._collision))
        if self._terrain_view is not None:
            events.append(TerrainChanged(terrain=self._terrain_view))
        if self._collision.zone != self._zone:
            self._zone = self._collision.zone
            events.append(RegimeChanged(regime=self.regime_view()))
        return events

    def _held_skip(self) -> list[tuple[str, str]]:
        return [(self._held, self._tool_body)] if self._held else []

    def _compute_collision(self, state: VirtualState) -> CollisionView:
        poses = self._object_poses or None
        tools = [self._tool_body, *([self._held] if self._held else [])]
        report = self._scene.check(state.q, object_poses=poses, distances=tools, skip=self._held_skip(), data=self._scene_data)
        zs = zone(self._scene, self.cell, state.q, held=[self._held] if self._held else (), object_poses=poses, report=report)
        bodies = {n for pr in report.pairs for n in (pr.a, pr.b)}
        nearest = report.nearest
        jog = state.last_jog
        colliding, pairs = report.colliding, [(p.a, p.b) for p in report.pairs]
        min_distance, nearest_pair = report.min_distance, (nearest.a, nearest.b) if nearest else None
        zone_now, zone_object, zone_distance = zs.zone, zs.object, zs.distance
        if self.terrain is not None:
            # merge the ground: its pairs and distance, and the zone it sets for the tool
            contact, self._terrain_view = self.terrain.evaluate(state.q)
            ground = TerrainLayer.NAME
            colliding = colliding or bool(contact.touching_links)
            pairs += [(link, ground) for link in contact.touching_links]
            if min_distance is None or contact.distance < min_distance:
                min_distance, nearest_pair = contact.distance, (self._tool_body, ground)
            if _ZONE_RANK[contact.zone] > _ZONE_RANK[zone_now] or (
                _ZONE_RANK[contact.zone] == _ZONE_RANK[zone_now] and contact.head_distance < zone_distance
            ):
                zone_now, zone_object, zone_distance = contact.zone, ground, max(contact.head_distance, 0.0)
        return CollisionView(
            colliding=colliding, pairs=pairs,
            triangles={b: report.interfering_triangles(b).tolist() for b in bodies},
            min_distance=min_distance, nearest=nearest_pair,
            zone=Regime(zone_now), zone_object=zone_object, zone_distance=None if not np.isfinite(zone_distance) else zone_distance,
            joint_limit=jog.message if jog is not None and jog.blocked == "joint_limit" else None,
        )

    def _move_held(self) -> None:
        if self._held is not None and self._tcp_T_held is not None:
            self._object_poses[self._held] = self._state.world_T_tcp @ self._tcp_T_held

    def _world_T_object(self, name: str) -> np.ndarray:
        if name in self._object_poses:
            return self._object_poses[name]
        return np.asarray(self.cell.object(name).world_T_object, dtype=float)

    # =========================================================================== program
    def set_auto_generate(self, on: bool, *, client: str | None = None) -> ProgramView:
        """Switch automatic generation; switching on anchors the generator at the arm's state."""
        with self._lock:
            self._check_control(client)
            flushed = self._generator.flush() if self._auto and not on else []
            self._auto = bool(on)
            self._generator.reset()
            self._gen_mode = None
        self._take_generated(flushed)
        view = self.program_view()
        self._emit([ProgramChanged(program=view)])
        return view

    def select(self, index: int, *, client: str | None = None) -> ProgramView:
        """Select statement ``index`` (0-based; ``empty_index`` is the trailing empty one). Allowed while previewing."""
        return self._edit(lambda e: e.select(index), client)

    def insert(self, statement: Statement | str, *, client: str | None = None) -> ProgramView:
        """Insert a statement (a model, or its text form) before the selection."""
        with self._lock:
            self._check_control(client)  # before any work on the caller's input
        st = self._statement(statement)
        return self._edit(lambda e: e.insert(st), client)

    def delete(self, *, client: str | None = None) -> ProgramView:
        """Delete the selected statement."""
        return self._edit(lambda e: e.delete(), client)

    def modify(self, statement: Statement | str, *, client: str | None = None) -> ProgramView:
        """Replace the selected statement by one of the same kind (§4.3.6 rules)."""
        with self._lock:
            self._check_control(client)  # before any work on the caller's input
        st = self._statement(statement)
        return self._edit(lambda e: e.modify(st), client)

    def modify_conditions(self, *, speed: Speed | None | object = KEEP, until: Until | None | object = KEEP, client: str | None = None) -> ProgramView:
        """Set (a value), clear (``None``) or keep (``KEEP``) the WITH speed / UNTIL of the selected action."""
        return self._edit(lambda e: e.modify_conditions(speed, until), client)  # type: ignore[arg-type]

    def undo(self, *, client: str | None = None) -> ProgramView:
        return self._edit(lambda e: e.undo(), client)

    def redo(self, *, client: str | None = None) -> ProgramView:
        return self._edit(lambda e: e.redo(), client)

    def load_program(self, text: str, filename: str = "program.tp", *, client: str | None = None) -> ProgramView:
        """Replace the program by a program file's content (text form, or JSON when the name ends
        in .json). A broken file raises ``InputError`` naming file, line and column; the current
        program is then kept."""
        name = PurePath(filename).name or "program"
        parsed = parse_json(text, name) if name.lower().endswith(".json") else parse_program(text, name)
        if not parsed.ok:
            lines = parsed.error_lines()
            more = f" (and {len(lines) - 1} more)" if len(lines) > 1 else ""
            raise InputError(lines[0] + more)
        state = ProgramState.of(parsed.statements)  # InputError when the rules are broken
        for i, st in enumerate(parsed.statements):
            try:
                _checked_statement(st)
            except TeleprogError as exc:
                raise InputError(f"{name}: statement {i + 1}: {exc}") from None
        with self._lock:
            self._check_control(client)
            self._check_not_previewing("load a program")
            self._editor = Editor(state)
            self._confirmed = None
        view = self.program_view()
        self._emit([ProgramChanged(program=view), Notice(level="info", message=f"loaded {len(parsed.statements)} statement(s) from {name}")])
        return view

    def save_program(self, fmt: str = "text") -> str:
        """The program's file content: ``text`` (the language) or ``json``."""
        with self._lock:
            statements = list(self._editor.state.statements)
        if fmt == "json":
            import json

            return json.dumps(program_to_json(statements), indent=2) + "\n"
        if fmt == "text":
            return format_program(statements)
        raise InputError(f"unknown program format {fmt!r}; valid: text, json")

    def _statement(self, statement: Statement | str) -> Statement:
        """The statement, checked as a program file's would be before it enters the program: a
        text form parsed; a model validated again by its own class (whatever built it) and
        written as text once, so that nothing the program view cannot show gets in."""
        if isinstance(statement, str):
            return parse_statement(statement)
        return _checked_statement(statement)

    def _check_not_previewing(self, what: str) -> None:
        if self._preview is not None:
            p = self._preview
            raise ConflictError(f"cannot {what} while statements {p.start + 1}..{p.stop} are being previewed; only selection is allowed")

    def _edit(self, op: Callable[[Editor], object], client: str | None) -> ProgramView:
        """Apply an editor operation on a copy of the editor and keep it only when the operation
        and the program's view both succeed: a refused or failed edit changes nothing."""
        with self._lock:
            self._check_control(client)
            before = self._editor
            trial = _copy_editor(before)
            try:
                result = op(trial)
                refusal = result if isinstance(result, Refusal) else None
                self._editor = trial
                view = self.program_view()
            except Exception:
                self._editor = before
                raise
        if refusal is not None:
            self._emit([Notice(level="warning", message=refusal.message, rule=refusal.rule.value)])
            raise RefusedByRule(refusal)
        self._emit([ProgramChanged(program=view)])
        return view

    def _take_generated(self, statements: list[Statement]) -> None:
        """Put generated statements at the program's end; in the free regime stream them."""
        if not statements:
            return
        notices: list[SessionEvent] = []
        with self._lock:
            editor = self._editor
            keep = editor.state.selected_index
            at_end = keep == editor.state.empty_index
            inserted = 0
            for st in statements:
                if editor.state.previewing:
                    break
                editor.select_empty()
                result = editor.insert(st)
                if isinstance(result, Refusal):
                    notices.append(Notice(level="warning", message=f"generated {st.kind} not added: {result.message}", rule=result.rule.value))
                    break
                inserted += 1
            if not at_end and keep < editor.state.empty_index:
                editor.select(keep)
            stream = inserted and self.regime is Regime.FREE and self._client is not None
        view = self.program_view()
        self._emit([ProgramChanged(program=view), *notices])
        if stream:
            hazard = self._streaming_hazard()
            if hazard is not None:
                self._emit([Notice(level="warning", message=(
                    f"held back, not sent to the robot: {hazard}; the program keeps it (undo, edit or delete it)"))])
                return
            try:
                self.submit(0, self.editor_state.empty_index, client=self._holder_caller())
            except TeleprogError as exc:
                self._emit([Notice(level="warning", message=f"streaming refused: {exc}")])

    def _streaming_hazard(self) -> str | None:
        """Why the program may not stream to the robot now, or None: its planned path from
        where the sent statements end touches something in the cell's collision model, leaves a
        joint range, or cannot be planned (:meth:`_arm_pair` says which touching pairs count)."""
        with self._lock:
            statements = list(self._editor.state.statements)
            held = self._held
            try:
                p = self._plan_preview(statements, 0, len(statements))
            except TeleprogError as exc:
                return f"the program cannot be planned: {exc}"
        if p.refusal is not None:
            return p.refusal
        for w in p.warnings:
            if w.kind == "joint_limit" or (w.kind == "collision" and self._arm_pair(w.bodies, held)):
                return w.message.replace(": ", f" ({format_statement(statements[w.index])}): ", 1)
        return None

    def _arm_pair(self, bodies: tuple[str, str] | None, held: str | None) -> bool:
        """Whether a touching pair involves the arm (a link; the terrain pairs name one too).
        Two objects touching each other (a peg the robot reported a little off its hole) are
        not the motion's doing; the held object rides with the gripper, which the plan does
        not model, so its pairs do not count either."""
        if bodies is None or held in bodies:
            return False
        names = set(self._scene.body_names)
        return any(b in names and self._scene.body(b).kind == "link" for b in bodies)

    # =========================================================================== preview
    def begin_preview(self, start: int, stop: int, *, client: str | None = None) -> PreviewView:
        """Plan ``statements[start:stop]`` from the program's start state and stand at its start.

        The statements before ``start`` are planned too (they set where the range starts). The
        samples are checked for collisions and joint limits now; warnings are in the view."""
        with self._lock:
            self._check_control(client)
            statements = self._editor.state.statements
            result = self._editor.begin_preview(start, stop)
            if isinstance(result, Refusal):
                refusal = result
            else:
                refusal = None
                try:
                    self._preview = self._plan_preview(statements, start, stop)
                except TeleprogError:
                    self._editor.end_preview()
                    raise
                self._display_before_preview = self._display
                self._display = DisplayMode.TASK_PREVIEW
        if refusal is not None:
            raise RefusedByRule(refusal)
        view = self.preview_view()
        self._emit([PreviewChanged(preview=view), ProgramChanged(program=self.program_view()), DisplayModeChanged(display=self._display)])
        return view

    def _plan_preview(self, statements: Sequence[Statement], start: int, stop: int) -> _Preview:
        plan = _plan(list(statements[:stop]), self.robot, self.cell, self._start_q)
        warnings: list[PreviewWarning] = []
        refusal = None
        if self._start_unknown:
            warnings.append(PreviewWarning(
                t=0.0, index=start, kind="plan",
                message="the robot's state after the statements sent is not known here (a task, a stop or a failure): "
                        "the preview starts from the last prediction; re-sync from telemetry first",
            ))
        if plan.refusal is not None:
            refusal = str(plan.refusal)
            idx = plan.refusal.index if plan.refusal.index is not None else len(plan.segments)
            warnings.append(PreviewWarning(t=0.0, index=idx, kind="plan", message=refusal))
        n = len(plan.segments)
        if start < n:
            t0 = float(plan.start_times[start])
        else:
            t0 = plan.duration
        t1 = plan.duration
        duration = max(0.0, t1 - t0)
        if duration > 0:
            dt = max(self.settings.preview_dt, duration / self.settings.preview_max_samples)
            ts = np.append(np.arange(0.0, duration, dt), duration)
            samples = plan.sample(t0 + ts)
            seen: set[tuple] = set()
            data = self._scene.new_data()
            for t, q in zip(ts, samples.q):
                idx = int(np.searchsorted(plan.start_times, t0 + t, side="right") - 1)
                idx = min(max(idx, start), stop - 1)
                if not self.robot.within_limits(q):
                    key = ("joint_limit", idx)
                    if key not in seen:
                        seen.add(key)
                        bad = [i + 1 for i in range(self.robot.dof) if not (self.robot.lower[i] - 1e-6 <= q[i] <= self.robot.upper[i] + 1e-6)]
                        warnings.append(PreviewWarning(t=float(t), index=idx, kind="joint_limit",
                                                       message=f"statement {idx + 1}: joint {bad[0] if bad else '?'} leaves its range at t={t:.2f} s"))
                report = self._scene.check(q, object_poses=self._object_poses or None, distances="none", triangles=False, data=data)
                touching = [(link, TerrainLayer.NAME) for link in self.terrain.touches(q)] if self.terrain is not None else []
                for pair in [*report.pairs, *(_Pair(a, b) for a, b in touching)]:
                    key = ("collision", idx, pair.a, pair.b)
                    if key not in seen:
                        seen.add(key)
                        warnings.append(PreviewWarning(t=float(t), index=idx, kind="collision", bodies=(pair.a, pair.b),
                                                       message=f"statement {idx + 1}: {pair.a} touches {pair.b} at t={t:.2f} s"))
        return _Preview(start, stop, plan, t0, duration, warnings, refusal)

    def _preview_q(self, p: _Preview) -> np.ndarray:
        return p.plan.sample(p.t0 + p.t).q[0]

    def play(self, rate: float = 1.0, *, client: str | None = None) -> PreviewView:
        """Play the preview from its current time at ``rate`` x real time."""
        if not (0 < rate <= 100):
            raise InputError(f"preview rate must be in (0, 100], got {rate}")
        with self._lock:
            self._check_control(client)
            p = self._need_preview()
            if p.t >= p.duration:
                p.t = 0.0
            p.playing, p.rate = True, float(rate)
            self._ensure_player()
        self._player_wake.set()
        return self._publish_preview()

    def pause(self, *, client: str | None = None) -> PreviewView:
        with self._lock:
            self._check_control(client)
            self._need_preview().playing = False
        return self._publish_preview()

    def seek(self, t: float, *, client: str | None = None) -> PreviewView:
        """Stand at preview time ``t`` (s from the range's start, clipped into the range)."""
        with self._lock:
            self._check_control(client)
            p = self._need_preview()
            p.t = float(min(max(t, 0.0), p.duration))
            self._maybe_confirm(p)
        return self._publish_preview()

    def step(self, statements: int = 1, *, client: str | None = None) -> PreviewView:
        """Jump to the end of the current statement (``statements`` > 0) or to the start of the
        previous one (< 0)."""
        with self._lock:
            self._check_control(client)
            p = self._need_preview()
            p.playing = False
            ends = [float(p.plan.start_times[i] + p.plan.segments[i].duration - p.t0) for i in range(p.start, min(p.stop, len(p.plan.segments)))]
            starts = [float(p.plan.start_times[i] - p.t0) for i in range(p.start, min(p.stop, len(p.plan.segments)))]
            eps = 1e-9
            if statements > 0:
                later = [e for e in ends if e > p.t + eps] or [p.duration]
                p.t = later[min(statements, len(later)) - 1]
            elif statements < 0:
                earlier = [s for s in starts if s < p.t - eps] or [0.0]
                p.t = earlier[max(len(earlier) + statements, 0)]
            p.t = min(max(p.t, 0.0), p.duration)
            self._maybe_confirm(p)
        return self._publish_preview()

    def end_preview(self, *, client: str | None = None) -> PreviewView:
        """Stop previewing; the arm is drawn where the operator left it again."""
        with self._lock:
            self._check_control(client)
            self._need_preview()
            self._preview = None
            self._editor.end_preview()
            self._display = self._display_before_preview
        view = PreviewView()
        self._emit([PreviewChanged(preview=view), ProgramChanged(program=self.program_view()), DisplayModeChanged(display=self._display)])
        return view

    def _need_preview(self) -> _Preview:
        if self._preview is None:
            raise ConflictError("no preview is running; begin one with a range of statements")
        return self._preview

    def _maybe_confirm(self, p: _Preview) -> None:
        if p.t >= p.duration - 1e-9 and not p.warnings:
            st = self._editor.state.statements
            self._confirmed = (p.start, p.stop, tuple(st[p.start : p.stop]))

    def _confirmed_range(self) -> tuple[int, int] | None:
        c = self._confirmed
        if c is None:
            return None
        start, stop, statements = c
        current = self._editor.state.statements
        return (start, stop) if tuple(current[start:stop]) == statements else None

    def _publish_preview(self) -> PreviewView:
        view = self.preview_view()
        events: list[SessionEvent] = [PreviewChanged(preview=view)]
        if view.active and not view.playing and view.t >= view.duration:
            events.append(ProgramChanged(program=self.program_view()))
        self._emit(events)
        return view

    def _ensure_player(self) -> None:
        if self._player is None or not self._player.is_alive():
            self._player = threading.Thread(target=self._player_loop, name="preview-player", daemon=True)
            self._player.start()

    def _player_loop(self) -> None:
        period = 1.0 / self.settings.player_rate_hz
        last = self._clock()
        while not self._closing:
            with self._lock:
                p = self._preview
                playing = p is not None and p.playing
            if not playing:
                self._player_wake.wait(0.5)
                self._player_wake.clear()
                last = self._clock()
                continue
            time.sleep(period)
            now = self._clock()
            with self._lock:
                p = self._preview
                if p is None or not p.playing:
                    continue
                p.t = min(p.t + (now - last) * p.rate, p.duration)
                if p.t >= p.duration:
                    p.playing = False
                    self._maybe_confirm(p)
            last = now
            try:
                self._publish_preview()
            except Exception:  # noqa: BLE001 - the player must survive a broken listener
                log.exception("preview publish failed")

    # =========================================================================== regime, display
    def set_regime_override(self, regime: Regime | None, *, client: str | None = None) -> RegimeView:
        """Force a regime (``None``: follow the zone again)."""
        with self._lock:
            self._check_control(client)
            self._override = None if regime is None else Regime(regime)
            view = self.regime_view()
        self._emit([RegimeChanged(regime=view)])
        return view

    def set_display_mode(self, mode: DisplayMode, *, client: str | None = None) -> DisplayMode:
        with self._lock:
            self._check_control(client)
            mode = DisplayMode(mode)
            if self._preview is not None and mode is not DisplayMode.TASK_PREVIEW:
                raise ConflictError("a preview is running: end it to leave the task preview display")
            self._display = mode
        self._emit([DisplayModeChanged(display=mode)])
        return mode

    # =========================================================================== terrain (rover cells)
    def _require_terrain(self) -> TerrainLayer:
        if self.terrain is None:
            raise InputError(f"cell {self.cell.name!r} has no terrain (open a rover terrain cell)")
        return self.terrain

    def terrain_view(self) -> TerrainView:
        """The arm against the ground at the virtual arm's pose."""
        self._require_terrain()
        with self._lock:
            assert self._terrain_view is not None
            return self._terrain_view

    def set_terrain_sensors(self, on: bool, *, client: str | None = None) -> TerrainView:
        """Show or hide the virtual sensors (their segments come with every terrain view)."""
        terrain = self._require_terrain()
        with self._lock:
            self._check_control(client)
            terrain.show_sensors = bool(on)
            _, self._terrain_view = terrain.evaluate(self._state.q)
            view = self._terrain_view
        self._emit([TerrainChanged(terrain=view)])
        return view

    def place_instrument(
        self, *, world_p: Sequence[float] | None = None, ground_xy: Sequence[float] | None = None,
        ray: tuple[Sequence[float], Sequence[float]] | None = None, client: str | None = None,
    ) -> PlacementView:
        """Instrument placement (seed 004) at a terrain point given as a world point, a ground
        position (x, y) or a picking ray (origin, direction), all in metres."""
        terrain = self._require_terrain()
        given = [v is not None for v in (world_p, ground_xy, ray)]
        if sum(given) != 1:
            raise InputError("give exactly one of a target point, a ground position or a picking ray")
        with self._lock:
            self._check_control(client)
        if ray is not None:
            target = terrain.pick(np.asarray(ray[0], dtype=float), np.asarray(ray[1], dtype=float))
        elif ground_xy is not None:
            xy = np.asarray(ground_xy, dtype=float).reshape(-1)
            if xy.shape != (2,):
                raise InputError(f"a ground position has 2 coordinates (x, y), got {xy.size}")
            target = terrain.ground_point(xy[0], xy[1])
        else:
            target = np.asarray(world_p, dtype=float).reshape(-1)
            if target.shape != (3,):
                raise InputError(f"a target point has 3 coordinates (x, y, z), got {target.size}")
        view = terrain.place(target)
        self._emit([PlacementChanged(placement=view)])
        return view

    def placement_view(self) -> PlacementView | None:
        return self._require_terrain().placement

    def insert_placement(self, *, client: str | None = None) -> ProgramView:
        """Insert the current placement's statements at the selection, as one undoable step each."""
        statements = self._require_terrain().placement_program()
        for statement in statements:
            self.insert(statement, client=client)
        return self.program_view()

    def goto_placement(self, index: int = 0, *, client: str | None = None) -> VirtualState:
        """Put the virtual arm at placement candidate ``index`` (0: the best) to look at it."""
        return self.set_q(self._require_terrain().candidate_q(index), client=client)

    # =========================================================================== robot link
    def attach_robot(self, client, loop: asyncio.AbstractEventLoop) -> None:
        """Use ``client`` (a started or starting ``RobotClient``) on ``loop`` for submissions,
        recovery commands and telemetry. Called once by the app's lifespan."""
        with self._lock:
            self._client, self._loop, self._url = client, loop, client.url
        client.on_report(self.on_report)
        client.on_telemetry(self.on_telemetry)
        client.on_restart(self.on_robot_restart)

    def note_round_trip(self, seconds: float) -> None:
        """Record a measured round trip (connection handshake, submit answer, recovery ack)."""
        with self._lock:
            self._rtts.append(float(seconds))
            del self._rtts[:-20]

    def submit(self, start: int, stop: int, *, client: str | None = None) -> SentListView:
        """Send ``statements[start:stop]`` (``start`` must be 0) to the robot.

        The statements leave the program at once and appear in the sent list as ``sending``;
        the robot's answer numbers them and its reports move them through their statuses. The
        regime applies: quasi needs the range previewed to its end without warnings (confirm);
        operation sends one statement at a time, each action with an UNTIL, in force mode."""
        with self._lock:
            self._check_control(client)
            if self._client is None or self._loop is None:
                raise NotConnectedError("no robot is configured for this console (started with --no-robot)")
            self._check_not_previewing("submit statements")
            state = self._editor.state
            check = state.check_submit(start, stop)
            if check is not None:
                raise RefusedByRule(check)
            statements = list(state.statements[start:stop])
            regime = self.regime
            if regime is Regime.QUASI:
                c = self._confirmed_range()
                if c is None or c[0] != 0 or c[1] < stop:
                    raise ConflictError(
                        f"quasi-operation regime: preview statements 1..{stop} to their end without warnings before sending"
                    )
            prefix: list[Statement] = []
            if regime is Regime.OPERATION:
                if stop - start != 1:
                    raise ConflictError("operation regime: send one statement at a time")
                if any(s.status not in FINAL_SENT for s in self._sent):
                    raise ConflictError("operation regime: wait until the previous statement is final")
                st = statements[0]
                if is_action(st) and st.until is None:
                    raise ConflictError(f"operation regime: the {st.kind} action needs an UNTIL condition (force or contact)")
                if self._robot_mode is not Mode.FORCE:
                    prefix.append(SetMode(mode=Mode.FORCE))
            elif self._robot_mode is Mode.FORCE and not any(getattr(s, "kind", "") == "MODE" for s in statements[:1]):
                prefix.append(SetMode(mode=Mode.POSITION))
            for i, st in enumerate(statements):  # whatever built them, they are checked before they leave
                try:
                    _checked_statement(st)
                except TeleprogError as exc:
                    raise InputError(f"statement {start + i + 1}: {exc}") from None
            outgoing = prefix + statements
            plan = None if self._start_unknown else _plan(outgoing, self.robot, self.cell, self._start_q)  # before anything changes
            result = self._editor.submit(start, stop)
            if isinstance(result, Refusal):
                raise RefusedByRule(result)
            for st in outgoing:
                if st.kind == "MODE":
                    self._robot_mode = st.mode
            comm = self._open_communication(outgoing)
            held_before = self._held
            self._advance_start(outgoing, plan)
            arm_events: list[SessionEvent] = []
            if self._held != held_before or self._held is not None:
                self._move_held()
                arm_events = self._after_arm_change()
            self._confirmed = None
            robot, loop = self._client, self._loop
        asyncio.run_coroutine_threadsafe(self._send(robot, comm, outgoing), loop)
        view = self.sent_view()
        self._emit([SentChanged(sent=view), ProgramChanged(program=self.program_view()), *arm_events])
        self._refresh_predicted()
        return view

    def _open_communication(self, outgoing: list[Statement]) -> int:
        """Number a new communication and list its statements as sending; returns its number."""
        self._comm_counter += 1
        now = time.time()
        for st in outgoing:
            self._sent.append(_Sent(len(self._sent) + 1, st, SentStatus.SENDING, now, self._comm_counter))
        return self._comm_counter

    def _advance_start(self, statements: list[Statement], plan: Plan | None = None) -> None:
        """The program now starts where the submitted statements are predicted to end (``plan``:
        theirs from the start, when already made); a grasp or release among them changes what
        the virtual gripper holds."""
        if self._start_unknown:
            return
        if plan is None:
            plan = _plan(statements, self.robot, self.cell, self._start_q)
        self._start_q = plan.q_final.copy()
        self._start_source = "predicted"
        if plan.after_task is not None or plan.refusal is not None:
            self._start_unknown = True
        for segment in plan.segments:
            if isinstance(segment.statement, TaskCall):
                self._track_task_virtual(segment.statement, world_T_tcp(self.robot, segment.q_start, self.frames))

    def _track_task_virtual(self, call: TaskCall, world_T_tcp_at: np.ndarray) -> None:
        """Grasp/release change what the virtual gripper holds (predicted at the task's pose)."""
        name = call.name.lower()
        if name.startswith("grasp") and call.args:
            obj = self._resolve_object(call.args[0])
            if obj is not None:
                self._held = obj
                self._tcp_T_held = invert(world_T_tcp_at) @ self._world_T_object(obj)
        elif (name.startswith("release") or name.startswith("insert")) and self._held is not None:
            if self._tcp_T_held is not None:
                self._object_poses[self._held] = world_T_tcp_at @ self._tcp_T_held
            self._held, self._tcp_T_held = None, None

    def _resolve_object(self, arg: str) -> str | None:
        for n in self.cell.object_names:
            if n.lower() == arg.lower():
                return n
        return None

    async def _send(self, robot, comm: int, statements: list[Statement]) -> None:
        t0 = self._clock()
        # a round trip counts only if the link stayed up throughout (else it includes the outage)
        was_up, reconnects = robot.connected.is_set(), robot.reconnects
        try:
            numbers = await robot.submit(statements)
        except RobotRestarted as exc:  # on_robot_restart marked them unknown already
            self._mark_unknown([s for s in self._sent if s.comm == comm], str(exc))
            return
        except TeleprogError as exc:  # CommunicationRejected
            with self._lock:
                for s in self._sent:
                    if s.comm == comm:
                        s.status, s.reason, s.finished_at = SentStatus.REJECTED, str(exc), time.time()
                # what was predicted did not happen: the robot's state is the truth now
                self._start_unknown = True
            self._emit([SentChanged(sent=self.sent_view()), Notice(level="error", message=str(exc))])
            return
        except Exception as exc:  # noqa: BLE001 - never let a send die silently
            log.exception("submission %d failed", comm)
            self._emit([Notice(level="error", message=f"submission failed: {exc}")])
            return
        if was_up and robot.connected.is_set() and robot.reconnects == reconnects:
            self.note_round_trip(self._clock() - t0)
        with self._lock:
            items = [s for s in self._sent if s.comm == comm]
            now = time.time()
            for s, number in zip(items, numbers):
                s.number, s.answered_at = number, now
                if s.status is SentStatus.SENDING:
                    s.status = SentStatus.RECEIVED
                self._by_number[number] = s
                for report in self._early_reports.pop(number, []):
                    self._apply_report(s, report)
        self._emit([SentChanged(sent=self.sent_view())])
        self._refresh_predicted()

    def on_report(self, report) -> None:
        """A ``StatusReport`` from the robot (the ``RobotClient`` calls this on the loop thread;
        a replay of a recorded session may call it too)."""
        with self._lock:
            s = self._by_number.get(report.number)
            if s is None:
                self._early_reports.setdefault(report.number, []).append(report)
                return
            self._apply_report(s, report)
            final = s.status in FINAL_SENT
        self._emit([SentChanged(sent=self.sent_view())])
        if final:
            for follow_up in (self._refresh_predicted, self._check_divergence):
                try:
                    follow_up()
                except Exception:  # noqa: BLE001 - the report is taken; a derived view must not undo that
                    log.exception("after the report of statement %d: %s failed", report.number, follow_up.__name__)

    def on_robot_restart(self, restart) -> None:
        """The robot began a new session (``shared.wire.session.SessionRestart``): every sent
        statement without a final status is unknown now, and robot numbers start again."""
        with self._lock:
            # the numbered ones belong to the old session; one still sending learns its fate from
            # its own submission (RobotRestarted in _send, or numbers from the new robot)
            numbered = list(self._by_number.values())
            self._by_number.clear()
            self._early_reports.clear()
        self._mark_unknown(numbered, restart.describe())
        self._emit([Notice(level="error", message=restart.describe()), LinkChanged(link=self.link_view())])

    def _mark_unknown(self, items: list[_Sent], reason: str) -> None:
        with self._lock:
            now = time.time()
            changed = False
            for s in items:
                if s.status not in FINAL_SENT:
                    s.status, s.reason, s.finished_at = SentStatus.UNKNOWN, reason, now
                    changed = True
            if changed:
                self._start_unknown = True  # the robot's state is the truth now
        if changed:
            self._emit([SentChanged(sent=self.sent_view())])
            self._refresh_predicted()

    def _apply_report(self, s: _Sent, report) -> None:
        status = SentStatus(report.state.value)
        now = time.time()
        if status is SentStatus.RUNNING and s.started_at is None:
            s.started_at = now
        if status in FINAL_SENT:
            s.finished_at = now
            if s.started_at is None:
                s.started_at = now
            if not self._take_robot_objects(getattr(report, "robot", None)):
                if status is SentStatus.DONE and isinstance(s.statement, TaskCall):
                    self._track_task_remote(s.statement, report)
            if status is not SentStatus.DONE:
                self._start_unknown = True  # the robot did not end where predicted
        if s.status not in FINAL_SENT:
            s.status = status
        s.reason = report.reason or s.reason

    def _take_robot_objects(self, snap) -> bool:
        """Take the objects where the robot reports them (with a final status or an ack): what
        it holds and where the others lie. False when the robot does not report objects."""
        if snap is None or getattr(snap, "objects", None) is None:
            return False
        world_T_base = np.asarray(self.cell.world_T_base, dtype=float)
        known = {o.name for o in self.cell.objects}
        poses = {o.name: world_T_base @ pose_to_transform(o.base_p, o.base_rpy) for o in snap.objects if o.name in known}
        self._remote_poses.update(poses)
        held = snap.held if snap.held in poses else None
        self._remote_held, self._remote_tcp_T_held = held, None
        if held is not None:
            self._remote_tcp_T_held = invert(self._remote_tcp(np.array(snap.q, dtype=float))) @ poses[held]
            self._remote_poses.pop(held, None)  # it rides with the remote gripper
        return True

    def _track_task_remote(self, call: TaskCall, report) -> None:
        """What the robot holds after a finished grasp/release, and where a released object lies."""
        name = call.name.lower()
        snap = getattr(report, "robot", None)
        q = np.array(snap.q, dtype=float) if snap is not None else (
            np.array(self._telemetry.q, dtype=float) if self._telemetry is not None else None)
        if q is None:
            return
        world_T_tcp_remote = self._remote_tcp(q)
        if name.startswith("grasp") and call.args:
            obj = self._resolve_object(call.args[0])
            if obj is not None:
                here = self._remote_poses.get(obj, np.asarray(self.cell.object(obj).world_T_object, dtype=float))
                self._remote_held, self._remote_tcp_T_held = obj, invert(world_T_tcp_remote) @ here
        elif (name.startswith("release") or name.startswith("insert")) and self._remote_held is not None:
            if self._remote_tcp_T_held is not None:
                self._remote_poses[self._remote_held] = world_T_tcp_remote @ self._remote_tcp_T_held
            self._remote_held, self._remote_tcp_T_held = None, None

    def on_telemetry(self, frame) -> None:
        """A ``TelemetryFrame`` (from the ``RobotClient`` on the loop thread, 50 Hz, or a replay):
        publish the remote arm at a lower rate; check divergence when the robot's state changes."""
        now = self._clock()
        with self._lock:
            old = self._telemetry
            self._telemetry, self._telemetry_at = frame, now
            changed_state = old is None or old.state != frame.state
            due = now - self._last_remote_emit >= 1.0 / self.settings.remote_event_hz
            if due or changed_state:
                self._last_remote_emit = now
        if due or changed_state:
            view = self.remote_view()
            if view is not None:
                self._emit([RemoteArmChanged(remote=view)])
        if changed_state:
            self._check_divergence()

    def _remote_tcp(self, q: np.ndarray) -> np.ndarray:
        return self.cell.world_T_base @ self.robot.fk(q, self._remote_data) @ self.cell.flange_T_tcp

    def _refresh_predicted(self) -> None:
        """Plan the submitted-not-done statements from the remote arm (or the last known start)."""
        with self._lock:
            pending = [s for s in self._sent if s.status not in FINAL_SENT]
            if not pending:
                view = PredictedPathView()
            else:
                frame = self._telemetry
                start = np.array(frame.q, dtype=float) if frame is not None else self._start_q
                try:
                    plan = _plan([s.statement for s in pending], self.robot, self.cell, start)
                except TeleprogError:
                    plan = None
                if plan is None or plan.duration <= 0:
                    view = PredictedPathView(numbers=[s.number for s in pending if s.number is not None])
                else:
                    ts = np.linspace(0.0, plan.duration, self.settings.predicted_points)
                    qs = plan.sample(ts).q
                    data = self.robot.new_data()
                    pts = [(self.cell.world_T_base @ self.robot.fk(q, data) @ self.cell.flange_T_tcp)[:3, 3].tolist() for q in qs]
                    view = PredictedPathView(points=pts, numbers=[s.number for s in pending if s.number is not None], end_q=plan.q_final.tolist())
            self._predicted = view
        self._emit([PredictedPathChanged(predicted=view)])

    # recovery --------------------------------------------------------------------------------
    def stop(self, *, client: str | None = None) -> LinkView:
        """STOP: the robot halts and waits (priority command; acknowledged after a round trip).
        Anybody may press STOP, whoever holds control."""
        return self._recover("stop", lambda r: r.stop(), None)

    def resume(self, *, client: str | None = None) -> LinkView:
        return self._recover("resume", lambda r: r.resume(), client)

    def skip(self, number: int | None = None, *, client: str | None = None) -> LinkView:
        """Skip statement ``number`` (default: the one running, else the first not final)."""
        with self._lock:
            if number is None:
                frame = self._telemetry
                if frame is not None and frame.statement:
                    number = frame.statement
                else:
                    number = next((s.number for s in self._sent if s.status not in FINAL_SENT and s.number is not None), None)
            if number is None:
                raise ConflictError("nothing to skip: no statement is running or waiting")
        n = int(number)
        return self._recover(f"skip {n}", lambda r: r.skip(n), client)

    def abort(self, *, client: str | None = None) -> LinkView:
        """Flush every statement the robot has not finished."""
        return self._recover("abort", lambda r: r.abort(), client)

    def back_away_motion(self) -> Draw:
        """The motion that backs the remote arm out of a contact fault: the tool point
        ``back_away_distance`` straight back along the way the failed statement was pressing
        (its planned path continued from where the robot stopped), or straight up when that way
        is not known, at ``back_away_speed``, orientation kept. Refused unless the robot reports
        a fault, or when neither motion can be planned from where it stopped."""
        with self._lock:
            frame = self._telemetry
            if frame is None:
                raise ConflictError("no telemetry from the robot yet: back away needs to know where it stopped")
            if frame.state is not RobotState.FAULT:
                raise ConflictError(f"back away is for a robot in fault after a contact; the robot is {frame.state.name.lower()}")
            q = self.robot.as_q(np.array(frame.q, dtype=float))
            failed = max((s for s in self._sent if s.status is SentStatus.FAILED),
                         key=lambda s: s.finished_at or 0.0, default=None)
        world_p = self._remote_tcp(q)[:3, 3]
        approach = self._approach_direction(failed.statement, q) if failed is not None else None
        ways = ([-approach] if approach is not None else []) + [np.array([0.0, 0.0, 1.0])]
        speed = Speed(value=self.settings.back_away_speed, unit=SpeedUnit.M_PER_S)
        refusal = ""
        for way in ways:
            target = world_p + self.settings.back_away_distance * way
            motion = Draw(position=tuple(float(v) for v in target), frame=Frame.WORLD, speed=speed)
            plan = plan_program([motion], self.robot, self.cell, start_q=q)
            if plan.refusal is None:
                return motion
            refusal = str(plan.refusal)
        raise ConflictError(f"cannot back away from where the robot stopped: {refusal}")

    def _approach_direction(self, statement: Statement, q: np.ndarray) -> np.ndarray | None:
        """Unit vector (world) the tool point moves along when ``statement`` goes on from ``q``,
        or None (it would not move the tool, or cannot be planned)."""
        try:
            plan = plan_program([statement], self.robot, self.cell, start_q=q)
        except TeleprogError:
            return None
        if plan.refusal is not None or plan.duration <= 0:
            return None
        qs = plan.sample(np.array([0.0, min(0.1, plan.duration)])).q
        step = self._remote_tcp(qs[1])[:3, 3] - self._remote_tcp(qs[0])[:3, 3]
        norm = float(np.linalg.norm(step))
        return step / norm if norm > 1e-6 else None

    def back_away(self, *, client: str | None = None) -> SentListView:
        """After a contact fault, one click: abort what the robot has not finished (it waits in
        fault until then), then send :meth:`back_away_motion`. The motion joins the sent list,
        not the program; the program's start is unknown until a re-sync."""
        motion = self.back_away_motion()
        with self._lock:
            self._check_control(client)
            if self._client is None or self._loop is None:
                raise NotConnectedError("no robot is configured for this console (started with --no-robot)")
            outgoing: list[Statement] = [motion]
            if self._robot_mode is Mode.FORCE:
                outgoing.insert(0, SetMode(mode=Mode.POSITION))
                self._robot_mode = Mode.POSITION
            comm = self._open_communication(outgoing)
            self._start_unknown = True  # the program goes on from where the robot ends: re-sync
            self._recovery_counter += 1
            key = self._recovery_counter
            self._recovery_pending[key] = "abort before back away"
            robot, loop = self._client, self._loop

        async def run() -> None:
            try:
                await robot.abort()
            except Exception as exc:  # noqa: BLE001 - shown, and the motion is not sent
                with self._lock:
                    self._recovery_pending.pop(key, None)
                    for s in self._sent:
                        if s.comm == comm:
                            s.status, s.reason, s.finished_at = SentStatus.REJECTED, f"abort failed: {exc}", time.time()
                self._emit([SentChanged(sent=self.sent_view()), Notice(level="error", message=f"back away not sent: abort failed: {exc}")])
                return
            with self._lock:
                self._recovery_pending.pop(key, None)
            self._emit([LinkChanged(link=self.link_view())])
            await self._send(robot, comm, outgoing)

        asyncio.run_coroutine_threadsafe(run(), loop)
        view = self.sent_view()
        self._emit([SentChanged(sent=view), LinkChanged(link=self.link_view()),
                    Notice(level="info", message=f"backing away: abort, then {format_statement(motion)}")])
        return view

    def _recover(self, what: str, call, client: str | None) -> LinkView:
        with self._lock:
            if what != "stop":
                self._check_control(client)
            if self._client is None or self._loop is None:
                raise NotConnectedError("no robot is configured for this console (started with --no-robot)")
            self._recovery_counter += 1
            key = self._recovery_counter
            self._recovery_pending[key] = what
            robot, loop = self._client, self._loop

        async def run() -> None:
            t0 = self._clock()
            try:
                ack = await call(robot)
            except Exception as exc:  # noqa: BLE001
                self._emit([Notice(level="error", message=f"{what} failed: {exc}")])
                ack = None
            else:
                self.note_round_trip(self._clock() - t0)
            with self._lock:
                self._recovery_pending.pop(key, None)
                if ack is not None:
                    self._take_robot_objects(ack.robot)
            if ack is not None:
                level = "info" if ack.applied else "warning"
                detail = f": {ack.detail}" if ack.detail else ""
                self._emit([Notice(level=level, message=f"robot {'applied' if ack.applied else 'did not apply'} {what}{detail}")])
            self._emit([LinkChanged(link=self.link_view())])

        asyncio.run_coroutine_threadsafe(run(), loop)
        view = self.link_view()
        self._emit([LinkChanged(link=view)])
        return view

    # divergence ------------------------------------------------------------------------------
    def _check_divergence(self) -> None:
        """Compare the reported arm with where it should be, once the robot is at rest."""
        with self._lock:
            frame = self._telemetry
            if frame is None:
                return
            state = frame.state.name.lower()
            pending = any(s.status not in FINAL_SENT for s in self._sent)
            at_rest = state in ("stopped", "fault") or (state == "idle" and not pending)
            if not at_rest:
                if self._divergence.checked:
                    self._divergence = self._divergence.model_copy(update={"checked": False})
                return
            q = np.array(frame.q, dtype=float)
            expect = self._start_q
            jerr = float(np.max(np.abs(q - expect))) if q.size == expect.size else float("inf")
            terr = float(np.linalg.norm(self._remote_tcp(q)[:3, 3] - world_T_tcp(self.robot, expect, self.frames)[:3, 3]))
            obj, oerr = self._object_divergence()
            arm_off = jerr > self.settings.divergence_joint or terr > self.settings.divergence_tool
            objects_off = oerr > self.settings.divergence_tool
            diverged = self._start_unknown or arm_off or objects_off
            msg = ""
            if diverged and (arm_off or self._start_unknown or not objects_off):
                msg = (f"the robot stopped {np.degrees(jerr):.2f} deg / {terr * 1e3:.1f} mm away from where the program "
                       "expects it; re-sync to continue from there")
            elif diverged:
                where = "is held on one side only" if not np.isfinite(oerr) else f"lies {oerr * 1e3:.1f} mm from its modelled place"
                msg = f"the robot reports that {obj} {where}; re-sync to take the objects as the robot sees them"
            view = DivergenceView(diverged=diverged, joint_error=jerr if np.isfinite(jerr) else 0.0, tool_error=terr,
                                  object_error=oerr if np.isfinite(oerr) else 0.0, object=obj if objects_off else None,
                                  threshold_joint=self.settings.divergence_joint, threshold_tool=self.settings.divergence_tool,
                                  checked=True, message=msg)
            changed = view != self._divergence
            self._divergence = view
        if changed:
            self._emit([DivergenceChanged(divergence=view)])

    def _object_divergence(self) -> tuple[str | None, float]:
        """The object whose reported place differs most from the virtual world's (under the
        lock): its name and distance (m; inf when one side holds it and the other does not)."""
        if self._remote_held != self._held:
            return self._remote_held or self._held, float("inf")
        worst, name = 0.0, None
        for obj, world_T_reported in self._remote_poses.items():
            if obj == self._held:
                continue
            d = float(np.linalg.norm(world_T_reported[:3, 3] - self._world_T_object(obj)[:3, 3]))
            if d > worst:
                worst, name = d, obj
        return name, worst

    def locate_object(self, name: str, camera: str, pixels: Sequence[Sequence[float]], *, client: str | None = None) -> LocatedView:
        """Correct a virtual object's pose from its feature points seen in a calibrated camera's
        image (thesis §4.2.3): ``pixels`` (u, v) in the order of the object's keypoints.
        Pixels that cannot determine a pose (repeated, collinear, not finite) are refused with
        ``InputError`` ("pixels are degenerate: ...")."""
        with self._lock:
            self._check_control(client)  # before the solve: an observer's call does no work
        obj = self._resolve_object(name)
        if obj is None:
            raise UnknownNameError("object", name, self.cell.object_names)
        if camera not in self.cell.cameras:
            raise UnknownNameError("camera", camera, self.cell.cameras)
        keypoints = self.cell.object(obj).keypoints
        if len(keypoints) < 4:
            raise InputError(f"object {obj!r} has {len(keypoints)} feature points in the cell file; locating it needs 4")
        try:
            px = np.asarray(pixels, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"{obj!r} has {len(keypoints)} feature points: give one pixel (u, v) for each, as numbers") from None
        if px.ndim != 2 or px.shape[1] != 2 or px.shape[0] != len(keypoints):
            raise InputError(f"{obj!r} has {len(keypoints)} feature points: give one pixel (u, v) for each, in order")
        located = _locate_or_refuse(self.cell.cameras[camera], keypoints, px)
        if located.residual_px > self.settings.locate_max_residual_px:
            raise InputError(
                f"the picked pixels do not fit {obj!r}'s feature points (reprojection error {located.residual_px:.1f} px, "
                f"at most {self.settings.locate_max_residual_px:g}): check the order of the points"
            )
        with self._lock:
            self._check_control(client)
            self._check_not_previewing("correct an object")
            if obj == self._held:
                raise ConflictError(f"{obj!r} is in the virtual gripper; release it before correcting its pose")
            before = self._world_T_object(obj).copy()
            self._object_poses[obj] = located.world_T_object.copy()
            moved = float(np.linalg.norm(located.world_T_object[:3, 3] - before[:3, 3]))
            events = self._after_arm_change()
        view = LocatedView(object=obj, camera=camera, world_T_object=_m(located.world_T_object),
                           residual_px=located.residual_px, moved=moved)
        self._emit([*events, Notice(level="info", message=f"{obj} located from camera {camera}: moved {moved * 1e3:.1f} mm "
                                                            f"(reprojection {located.residual_px:.2f} px)")])
        return view

    def resync(self, *, client: str | None = None) -> SessionSnapshot:
        """Put the virtual arm (and the object the robot holds) where telemetry says, and start
        the program from there (§4.2.3 error correction)."""
        with self._lock:
            self._check_control(client)
            self._check_not_previewing("re-sync")
            frame = self._telemetry
            if frame is None:
                raise ConflictError("no telemetry from the robot yet: nothing to re-sync from")
            q = self.robot.as_q(np.array(frame.q, dtype=float))
            self._state = VirtualState(q.copy(), world_T_tcp(self.robot, q, self.frames), None, self._state.version + 1)
            # objects as the robot's state implies: the held one in the remote gripper, released
            # ones where the robot let them go
            self._object_poses.update({k: v.copy() for k, v in self._remote_poses.items()})
            self._held = self._remote_held
            self._tcp_T_held = None if self._remote_tcp_T_held is None else self._remote_tcp_T_held.copy()
            self._move_held()
            self._start_q = q.copy()
            self._start_source = "telemetry"
            self._start_unknown = False
            self._generator.reset()
            self._gen_mode = None
            self._confirmed = None
            self._divergence = self._divergence.model_copy(update={"diverged": False, "message": "re-synced from telemetry"})
            state, listeners = self._state, list(self._listeners)
            events = self._after_arm_change()
        for listener in listeners:
            try:
                listener(state)
            except Exception:
                log.exception("session listener failed")
        self._emit([*events, ProgramChanged(program=self.program_view()), DivergenceChanged(divergence=self.divergence_view())])
        return self.snapshot()

    async def monitor_link(self) -> None:
        """Publish ``LinkChanged`` when the link's state changes and the age as it grows; run on
        the app's loop for the console's lifetime."""
        while not self._closing:
            # every poll: the telemetry age grows even when nothing else changes
            try:
                self._last_link = self.link_view()
                self._emit([LinkChanged(link=self._last_link)])
            except Exception:  # noqa: BLE001 - the monitor must outlive any one bad view
                log.exception("publishing the link view failed")
            await asyncio.sleep(self.settings.link_poll_s)

    def close(self) -> None:
        """Stop the preview player thread."""
        self._closing = True
        self._player_wake.set()

    # =========================================================================== events
    def _emit(self, events: Sequence[SessionEvent]) -> None:
        if not events:
            return
        with self._lock:
            listeners = list(self._event_listeners)
        for event in events:
            for listener in listeners:
                try:
                    listener(event)
                except Exception:  # a broken watcher must not break the session
                    log.exception("session event listener failed")
