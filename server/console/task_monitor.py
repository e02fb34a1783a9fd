"""The task panel's state (thesis §3.5, §3.1: task coordination and task monitoring): two
markings of the cell's task net, one following the virtual cell as the operator drives, one
following the robot's reports, and the deviations between what the robot reports and what the
net allows.

* Virtual side: every change of the virtual arm (``ArmChanged``: tool pose, held object, object
  poses) is a state of the virtual cell; its coordinator recognises the actions and moves the
  virtual marking. The recognised actions generate the task net (§3.5.5) shown on the page. A
  cell that jumped (a submit or a report put the arm and the objects where the sent statements
  end) is followed by the shortest run of enabled actions that explains it
  (``TaskCoordinator.follow``); after a re-sync the marking is what the cell shows (``take``).
  So the virtual marking is always the marking of what the virtual cell shows.
* Robot side: every remote arm view (``RemoteArmChanged``: the robot's tool, gripper, held and
  reported objects) moves the robot's marking the same way.
* Preview: when a range is previewed, the console plays the program up to the range's end once
  (the same playback) and, as the preview player moves, shows the actions the range makes up to
  the player's time and the marking where the player stands.
* Monitoring: when a range leaves, the console plays it on the virtual cell (the same playback
  as ``teleprog net recognise``) and expects, per statement, the actions the play recognised.
  When a statement's final status arrives and the robot's state (the next remote view) has not
  made an action expected of it, that is a deviation with the transition expected. A robot state
  the marking contradicts with no enabled transition explaining it (the peg reported free while
  held) is a deviation too.
* One truth: with the robot at rest, nothing pending and the virtual arm at the program's start
  (the program empty), the two markings must be the same; a disagreement is a deviation
  (``markings``) and a warning notice, never a silent difference in the panel.

No geometry here: ``shared.tasknet`` does the contacts and the net. Listeners run after the
session's lock is released; this part has its own lock.
"""

from __future__ import annotations

import contextlib
import logging
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
from server.console.context import ConsoleContext
from server.console.enums import FINAL_SENT
from server.console.events import (
    ActionTaken,
    ArmChanged,
    Notice,
    PreviewChanged,
    RangeSubmitted,
    RemoteArmChanged,
    SentChanged,
    SessionEvent,
    TaskChanged,
)
from server.console.views import ActionView, DeviationView, PreviewView, RemoteArmView, RuleView, TaskView
from server.console.work import Work
from server.delivery import Delivery
from shared.cells.object_world import ObjectWorld
from shared.motion.frames import CellFrames
from shared.language.parser import parse_program
from shared.tasknet.cenet import ConditionEventModel, ConditionModel, EventModel
from shared.tasknet.contacts import CellState, ContactModel
from shared.tasknet.coordinator import TaskCoordinator, generate_task_net
from shared.tasknet.playback import PrefixRecognition, ProgramRecognition
from shared.tasknet.taskspace import TaskSpace, load_task_space, task_file_for_cell

log = logging.getLogger(__name__)

GRIPPER_CLOSED_M = 0.005
"""A reported gripper opening (m) below which the robot's gripper counts as closed."""
MAX_DEVIATIONS = 50
AT_REST = ("idle", "stopped", "fault")
"""Robot states in which nothing moves: the markings are compared then."""


@dataclass
class _Expectation:
    """The actions a sent statement should make, by the console's play of its range."""

    sent_id: int
    text: str
    actions: list[str]
    checked: bool = False
    final_seen: bool = False
    status: str = ""
    number: int | None = None


PreviewSource = Callable[[int], tuple[Sequence, np.ndarray, dict[str, np.ndarray], str | None]]
"""``stop -> (the program's first stop statements, its start q, the virtual objects' poses, held)``."""


@dataclass
class _PreviewPlay:
    """The play of a previewed range: recognised once, read as the player moves."""

    key: tuple
    start: int
    recognition: ProgramRecognition | None
    shown: tuple | None = ()  # (actions shown, marking) last emitted


@dataclass
class _RobotSide:
    coordinator: TaskCoordinator
    expectations: dict[int, _Expectation] = field(default_factory=dict)
    matched: int = 0  # robot actions already matched to expectations
    playing: set[int] = field(default_factory=set)  # sent ids whose range is being played
    early_finals: dict[int, tuple[str, int | None]] = field(default_factory=dict)
    """Final statuses of sent statements whose expectations were still being played."""


