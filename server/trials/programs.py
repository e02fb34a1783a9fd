"""The peg transfer of thesis §3.5.6 and §4.6 as the statements an operator makes, phase by
phase, for any cell with a movable peg standing in one hole and another hole to put it in.

The phases are the trials' pieces: ``approach`` (home to 70 mm above the peg's top, gripper
down), ``grasp`` (down to the grasp height until contact, then the grasp task), ``extract`` (the
robot's extraction task), ``carry`` (up, across, down to 20 mm above the target hole's mouth),
``insert`` (force mode and the robot's insertion task) and ``release`` (open, position mode).
Heights come from the cell: the peg's top from its box, the fingers' centre 15 mm below it (as in
``assets/programs/peg_transfer.tp``, which this reproduces for the shipped cell).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from shared.errors import InputError

Phase = Literal["approach", "grasp", "extract", "carry", "insert", "release"]
PHASES: tuple[Phase, ...] = ("approach", "grasp", "extract", "carry", "insert", "release")
APPROACH_CLEARANCE_M = 0.070  # above the peg's top where the approach ends
GRIP_BELOW_TOP_M = 0.015  # the fingers' centre below the peg's top
ABOVE_MOUTH_M = 0.020  # the peg's foot above the target hole's mouth before the insertion
SEAT_MATCH_M = 0.001  # the peg's axis within this of a hole's axis: it stands in that hole


@dataclass(frozen=True)
class PhaseStatement:
    phase: Phase
    text: str


@dataclass(frozen=True)
class TransferProgram:
    cell: str
    peg: str
    from_hole: str
    to_hole: str
    statements: tuple[PhaseStatement, ...]

    def texts(self, *phases: Phase) -> list[str]:
        """The statements of these phases (all when none is named), in program order."""
        return [s.text for s in self.statements if not phases or s.phase in phases]


def _mm(p: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:.2f}".rstrip("0").rstrip(".") for v in np.round(p * 1e3, 2) + 0.0) + ") mm"


def transfer_program(cell_path: str | Path, peg: str | None = None, to_hole: str | None = None) -> TransferProgram:
    """The peg transfer for the cell at ``cell_path`` (the first movable object when ``peg`` is
    None, the first other hole when ``to_hole`` is None); ``InputError`` names what is missing."""
    from shared.cells.loader import load_cell

    cell = load_cell(cell_path)
    if "work" not in cell.frames:
        raise InputError(f"{cell_path}: the cell has no 'work' frame to state the transfer in")
    movable = [o for o in cell.objects if o.movable and any(s.kind == "box" for s in o.shapes)]
    if peg is None:
        if not movable:
            raise InputError(f"{cell_path}: the cell has no movable box-shaped object (a peg) to transfer")
        obj = movable[0]
    else:
        obj = next((o for o in movable if o.name.lower() == peg.lower()), None)
        if obj is None:
            raise InputError(f"{cell_path}: no movable box-shaped object named {peg!r}; "
                             f"movable: {', '.join(o.name for o in movable) or 'none'}")
    holes = {f.name: f for f in cell.features.values() if f.kind == "hole"}
    world_p_obj = obj.world_T_object[:3, 3]
    start = next((h for h in holes.values() if np.linalg.norm(h.world_T_feature[:2, 3] - world_p_obj[:2]) < SEAT_MATCH_M), None)
    if start is None:
        raise InputError(f"{cell_path}: {obj.name} stands in no hole (holes: {', '.join(holes) or 'none'})")
    targets = [h for h in holes.values() if h.name != start.name]
    if to_hole is not None:
        targets = [h for h in targets if h.name.lower() == to_hole.lower()]
    if not targets:
        raise InputError(f"{cell_path}: no hole other than {start.name} to put {obj.name} in"
                         + (f" named {to_hole!r}" if to_hole else ""))
    target = targets[0]

    work_T_world = np.linalg.inv(cell.frames["work"])
    box = next(s for s in obj.shapes if s.kind == "box")
    top = float(box.link_T_shape[2, 3] + box.size[2] / 2.0)
    length = float(box.size[2])
    p_obj = (work_T_world @ obj.world_T_object)[:3, 3]
    p_top = p_obj + np.array([0.0, 0.0, top])
    above_peg = p_top + np.array([0.0, 0.0, APPROACH_CLEARANCE_M])
    grip = p_top - np.array([0.0, 0.0, GRIP_BELOW_TOP_M])
    mouth = (work_T_world @ target.world_T_feature)[:3, 3]
    above_target = np.array([mouth[0], mouth[1], above_peg[2]])
    over_mouth = mouth + np.array([0.0, 0.0, ABOVE_MOUTH_M + length - GRIP_BELOW_TOP_M])
    name = obj.name
    rows: list[tuple[Phase, str]] = [
        ("approach", "SPEED 50 %"),
        ("approach", f"MOVES TO {_mm(above_peg)} (180, 0, 0) deg IN WORK"),
        ("grasp", f"DRAW TO {_mm(grip)} IN WORK WITH SPEED 10 mm/s UNTIL CONTACT"),
        ("grasp", f"TASK grasp({name})"),
        ("extract", f"TASK extract_peg({name}, {start.name})"),
        ("carry", f"DRAW TO {_mm(above_peg)} IN WORK WITH SPEED 30 mm/s"),
        ("carry", f"DRAW TO {_mm(above_target)} IN WORK"),
        ("carry", f"DRAW TO {_mm(over_mouth)} IN WORK WITH SPEED 10 mm/s"),
        ("insert", "MODE FORCE"),
        ("insert", f"TASK insert_peg({name}, {target.name})"),
        ("release", "TASK release()"),
        ("release", "MODE POSITION"),
    ]
    return TransferProgram(str(cell_path), name, start.name, target.name,
                           tuple(PhaseStatement(phase, text) for phase, text in rows))
