"""Task-level commands (issue 40): a goal of the cell's task space planned from where the program
leaves the virtual cell (``shared.tasknet.goals.plan_goal``; the virtual cell itself when the
program is empty), or one action enabled there; either
inserts its actions' statements (``shared.tasknet.action_program``, filled from where the virtual
cell's objects are now) before the selection as one edit, each line marked with the action it
serves (``task_lines.py``). ``POST /api/task/goal``, ``POST /api/task/action`` and the Task tab's
goal box and action buttons all come here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from server.console.errors import ConflictError
from server.console.statement_checks import statement_text
from shared.errors import TeleprogError
from server.console.views import Caller, ProgramView
from shared.language.parser import parse_statement
from shared.language.task_rule import may_follow, pose_after
from shared.tasknet.action_program import ActionStatements, action_statements
from shared.tasknet.goals import GoalPlan, enabled_actions, plan_goal, resolve_action
from shared.tasknet.taskspace import TaskSpace

if TYPE_CHECKING:
    from server.console.arm import VirtualArm
    from server.console.context import ConsoleContext
    from server.console.control import ControlLock
    from server.console.program_desk import ProgramDesk
    from server.console.task_monitor import TaskMonitor


@dataclass(frozen=True)
class TaskInsert:
    """What a task command inserted: the goal's plan (None for one action), each action's
    statements, and the program after."""

    plan: GoalPlan | None
    rows: tuple[ActionStatements, ...]
    program: ProgramView
    deferred: tuple[str, ...] = ()
    """The plan's actions not inserted: they would move the arm after a task whose end only the
    robot knows (``shared.language.task_rule``); plan the goal again once it reports."""
    warnings: tuple[str, ...] = ()
    """What the preview's check finds on the inserted lines (planned with the console's planner:
    the arm touching something, a joint out of range, a refused plan), each naming its line."""


class TaskCommands:
    """``session.task_commands``."""

    def __init__(self, ctx: ConsoleContext, control: ControlLock, monitor: TaskMonitor, desk: ProgramDesk,
                 arm: VirtualArm) -> None:
        self._ctx, self._cell = ctx, ctx.cell
        self._control, self._monitor, self._desk, self._arm = control, monitor, desk, arm

    def _space(self) -> TaskSpace:
        space = self._monitor.space
        if space is None:
            raise ConflictError("this cell has no task model (assets/tasks/<cell>.toml): there are no task actions")
        return space

    def _where(self, wait: bool = True) -> tuple[frozenset[str], dict] | None:
        """Where the next task lines start: the marking and the objects' poses where the program
        as it stands leaves the virtual cell (the virtual cell itself when the program is empty),
        so an action button after another, or a goal after both, continues from there."""
        end = self._monitor.program_end(wait)
        if end is False:
            return None  # busy, and not to be waited for
        if end is not None:
            return end
        return frozenset(self._monitor.view().virtual_marking), self._arm.object_poses_now()

    def offered(self, wait: bool = True) -> list[str] | None:
        """The actions enabled where the program leaves the virtual cell, never one that puts an
        object in two places (what the Task tab offers as buttons); none without a task model;
        None when not ``wait`` and a play of the task panel is under way (ask again later)."""
        if self._monitor.space is None:
            return []
        where = self._where(wait)
        return None if where is None else [a.text for a in enabled_actions(self._monitor.space, where[0])]

    def goal(self, goal: list[str] | str, *, keep: bool = True, client: Caller | str | None = None) -> TaskInsert:
        """Plan ``goal`` from where the program leaves the virtual cell and insert its statements (one undo step); a
        goal no reachable marking meets is an ``InputError`` naming the atom."""
        self._control.check(client)  # before the search
        marking, poses = self._where()
        plan = plan_goal(self._space(), marking, goal, keep=keep)
        rows, deferred = _until_unknown_end(self._statements(plan.actions, poses), self._desk.state.unknown_pose)
        view, warnings = self._insert(rows, f"plan {', '.join(plan.goal)}", client)
        return TaskInsert(plan, rows, view, deferred, warnings)

    def action(self, text: str, *, client: Caller | str | None = None) -> TaskInsert:
        """Insert the statements of the action ``text`` (one undo step); one the virtual marking
        does not enable is refused, naming what does not hold."""
        self._control.check(client)
        space = self._space()
        act = resolve_action(space, text)
        marking, poses = self._where()
        if act not in enabled_actions(space, marking):
            missing = [a for a in act.pre if a not in marking]
            why = (f"{', '.join(missing)} does not hold" if missing
                   else "its results hold already, or it would put an object in two places")
            raise ConflictError(f"{act.text} is not enabled in the virtual cell: {why}")
        rows = self._statements([act], poses)
        view, warnings = self._insert(rows, act.text, client)
        return TaskInsert(None, rows, view, warnings=warnings)

    def _statements(self, actions, poses: dict) -> tuple[ActionStatements, ...]:
        return tuple(action_statements(self._space(), self._cell, actions, poses=poses))

    def _insert(self, rows: tuple[ActionStatements, ...], label: str,
                client: Caller | str | None) -> tuple[ProgramView, tuple[str, ...]]:
        """Insert the rows (one edit), then check the inserted lines as a preview checks them."""
        if not rows:
            return self._desk.view(), ()
        view = self._desk.insert_actions([(r.action, r.statements) for r in rows], label, client=client)
        count = sum(len(r.statements) for r in rows)
        at = view.selected - count  # they went in before the selection, which stays on its statement
        with self._ctx.lock:
            try:
                found = self._desk.preview.path_not_clear(at, at + count) if self._desk.preview is not None else {}
            except TeleprogError as exc:  # the start is the robot's to report, or the planner failed on it
                found = {at: f"not checked: {exc}"}
            statements = self._desk.state.statements
        warnings = tuple(f"statement {i + 1} ({statement_text(statements[i])}): {why}" for i, why in sorted(found.items()))
        return view, warnings


def _until_unknown_end(rows: tuple[ActionStatements, ...], unknown) -> tuple[tuple[ActionStatements, ...], tuple[str, ...]]:
    """The rows a program may hold in one piece, from a program whose pose is ``unknown`` after
    one of its tasks (None: known): every row whose statements may follow what comes before
    them (a motion may not follow an insertion only the robot's report ends), and the actions
    of the rows left out."""
    for k, row in enumerate(rows):
        for text in row.statements:
            statement = parse_statement(text)
            if not may_follow(statement, unknown):
                return rows[:k], tuple(r.action for r in rows[k:])
            unknown = pose_after(statement, 0, unknown)
    return rows, ()
