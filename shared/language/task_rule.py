"""What may follow a task call: one rule, read from the task registry's end-state contracts.

The editor (``shared.program.editor`` and ``shared.program.rules.program_violations``), the
checks behind ``teleprog check`` (``shared.language.checks``) and the planner
(``shared.motion.interpreter``) all ask this module, so a program one of them accepts the others
accept too.

Each task of ``shared.language.tasks.TASKS`` says how the arm's pose after it is known
(``arm_end``):

* ``still`` (grasp, release) and ``retract`` (extract_peg): the pose after the task is known (the
  same pose, or the one the task's contract fixes), so anything may follow;
* ``unknown`` (insert_peg, and any task the registry does not know): only the robot will know where
  the arm ends, so until it reports, only statements that leave the arm where it is may follow:
  parameter statements (SPEED, MODE, EVENT) and tasks that keep the arm still.

Thesis §4.3.6 lets nothing follow any task call; that literal reading survives as
``teleprog check --strict-tasks``. The registry's contracts are the finer rule: they let the
shipped peg transfer (grasp, extract, carry, insert, release) be one program.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from shared.language.statements import is_action, is_task
from shared.language.tasks import TASKS, ArmEnd


def task_arm_end(name: str) -> ArmEnd:
    """How the arm's pose after the task ``name`` is known; ``unknown`` for a task not in the registry."""
    spec = TASKS.get(name) or TASKS.get(name.lower())
    return "unknown" if spec is None else spec.arm_end


def moves_arm(statement: object) -> bool:
    """Actions, and task calls not known to keep the arm still."""
    if is_task(statement):
        return task_arm_end(statement.name) != "still"
    return is_action(statement)


@dataclass(frozen=True, slots=True)
class UnknownPose:
    """The arm's pose is unknown from here on: the task call that left it so, and its 0-based index."""

    task: str
    index: int


def pose_after(
    statement: object, index: int, before: UnknownPose | None, arm_end: ArmEnd | None = None
) -> UnknownPose | None:
    """Whether the arm's pose is unknown after ``statement`` (at ``index``), given ``before``.

    ``arm_end`` overrides the registry's contract for this call: the planner passes ``unknown``
    for an ``extract_peg`` whose hole it cannot find in the cell. A pose once unknown stays
    unknown (nothing that may follow can make it known again; only the robot's report can).
    """
    if before is not None:
        return before
    if is_task(statement) and (arm_end or task_arm_end(statement.name)) == "unknown":
        return UnknownPose(statement.name, index)
    return None


def may_follow(statement: object, unknown: UnknownPose | None) -> bool:
    """Whether ``statement`` may come next when the arm's pose is ``unknown`` (None: it is known)."""
    return unknown is None or not moves_arm(statement)


def why_not(statement: object, unknown: UnknownPose, where: str | None = None) -> str:
    """The sentence for a ``statement`` that may not follow the task of ``unknown``; ``where``
    names that task's place (default: ``statement N``)."""
    place = where or f"statement {unknown.index + 1}"
    kind = getattr(statement, "kind", type(statement).__name__)
    what = f"TASK {statement.name}" if is_task(statement) else kind
    return (
        f"{what} cannot follow TASK {unknown.task} ({place}): the arm's pose after that task is known only "
        "when the robot reports it; only parameter statements and tasks that keep the arm still may follow"
    )


@dataclass(frozen=True, slots=True)
class TaskRuleBreak:
    """A statement (0-based ``index``) that may not follow the task call at ``after.index``."""

    index: int
    after: UnknownPose
    message: str


def task_rule_breaks(statements: Sequence[object]) -> list[TaskRuleBreak]:
    """Every statement of a whole program that may not stand where it is, in order."""
    breaks: list[TaskRuleBreak] = []
    unknown: UnknownPose | None = None
    for index, statement in enumerate(statements):
        if unknown is not None and not may_follow(statement, unknown):
            breaks.append(TaskRuleBreak(index, unknown, f"statement {index + 1}: " + why_not(statement, unknown)))
            continue
        unknown = pose_after(statement, index, unknown)
    return breaks
