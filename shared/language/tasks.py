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

What each task does to the arm and the objects is declared once, in its ``effect``
(:class:`TaskEffect`), and both sides read it: the robot's task code (``robot_sim.executor``)
aims its motions at the pose the effect names, and the console's planner
(``shared.motion.interpreter``, through ``shared.motion.task_effects``) predicts the same pose, so
the preview and the virtual arm end where the robot ends. ``insert_peg`` ends with the held peg
seated in the hole (its foot on the hole's axis, ``seat depth`` below the mouth, the tool's
orientation kept); ``extract_peg`` lifts the tool ``EXTRACT_LIFT_M`` along the hole's axis;
``release`` opens and backs the tool ``RELEASE_RETREAT_M`` along its own axis; ``grasp`` keeps the
arm still. Where contact decides the exact end (the insertion's search), the effect says how far
the robot's end may lie from the prediction for a successful task (``tolerance_m``,
``tolerance_rad``): within it the robot's report is the truth and no divergence is told.

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
ArmMotion = Literal["still", "lift", "seat", "retreat"]
ObjectChange = Literal["none", "grasp", "release", "carry"]

EXTRACT_LIFT_M = 0.05
"""How far ``extract_peg`` lifts the tool along the hole's axis (m): the peg of the §4.6 cell
sits 30 mm deep, so 50 mm leaves it 20 mm clear of the mouth."""
RELEASE_RETREAT_M = 0.0
"""How far ``release`` backs the tool along its own axis once the fingers are open (m). The §4.6
gripper opens to 60 mm round a 20 mm peg, so the fingers clear it where they are and the arm
stays still (the editor's rule: a release may follow an insertion). A gripper that needs to back
off sets it here, and the robot and the console's planner both move by it."""
HOLE_DEPTH_M = 0.030
"""How deep ``insert_peg`` seats a peg below a hole's mouth when the cell does not say (m): the
§4.6 plate's holes. A cell whose peg stands in a hole at load says it by that seat."""
INSERT_TOLERANCE_M = 0.005
"""How far (m) a successful insertion's tool may end from the predicted seat: the search may find
the hole up to 4 mm from the first contact, and a peg 2 mm above the floor is seated."""
INSERT_TOLERANCE_RAD = 0.07
"""How far (rad) its tool may turn from the predicted orientation (the compliance's 3.4 deg)."""
EXTRACT_TOLERANCE_M = 0.004
"""How far (m) a successful extraction's tool may end from the predicted lift: the force-compliant
pull follows a peg that sits off the modelled hole sideways, up to the compliance's 4 mm."""


@dataclass(frozen=True)
class TaskEffect:
    """What a task does to the arm and the objects: the one definition the robot's task code and
    the console's planner both read (``shared.motion.task_effects`` turns it into poses).

    ``arm``: ``still`` (the tool stays), ``lift`` (``distance_m`` along the hole's axis, the
    second argument), ``seat`` (the held object's foot on the hole's axis at the seat depth, the
    tool's orientation kept), ``retreat`` (``distance_m`` back along the tool's own axis).
    ``objects``: ``grasp`` (the first argument is held where it is), ``release`` (the held
    object stays where the tool leaves it), ``carry`` (the held object rides with the tool),
    ``none``. ``tolerance_m`` / ``tolerance_rad``: how far the robot's end may lie from the
    predicted one when contact decides it (0: the robot ends exactly there, within its servo)."""

    arm: ArmMotion = "still"
    objects: ObjectChange = "none"
    distance_m: float = 0.0
    tolerance_m: float = 0.0
    tolerance_rad: float = 0.0

    @property
    def by_contact(self) -> bool:
        """Contact decides where the arm ends exactly (within the tolerance)."""
        return self.tolerance_m > 0.0 or self.tolerance_rad > 0.0


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
    effect: TaskEffect = TaskEffect()

    def signature(self) -> str:
        return f"{self.name}({', '.join(p.value for p in self.params)})"


TASKS: dict[str, TaskSpec] = {
    t.name: t
    for t in (
        TaskSpec("grasp", (ArgKind.OBJECT,), "still", "close the gripper on an object at the tool", needs_holding=False,
                 effect=TaskEffect("still", "grasp")),
        TaskSpec("release", (), "still", "open the gripper and let go of what it holds", needs_holding=True,
                 effect=TaskEffect("retreat", "release", RELEASE_RETREAT_M)),
        TaskSpec(
            "extract_peg", (ArgKind.PEG_OBJECT, ArgKind.HOLE_FEATURE), "retract",
            "pull the held peg out of the hole along the hole's axis (force-compliant)", needs_holding=True,
            effect=TaskEffect("lift", "carry", EXTRACT_LIFT_M, EXTRACT_TOLERANCE_M, INSERT_TOLERANCE_RAD),
        ),
        TaskSpec(
            "insert_peg", (ArgKind.PEG_OBJECT, ArgKind.HOLE_FEATURE), "unknown",
            "search for the hole and insert the held peg until seated (force-compliant)", needs_holding=True,
            effect=TaskEffect("seat", "carry", tolerance_m=INSERT_TOLERANCE_M, tolerance_rad=INSERT_TOLERANCE_RAD),
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