class TaskMonitor:
    """``session.task``: recognition on both sides and deviations (see the module docstring)."""

    def __init__(self, ctx: ConsoleContext, task_file: str | None = None, preview_source: PreviewSource | None = None) -> None:
        self._ctx, self._preview_source = ctx, preview_source
        self._preview: _PreviewPlay | None = None
        self._lock, self._play_lock = threading.Lock(), threading.Lock()  # the play's: a previewed range's, outside ``_lock``
        self._played: _PreviewPlay | None = None  # the newest play (``_preview`` while previewing)
        self._recognition = _KeptRecognition(ctx.cell)  # per statement, from the newest start
        # the plays (seconds for a long range) run here, never on the thread that previewed or submitted
        self._plays = Delivery(name="task-plays")
        self._queued = 0
        self._settled = threading.Condition()
        self._preview_seq = 0  # bumped by every PreviewChanged: a play that finds it moved shows nothing
        cell = ctx.cell
        path = task_file or task_file_for_cell(cell.name)
        self.space: TaskSpace | None = None
        if path is None:
            return
        try:
            self.space = load_task_space(path)
            self._contacts = ContactModel(self.space, cell)
        except Exception as exc:  # a bad task file must not stop the console; the panel says why
            log.warning("task monitoring off: %s", exc)
            self.space, self.error = None, str(exc)
            return
        self._frames = CellFrames.from_cell(cell)
        start = CellState.of_world(ObjectWorld(cell), self._frames.world_T_tcp(cell.robot, cell.q_home))
        self._virtual = TaskCoordinator(self.space, self._contacts, start)
        self._robot = _RobotSide(TaskCoordinator(self.space, self._contacts, start))
        self._deviations: list[DeviationView] = []
        self._deviation_keys: set[str] = set()
        self._version = 0
        self._space_net = _space_model(self.space, self._virtual.m0)

    error: str | None = None
    _last: CellState | None = None  # the robot's cell as its newest remote view shows it
    _last_remote: RemoteArmView | None = None
    _pending = 0  # statements sent and not final, by the newest sent list
    _resynced = False  # a re-sync came: the next virtual cell is taken as it is
    _virtual_q: np.ndarray | None = None  # the virtual arm's joints, by its newest view
    _disagreed: tuple | None = None  # (virtual, robot) markings the last robot view at rest found apart

    @property
    def available(self) -> bool:
        return self.space is not None

    # -- events --------------------------------------------------------------------------------
    def on_event(self, event: SessionEvent) -> None:
        if self.space is None:
            return
        if isinstance(event, RangeSubmitted):
            with self._lock:
                self._robot.playing.update(event.ids)
            self._later(self._take_submitted, event)
            return
        if isinstance(event, PreviewChanged):
            with self._lock:
                self._preview_seq += 1
                seq = self._preview_seq
            source = None
            if event.preview.active and self._preview_source is not None:
                source = self._preview_source(event.preview.stop)  # read outside this part's lock
                if not self._kept(event.preview, source):  # a new range: played off this thread
                    self._later(self._take_preview, event, source, seq)
                    return
            self._take_preview(event, source, seq)
            return
        # the program's start, read outside this part's lock as a preview's source is: the
        # markings are compared on the robot's views, which carry what its reports left
        start = self._program_start(event.remote) if isinstance(event, RemoteArmChanged) else None
        notices: list[Notice] = []
        with self._lock:
            if isinstance(event, ArmChanged):
                changed = self._observe_virtual(event)
            elif isinstance(event, RemoteArmChanged):
                changed = self._observe_robot(event)
                changed |= self._compare_markings(start, notices)
            elif isinstance(event, SentChanged):
                self._pending = event.sent.pending
                changed = self._statuses(event)
            else:
                if isinstance(event, ActionTaken) and event.action == "resync":
                    self._resynced = True  # the next virtual cell is taken as it is
                changed = False
            view = self._changed() if changed else None
        if view is not None:
            self._ctx.bus.emit([TaskChanged(task=view), *notices])

    def close(self) -> None:
        self._plays.close()

    def settled(self, timeout: float = 60.0) -> bool:
        """Wait until no play is queued or running (tests; a caller that must read its result)."""
        with self._settled:
            return self._settled.wait_for(lambda: self._queued == 0, timeout)

    def _later(self, fn: Callable, *args: object) -> None:
        def run() -> None:
            try:
                fn(*args)
            finally:
                with self._settled:
                    self._queued -= 1
                    self._settled.notify_all()

        with self._settled:
            self._queued += 1
        self._plays.post(run)

    def _changed(self) -> TaskView:
        self._version += 1
        return self._view()

    def _take_submitted(self, event: RangeSubmitted) -> None:
        """Play a submitted range (on the plays' thread): what each statement should do."""
        expected = self._expected_actions(event)
        with self._lock:
            self._robot.playing.difference_update(event.ids)
            for sent_id, exp in expected.items():
                self._robot.expectations[sent_id] = exp
                final = self._robot.early_finals.pop(sent_id, None)
                if final is not None:  # it ended while the range was being played
                    exp.final_seen, (exp.status, exp.number) = True, final

    def _take_preview(self, event: PreviewChanged, source, seq: int) -> None:
        play = self._preview_play(event.preview, source)
        with self._lock:
            if seq != self._preview_seq:  # a newer preview event came meanwhile: it shows
                return
            view = self._changed() if self._follow_preview(event.preview, source, play) else None
        if view is not None:
            self._ctx.bus.emit([TaskChanged(task=view)])

    def _kept(self, pv: PreviewView, source) -> bool:
        kept = self._played
        return kept is not None and kept.key == self._preview_key(pv, source)

    @staticmethod
    def _preview_key(pv: PreviewView, source) -> tuple:
        statements, start_q, poses, held = source
        return (pv.start, pv.stop, tuple(statements), np.asarray(start_q).tobytes(),
                tuple(sorted((k, np.asarray(v).tobytes()) for k, v in poses.items())), held)

    def _state(self, world_T_tcp, closed: bool, poses: dict) -> CellState:
        cell = self._ctx.cell
        objects = {o.name: np.asarray(o.world_T_object, dtype=float) for o in cell.objects}
        objects.update({k: np.asarray(v, dtype=float) for k, v in poses.items()})
        return CellState(np.asarray(world_T_tcp, dtype=float), closed, objects)

    def _observe_virtual(self, event: ArmChanged) -> bool:
        arm = event.arm
        state = self._state(arm.world_T_tcp, arm.held is not None, arm.object_poses)
        self._virtual_q = np.asarray(arm.q, dtype=float)
        now = self._ctx.clock()
        if self._resynced:  # the cell was taken from the robot: so is its marking
            self._resynced = False
            return self._virtual.take(state)
        changed = bool(self._virtual.observe(state, now))
        return bool(self._virtual.follow(state, now)) or changed  # a jump: the actions that explain it

    def _program_start(self, r: RemoteArmView) -> tuple[bool, np.ndarray] | None:
        """Whether the program is empty and where it starts, while the robot is at rest with
        nothing pending (None otherwise, or with no source to read it from)."""
        if self._preview_source is None or r.state not in AT_REST or self._pending:
            return None
        statements, start_q, _poses, _held = self._preview_source(1)
        return not statements, np.asarray(start_q, dtype=float)

    def _compare_markings(self, start: tuple[bool, np.ndarray] | None, notices: list[Notice]) -> bool:
        """After the robot's newest view: the robot at rest, nothing pending, the virtual arm at
        the program's start with the program empty: the two markings must agree; a
        disagreement is a deviation and a notice."""
        r = self._last_remote
        at_start = self._preview_source is None or (
            start is not None and start[0] and self._virtual_q is not None and self._virtual_q.shape == start[1].shape
            and np.allclose(self._virtual_q, start[1], rtol=0.0, atol=1e-9))
        if r is None or r.state not in AT_REST or self._pending or self._resynced or not at_start:
            self._disagreed = None
            return False
        v, rb = self._virtual.marking, self._robot.coordinator.marking
        if v == rb or self._disagreed != (v, rb):  # told when two views in a row show it: the
            self._disagreed = None if v == rb else (v, rb)  # console settles a report first
            return False
        only_v, only_r = self._virtual.ordered(v - rb), self._virtual.ordered(rb - v)
        path = self._robot.coordinator.path_to(v)  # what the robot's net lacks to be where the virtual one is
        expected = path[0].text if path else None
        message = (f"the virtual cell's marking has {', '.join(only_v) or 'nothing more'} where the robot's has "
                   f"{', '.join(only_r) or 'nothing more'}, with the robot at rest"
                   + (f" (expected {expected})" if expected else "") + "; re-sync to take the robot's cell")
        if not self._deviate("markings", expected, r.statement or None, "", message, {a: a in rb for a in sorted(v ^ rb)}):
            return False
        notices.append(Notice(level="warning", message=f"task net: {message}"))
        return True

    def _observe_robot(self, event: RemoteArmChanged) -> bool:
        r = event.remote
        closed = r.held is not None or r.gripper < GRIPPER_CLOSED_M
        state = self._state(r.world_T_tcp, closed, r.object_poses)
        self._last, self._last_remote = state, r
        side = self._robot
        fired = side.coordinator.observe(state, self._ctx.clock(), r.statement or None)
        changed = bool(fired)
        changed |= self._check_expectations()
        unexplained = side.coordinator.unexplained(state)
        if unexplained:
            expected = self._next_expected()
            observed = ", ".join(f"{a} {'true' if v else 'false'}" for a, v in unexplained.items())
            changed |= self._deviate(
                "state", expected, r.statement or None, "",
                f"the robot's cell shows {observed}, which no action of the task net allows from its marking"
                + (f" (expected {expected})" if expected else ""),
                unexplained,
            )
        return changed

    def _preview_play(self, pv: PreviewView, source) -> _PreviewPlay | None:
        """The play of the previewed range (outside the lock): the one kept when its key is the
        same, else a new one."""
        if not pv.active or source is None:
            return None
        statements, start_q, poses, held = source
        key = self._preview_key(pv, source)
        with self._play_lock:  # one play at a time: the player's events must not each start one
            kept = self._played
            if kept is not None and kept.key == key:
                return kept
            self._played = _PreviewPlay(key, pv.start, self._play(statements, start_q, poses, held))
            return self._played

    def _follow_preview(self, pv: PreviewView, source, play: _PreviewPlay | None) -> bool:
        if not pv.active or source is None or play is None:
            was, self._preview = self._preview is not None, None
            return was
        if self._preview is not play:  # a preview (re)starts: shown whatever a play kept showed before
            self._preview, play.shown = play, None
        shown = self._preview_state(play, pv.t)
        if shown == play.shown:
            return False
        play.shown = shown
        return True

    def _play(self, statements, start_q, poses, held) -> ProgramRecognition | None:
        cell = self._ctx.cell
        world = ObjectWorld(cell)
        world.take_reported(poses, held, self._frames.world_T_tcp(cell.robot, np.asarray(start_q)))
        statements = list(statements)
        try:
            return self._recognise(statements, start_q, world, f"recognising the task in the {len(statements)} statement(s) previewed")
        except Exception as exc:  # the preview itself reports planning problems; the panel just goes without
            log.warning("could not play the previewed range for the task panel: %s", exc)
            return None

    def program_end(self, wait: bool = True) -> tuple[frozenset[str], dict[str, np.ndarray]] | None | bool:
        """The marking and objects' poses where the program leaves the virtual cell (kept per
        statement); None: no program or model; False: busy playing and not ``wait``."""
        source = self._preview_source(None) if self.space is not None and self._preview_source else None
        return None if source is None else self._recognition.program_end(self.space, source, self._frames, wait)

    def _recognise(self, statements, start_q, world: ObjectWorld, what: str) -> ProgramRecognition:
        with self._work(what) as step:
            return self._recognition.recognise(self.space, statements, start_q, world, step)

    @contextlib.contextmanager
    def _work(self, what: str) -> Iterator[Callable[[int, int], None]]:
        """A play as a long work (``WorkProgress`` once it runs past 0.3 s): the progress
        function ``recognise_program`` calls with the statements played."""
        with Work(self._ctx.bus, self._ctx.clock, "task_play", what, (("recognise", 1.0),)) as work:
            work.phase("recognise", 1)
            yield work.advance

    def _preview_state(self, play: _PreviewPlay, t: float) -> tuple:
        rec = play.recognition
        if rec is None:
            return ((), ())
        t0 = rec.starts[play.start] if play.start < len(rec.starts) else (rec.starts[-1] if rec.starts else 0.0)
        upto = [a for a in rec.actions if a.t is None or a.t <= t0 + t + 1e-9]
        marking = upto[-1].marking if upto else rec.m0
        in_range = tuple(a for a in upto if a.statement is not None and a.statement > play.start)
        return (in_range, tuple(marking))

    def _expected_actions(self, event: RangeSubmitted) -> dict[int, _Expectation]:
        """Play the submitted range on the virtual cell from where it starts: per sent
        statement, the actions the play recognised (outside the lock)."""
        if event.start_q is None:
            return {}
        parsed = parse_program("\n".join(event.texts))
        if not parsed.ok or len(parsed.statements) != len(event.ids):
            return {}
        world = ObjectWorld(self._ctx.cell)
        r = self._last_remote
        if r is not None:
            world.take_reported({k: np.asarray(v) for k, v in r.object_poses.items()}, r.held, np.asarray(r.world_T_tcp))
        try:
            result = self._recognise(parsed.statements, event.start_q, world,
                                     f"recognising the task in the {len(parsed.statements)} statement(s) sent")
        except Exception as exc:
            log.warning("could not play the submitted range for task monitoring: %s", exc)
            return {}
        per: dict[int, list[str]] = {i: [] for i in range(len(event.ids))}
        for a in result.actions:
            if a.statement is not None:
                per[a.statement - 1].append(a.action)
        return {sent_id: _Expectation(sent_id, event.texts[i], per[i]) for i, sent_id in enumerate(event.ids)}

    def _statuses(self, event: SentChanged) -> bool:
        for item in event.sent.items:
            exp = self._robot.expectations.get(item.id)
            if item.status not in FINAL_SENT:
                continue
            if exp is None:
                if item.id in self._robot.playing:
                    self._robot.early_finals[item.id] = (item.status.value, item.number)
            elif not exp.final_seen:
                exp.final_seen, exp.status, exp.number = True, item.status.value, item.number
        return False  # checked on the next remote view, which carries the state the status ends in

    def _check_expectations(self) -> bool:
        side = self._robot
        texts = [a.action for a in side.coordinator.actions]
        changed = False
        for exp in sorted(side.expectations.values(), key=lambda e: e.sent_id):
            if exp.checked or not exp.final_seen:
                continue
            exp.checked = True
            for action in exp.actions:
                if action in texts[side.matched:]:
                    side.matched = texts.index(action, side.matched) + 1
                    continue
                act = self.space.action(action)
                truth = self._contacts.evaluate(self._last, [*act.add, *act.delete]) if self._last is not None else {}
                seen = ", ".join(f"{a} {'true' if v else 'false'}" for a, v in truth.items())
                changed |= self._deviate(
                    "missing", action, exp.number, exp.status,
                    f"statement {exp.number if exp.number is not None else '?'} `{exp.text}` ended {exp.status} "
                    f"without {action}: the robot reports {seen}",
                    truth,
                )
        return changed

    def _next_expected(self) -> str | None:
        side = self._robot
        done = len(side.coordinator.actions)
        virtual = [a.action for a in self._virtual.actions]
        return virtual[done] if done < len(virtual) else None

    def _deviate(self, kind: str, expected: str | None, statement: int | None, status: str, message: str,
                 observed: dict[str, bool]) -> bool:
        key = f"{kind}|{expected}|{statement}|{sorted(observed.items())}"
        if key in self._deviation_keys:
            return False
        self._deviation_keys.add(key)
        self._deviations.append(DeviationView(
            kind=kind, expected=expected, statement=statement, status=status or None, message=message,
            observed=observed, robot_marking=self._robot.coordinator.ordered(self._robot.coordinator.marking),
            at=self._ctx.wall_clock()))
        del self._deviations[:-MAX_DEVIATIONS]
        log.warning("task deviation: %s", message)
        return True

    def generated_net(self):
        """The task net of the actions recognised on the virtual cell (§3.5.5) as a P/T net, for
        saving as PNML or JSON; None for a cell without a task file."""
        if self.space is None:
            return None
        with self._lock:
            v = self._virtual
            return generate_task_net(self.space, v.m0, [a.action for a in v.actions]).net

    # -- views ---------------------------------------------------------------------------------
    def view(self) -> TaskView:
        if self.space is None:
            return TaskView(available=False, error=self.error)
        with self._lock:
            return self._view()

    def _view(self) -> TaskView:
        space = self.space
        v, r = self._virtual, self._robot.coordinator
        net = generate_task_net(space, v.m0, [a.action for a in v.actions])
        return TaskView(
            available=True,
            task=space.spec.name,
            description=space.spec.description,
            rules=[RuleView(name=x.name, params=list(x.params), pre=x.pre, delete=x.delete, add=x.add) for x in space.spec.rules],
            atoms=list(space.atom_texts),
            virtual_marking=v.ordered(v.marking),
            robot_marking=r.ordered(r.marking),
            virtual_actions=[ActionView(action=a.action, t=a.t, statement=a.statement) for a in v.actions],
            robot_actions=[ActionView(action=a.action, t=a.t, statement=a.statement) for a in r.actions],
            enabled=[a.text for a in v.enabled()],
            net=net.model,
            space_net=self._space_net,
            preview_active=self._preview is not None,
            preview_actions=[] if self._preview is None else
            [ActionView(action=a.action, t=a.t, statement=a.statement) for a in self._preview.shown[0]] if self._preview.shown else [],
            preview_marking=[] if self._preview is None or not self._preview.shown else list(self._preview.shown[1]),
            deviations=list(self._deviations),
            version=self._version,
        )


