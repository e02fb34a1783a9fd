"""Actions to statements (issue 40): each rule of a task space has a motion template in its task
file (``statements``; for the peg cell, the statements the thesis's own peg transfer,
``assets/programs/peg_transfer.tp``, makes for it), and
a planned action run becomes a program by filling the templates with the modelled poses of the
objects and features the actions name.

A template line may hold fields, each ``{what VAR ...}`` over the rule's variables:

* ``{obj p}`` / ``{feat h}``: the cell object or feature the individual bound to ``p``/``h`` is;
* ``{above p}``: ``APPROACH_CLEARANCE_MM`` above the top of ``p``'s box, where ``p`` is now;
* ``{grip p}``: the fingers' centre ``GRIP_BELOW_TOP_MM`` below that top;
* ``{carry h}``: over ``h``'s mouth at the carrying height (the approach height above the
  tallest movable object as loaded);
* ``{over p h}``: the tool where ``p``'s foot is ``ABOVE_MOUTH_MM`` over ``h``'s mouth.

Positions are written in mm in the cell's ``work`` frame (the gripper down is ``(180, 0, 0)``
deg there). Nothing here knows a cell or a task: every number comes from the cell's objects and
features, every line from the task file, and an action that adds an atom placing an object at a
feature seats that object there for the actions after it.
Each action's statements are preceded by a comment line naming it, so the program shows which
statements serve which action.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from shared.errors import InputError
from shared.tasknet.taskspace import TEMPLATE_FIELD, GroundAction, TaskSpace, parse_atom

APPROACH_CLEARANCE_MM = 70.0
GRIP_BELOW_TOP_MM = 15.0
ABOVE_MOUTH_MM = 20.0
SEAT_MATCH_MM = 1.0
"""An object whose axis is within this of a feature's axis at load stands in that feature."""



@dataclass(frozen=True)
class ActionStatements:
    action: str
    statements: tuple[str, ...]


def _mm(p: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:.2f}".rstrip("0").rstrip(".") for v in np.round(p, 2) + 0.0) + ") mm"


class _Scene:
    """Where the objects are (mm, work frame) as the actions move them."""

    def __init__(self, cell, poses: Mapping[str, np.ndarray] | None = None) -> None:
        """``poses``: where the objects are now (world_T_object by name; default: as loaded)."""
        work_T_world = np.linalg.inv(cell.frame("work"))
        poses = poses or {}
        self.cell = cell
        self.features = {n: (work_T_world @ f.world_T_feature)[:3, 3] * 1e3 for n, f in cell.features.items()}
        self.pos: dict[str, np.ndarray] = {}
        self.top: dict[str, float] = {}  # box top above the object's origin
        self.length: dict[str, float] = {}
        self.seat: dict[str, np.ndarray] = {}  # origin relative to the mouth it stands in
        for o in cell.objects:
            box = next((s for s in o.shapes if s.kind == "box"), None)
            if not o.movable or box is None:
                continue
            p = (work_T_world @ np.asarray(poses.get(o.name, o.world_T_object), dtype=float))[:3, 3] * 1e3
            self.pos[o.name] = p
            self.top[o.name] = float(box.link_T_shape[2, 3] + box.size[2] / 2.0) * 1e3
            self.length[o.name] = float(box.size[2]) * 1e3
            for mouth in self.features.values():
                if np.linalg.norm(mouth[:2] - p[:2]) < SEAT_MATCH_MM:
                    self.seat[o.name] = p - mouth
        if not self.pos:
            raise InputError(f"cell {cell.name!r} has no movable box-shaped object for the task's actions")
        self.carry_z = max(p[2] + self.top[n] + APPROACH_CLEARANCE_MM for n, p in self.pos.items())

    def obj(self, name: str) -> np.ndarray:
        if name not in self.pos:
            raise InputError(f"cell {self.cell.name!r} has no movable box-shaped object {name!r}; "
                             f"movable: {', '.join(self.pos)}")
        return self.pos[name]

    def mouth(self, name: str) -> np.ndarray:
        if name not in self.features:
            raise InputError(f"cell {self.cell.name!r} has no feature {name!r}; features: {', '.join(self.features)}")
        return self.features[name]

    def field(self, what: str, names: list[str]) -> str:
        if what == "obj" or what == "feat":
            return names[0]
        if what == "above":
            return _mm(self.obj(names[0]) + [0.0, 0.0, self.top[names[0]] + APPROACH_CLEARANCE_MM])
        if what == "grip":
            return _mm(self.obj(names[0]) + [0.0, 0.0, self.top[names[0]] - GRIP_BELOW_TOP_MM])
        if what == "carry":
            m = self.mouth(names[0])
            return _mm(np.array([m[0], m[1], self.carry_z]))
        if what == "over":
            o, m = names[0], self.mouth(names[1])
            foot_below_grip = self.length[o] - GRIP_BELOW_TOP_MM
            return _mm(m + [0.0, 0.0, ABOVE_MOUTH_MM + foot_below_grip])
        raise InputError(f"template field {{{what} ...}} is not one of obj, feat, above, grip, carry, over")

    def after(self, space: TaskSpace, act: GroundAction) -> None:
        """Move the modelled objects as the action does: an atom it adds that places an object at
        a feature (``PEGINHOLE(PEG, HOLE2)``: one argument bound to a cell object, one to a cell
        feature) seats the object in that feature, as it stood in its feature at load."""
        inds = space.spec.individuals
        for atom in act.add:
            _, args = parse_atom(atom)
            objects = [inds[a].object for a in args if a in inds and inds[a].object]
            features = [inds[a].feature for a in args if a in inds and inds[a].feature]
            if len(args) == 2 and len(objects) == 1 and len(features) == 1 and objects[0] in self.pos:
                o, m = objects[0], self.mouth(features[0])
                self.pos[o] = m + self.seat.get(o, np.array([0.0, 0.0, self.length[o] / 2.0]))


