"""The tasks the telerobot knows: one typed registry, read by the checks, the editor and the robot.

A task call (``TASK insert_peg(peg, HOLE1)``) hands a whole sub-task to the robot's own
autonomy (thesis §4.3.5 c, §4.6: extraction and insertion ran as pre-developed sub-tasks). The
console cannot predict where a force-guided task leaves the arm, which is why §4.3.6 lets
nothing follow a task call. Each entry here says how its end state is known:

* ``still``: the arm does not move (the gripper closes or opens), so the pose after the task is
  the pose before it and the program may go on;
* ``retract``: the arm ends at a pose fixed by the task's contract (``extract_peg`` pulls the
  peg straight out along the hole's axis and stops ``EXTRACT_LIFT_M`` above where it started),
  so the program may go on from that pose;
* ``unknown``: the end pose depends on contact (``insert_peg`` searches and seats the peg); no
  action may follow, only parameter statements and tasks that keep the arm still.

Argument kinds name what an argument must be in the cell: any object, a movable object (a peg),
or a feature (a hole). Names resolve case-insensitively (``PEG`` is the cell's ``peg``) when that
is unambiguous; :func:`resolve_name` is the one rule both sides use.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Literal

from shared.errors import UnknownNameError

ArmEnd = Literal["still", "retract", "unknown"]

EXTRACT_LIFT_M = 0.05
"""How far ``extract_peg`` lifts the tool along the hole's axis (m): the peg of the §4.6 cell
sits 30 mm deep, so 50 mm leaves it 20 mm clear of the mouth."""


class ArgKind(str, Enum):
    OBJECT = "OBJECT"  # any object of the cell
    PEG_OBJECT = "PEG_OBJECT"  # a movable object
    HOLE_FEATURE = "HOLE_FEATURE"  # a feature of the cell (kind "hole" when the cell says so)


@dataclass(frozen=True)
class TaskSpec:
    """One known task: its name, argument kinds, how its end state is known, what it does."""

    name: str
    params: tuple[ArgKind, ...]
    arm_end: ArmEnd
    summary: str
    needs_holding: bool | None = None  # True: gripper must hold the first argument; False: must be empty

    def signature(self) -> str:
        return f"{self.name}({', '.join(p.value for p in self.params)})"


TASKS: dict[str, TaskSpec] = {
    t.name: t
    for t in (
        TaskSpec("grasp", (ArgKind.OBJECT,), "still", "close the gripper on an object at the tool", needs_holding=False),
        TaskSpec("release", (), "still", "open the gripper and let go of what it holds", needs_holding=True),
        TaskSpec(
            "extract_peg", (ArgKind.PEG_OBJECT, ArgKind.HOLE_FEATURE), "retract",
            "pull the held peg out of the hole along the hole's axis (force-compliant)", needs_holding=True,
        ),
        TaskSpec(
            "insert_peg", (ArgKind.PEG_OBJECT, ArgKind.HOLE_FEATURE), "unknown",
            "search for the hole and insert the held peg until seated (force-compliant)", needs_holding=True,
        ),
    )
}


def find_task(name: str) -> TaskSpec:
    """The task called ``name`` (case-insensitive); ``UnknownNameError`` lists the known ones."""
    spec = TASKS.get(name) or TASKS.get(name.lower())
    if spec is None:
        raise UnknownNameError("task", name, [t.signature() for t in TASKS.values()])
    return spec


def resolve_name(name: str, choices: list[str] | tuple[str, ...]) -> str | None:
    """``name`` if it is one of ``choices``, else the one choice equal ignoring case, else None."""
    if name in choices:
        return name
    folded = [c for c in choices if c.lower() == name.lower()]
    return folded[0] if len(folded) == 1 else None