class _KeptRecognition:
    """The recognition of the newest start, kept per statement: a program changed near its end (a
    statement generated, a range previewed again after an edit) plays from its first changed
    statement (``shared.tasknet.playback.PrefixRecognition``); a new start plays from the beginning."""

    def __init__(self, cell) -> None:
        self._cell = cell
        self._kept: tuple[tuple, PrefixRecognition] | None = None
        self._lock = threading.RLock()  # end() plays under it, as recognise() does

    def recognise(self, space: TaskSpace, statements, start_q, world: ObjectWorld,
                  progress: Callable[[int, int], None]) -> ProgramRecognition:
        """``statements`` played from ``start_q`` with ``world``'s objects, recognised."""
        q = np.asarray(start_q, dtype=float)
        key = (q.tobytes(), _world_key(world))
        with self._lock:
            if self._kept is None or self._kept[0] != key:
                self._kept = (key, PrefixRecognition(self._cell, space, q, world))
            return self._kept[1].recognise(statements, progress=progress)

    def program_end(self, space: TaskSpace, source, frames, wait: bool = True):
        """``TaskMonitor.program_end`` for a preview source's whole program."""
        statements, start_q, poses, held = source
        if not statements:
            return None
        robot = self._cell.robot
        world = ObjectWorld(self._cell)
        world.take_reported(poses, held, frames.world_T_tcp(robot, np.asarray(start_q)))
        if not self._lock.acquire(blocking=wait):
            return False  # a play holds it (seconds on a long range): the caller asks again later
        try:
            rec = self.recognise(space, statements, start_q, world, lambda _done, _total: None)
            end_world, q_end = self._kept[1].world_at_end(), self._kept[1].q_end.copy()
        finally:
            self._lock.release()
        return frozenset(rec.final_marking), end_world.poses(frames.world_T_tcp(robot, q_end))


def _world_key(world: ObjectWorld) -> tuple:
    """What of ``world`` a play depends on, as bytes: where the objects are and what is held how."""
    def raw(a) -> bytes:
        return b"" if a is None else np.asarray(a).tobytes()

    placed = tuple(sorted((k, raw(v)) for k, v in world.placed.items()))
    return placed, world.held, raw(world.tcp_T_held), raw(world.world_T_tcp_inserted)


def _space_model(space: TaskSpace, m0: frozenset[str] | set[str]) -> ConditionEventModel:
    """The grounded task space as a C/E model with short ids (P1.. by atom, T1.. by action),
    marked as the cell was loaded: the picture the task panel draws."""
    pid = {a.text: f"P{i + 1}" for i, a in enumerate(space.atoms)}
    return ConditionEventModel(
        places=[ConditionModel(id=pid[a.text], predicate=a.text) for a in space.atoms],
        transitions=[EventModel(id=f"T{j + 1}", action=act.text, pre=[pid[p] for p in act.pre], post=[pid[p] for p in act.post])
                     for j, act in enumerate(space.actions)],
        initial_marking=[pid[a.text] for a in space.atoms if a.text in m0],
    )