def _cell_name(space: TaskSpace, individual: str) -> str:
    spec = space.spec.individuals[individual]
    return spec.object or spec.feature or individual


def action_statements(space: TaskSpace, cell, actions: list[GroundAction] | tuple[GroundAction, ...],
                      templates: dict[str, tuple[str, ...]] | None = None,
                      poses: Mapping[str, np.ndarray] | None = None) -> list[ActionStatements]:
    """The statements of each action, filled from the objects' modelled poses in order: where
    ``poses`` has them (the virtual cell's, world_T_object by name), else as the cell loads them."""
    table = {r.name: tuple(r.statements) for r in space.spec.rules if r.statements} if templates is None else templates
    scene = _Scene(cell, poses)
    out = []
    for act in actions:
        if act.rule not in table:
            raise InputError(f"action {act.text}: the rule {act.rule!r} has no statements in the task file "
                             f"{space.spec.name!r} (rules with statements: {', '.join(table) or 'none'})")
        rule = next(r for r in space.spec.rules if r.name == act.rule)
        binding = {var: _cell_name(space, ind) for var, ind in zip(rule.params, act.args)}

        def fill(m: re.Match) -> str:
            names = []
            for var in m.group(2).split():
                if var not in binding:
                    raise InputError(f"template of {act.rule}: {m.group(0)} names {var!r}, not a variable of the rule")
                names.append(binding[var])
            return scene.field(m.group(1), names)

        out.append(ActionStatements(act.text, tuple(TEMPLATE_FIELD.sub(fill, line) for line in table[act.rule])))
        scene.after(space, act)
    return out


def program_text(rows: list[ActionStatements]) -> str:
    """The program: each action's statements after a comment line naming it."""
    lines = []
    for row in rows:
        lines.append(f"# action {row.action}")
        lines.extend(row.statements)
    return "\n".join(lines) + "\n"


def cell_marking(space: TaskSpace, cell, q=None) -> frozenset[str]:
    """The marking recognised in the cell as loaded, the arm at ``q`` (default: home)."""
    from shared.cells.object_world import ObjectWorld
    from shared.motion.frames import CellFrames
    from shared.tasknet.coordinator import TaskCoordinator
    from shared.tasknet.contacts import CellState, ContactModel

    frames = CellFrames.from_cell(cell)
    q = cell.q_home if q is None else q
    state = CellState.of_world(ObjectWorld(cell), frames.world_T_tcp(cell.robot, np.asarray(q, dtype=float)))
    return TaskCoordinator(space, ContactModel(space, cell), state).m0
