"""The seeded catalogue of faults a campaign draws from, one fault per run.

Every fault is typed (:class:`Fault`): its kind, when it strikes (``at_s`` after the program's
first submit), its size in the unit a person reads (``magnitude`` with ``unit``), and what the kind
needs besides (a direction, a joint, a duration). The draw (:func:`draw_fault`) depends on the
run's seed and on what the group's fault-free run did (:class:`CleanTrace`: how long it took,
where the tool went, when the last task started), never on the faulted run itself, so a seed
replays its fault exactly.

| kind | what changes | magnitude |
|---|---|---|
| ``object_moved`` | a movable object moved: into another free hole, or sideways on the cell | mm |
| ``object_missing`` | a movable object gone | - |
| ``hole_moved`` | the plate with its holes (and what stands in them) moved sideways | mm |
| ``peg_slip`` | the held object slips: the finger pads lose their grip (friction) | friction |
| ``obstacle`` | an unmodelled box on the tool's coming path | mm (half size) |
| ``heavier`` | a movable object heavier than modelled (from the start) | x mass |
| ``friction`` | every contact's friction far off the model (from the start) | x friction |
| ``jam`` | a block at the bottom of the target hole | mm (height) |
| ``joint_drag`` | a torque disturbance on one joint | N m |
| ``sensor_bias`` | the wrist sensor reads a constant force more | N |
| ``sensor_dropout`` | the wrist sensor's readings flagged invalid | - |
| ``link_cut`` | the connection breaks; the console reconnects after ``duration_s`` | s |
| ``link_stall`` | nothing passes the link either way for ``duration_s`` (line or link process frozen) | s |
| ``jitter_burst`` | each message takes up to ``magnitude`` s more, for ``duration_s`` | s |
| ``console_frozen`` | the console sends nothing, heartbeats included, for ``duration_s`` | s |
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict

FaultKind = Literal[
    "none", "object_moved", "object_missing", "hole_moved", "peg_slip", "obstacle", "heavier", "friction", "jam",
    "joint_drag", "sensor_bias", "sensor_dropout", "link_cut", "link_stall", "jitter_burst", "console_frozen",
]
WORLD_KINDS = ("object_moved", "object_missing", "hole_moved", "peg_slip", "obstacle", "heavier", "friction", "jam")
ROBOT_KINDS = ("joint_drag", "sensor_bias", "sensor_dropout")
LINK_KINDS = ("link_cut", "link_stall", "jitter_burst", "console_frozen")
FAULT_KINDS: tuple[str, ...] = WORLD_KINDS + ROBOT_KINDS + LINK_KINDS
BLINDING_KINDS = frozenset(("sensor_dropout",))
"""Kinds that leave the robot without a sense it moves by: they matter once it moves (:mod:`.judge`).
A biased sensor is judged as a change of the world: by the force the robot really exerts."""


def check_kinds(kinds: tuple[str, ...]) -> tuple[str, ...]:
    """``kinds`` if every one is in the catalogue; an ``InputError`` naming the first that is not."""
    from shared.errors import InputError

    bad = [k for k in kinds if k not in FAULT_KINDS]
    if bad:
        raise InputError(f"--kind {bad[0]}: not a fault kind; kinds: {', '.join(FAULT_KINDS)}")
    return kinds


class Fault(BaseModel):
    """One run's fault (kind ``none``: a fault-free run)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: FaultKind
    at_s: float = 0.0
    magnitude: float = 0.0
    unit: str = ""
    direction: tuple[float, float, float] = (0.0, 0.0, 0.0)
    joint: int | None = None
    duration_s: float = 0.0
    target: str | None = None  # the object or hole it acts on

    def describe(self) -> str:
        if self.kind == "none":
            return "no fault"
        size = f" {self.magnitude:.3g} {self.unit}".rstrip() if self.unit else ""
        on = f" on {self.target}" if self.target else ""
        joint = f" on joint {self.joint + 1}" if self.joint is not None else ""
        lasting = f" for {self.duration_s:.2f} s" if self.duration_s else ""
        return f"{self.kind}{size}{on}{joint}{lasting} at {self.at_s:.2f} s"


@dataclass
class CleanTrace:
    """What the group's fault-free run did, tick by tick (ground truth, physics): the twin a
    faulted run is compared with, and what a fault's draw may depend on."""

    dt: float
    start: float  # the program's first submit (virtual s)
    end: float  # the robot's last final report (virtual s)
    last_task_start: float  # when the robot started its last task statement
    ticks: dict[int, int] = field(default_factory=dict)  # tick number -> row
    tcp: list[tuple[float, float, float]] = field(default_factory=list)
    finger: list[float] = field(default_factory=list)
    end_holes: dict[str, str | None] = field(default_factory=dict)  # object -> hole at the end

    def add(self, t: float, tcp, finger: float) -> None:
        self.ticks[int(round(t / self.dt))] = len(self.tcp)
        self.tcp.append(tuple(float(v) for v in tcp))
        self.finger.append(float(finger))

    def row(self, t: float) -> int | None:
        return self.ticks.get(int(round(t / self.dt)))

    def tool_path(self, t_from: float, t_to: float) -> list[tuple[float, tuple[float, float, float]]]:
        out = []
        for tick, row in self.ticks.items():
            t = tick * self.dt
            if t_from <= t <= t_to:
                out.append((t, self.tcp[row]))
        return sorted(out)


def _unit_xy(rng: np.random.Generator) -> tuple[float, float, float]:
    a = float(rng.uniform(0.0, 2.0 * math.pi))
    return (math.cos(a), math.sin(a), 0.0)


def _unit_3d(rng: np.random.Generator) -> tuple[float, float, float]:
    v = rng.normal(size=3)
    v /= np.linalg.norm(v)
    return tuple(float(x) for x in v)


def draw_fault(rng: np.random.Generator, kinds: tuple[str, ...], trace: CleanTrace, dof: int, objects: list[str]) -> Fault:
    """One fault of one of ``kinds``, striking during the fault-free run's program (objects: before
    the last task starts, after which nothing the robot does can still find them out)."""
    kind = str(rng.choice(kinds))
    span = max(trace.end - trace.start, trace.dt)
    at = float(rng.uniform(0.0, span))
    target = objects[0] if objects else None
    if kind in ("object_moved", "object_missing", "hole_moved"):
        at = float(rng.uniform(0.0, max(trace.last_task_start - trace.start, trace.dt)))
    if kind == "object_moved":
        return Fault(kind=kind, at_s=at, magnitude=float(rng.uniform(5.0, 20.0)), unit="mm", direction=_unit_xy(rng), target=target)
    if kind == "object_missing":
        return Fault(kind=kind, at_s=at, target=target)
    if kind == "hole_moved":
        return Fault(kind=kind, at_s=at, magnitude=float(rng.uniform(2.0, 10.0)), unit="mm", direction=_unit_xy(rng))
    if kind == "peg_slip":
        return Fault(kind=kind, at_s=at, magnitude=float(rng.uniform(0.0, 0.05)), unit="friction", target=target)
    if kind == "obstacle":
        return Fault(kind=kind, at_s=at, magnitude=float(rng.uniform(10.0, 25.0)), unit="mm",
                     duration_s=float(rng.uniform(0.5, 4.0)))  # the obstacle stands where the tool will be this much later
    if kind == "heavier":  # the world is so from the start: a mass does not change while it is held
        return Fault(kind=kind, at_s=0.0, magnitude=float(rng.uniform(1.5, 5.0)), unit="x", target=target)
    if kind == "friction":
        factor = float(rng.uniform(0.1, 0.4)) if rng.random() < 0.5 else float(rng.uniform(2.5, 6.0))
        return Fault(kind=kind, at_s=0.0, magnitude=factor, unit="x")
    if kind == "jam":
        return Fault(kind=kind, at_s=at, magnitude=float(rng.uniform(3.0, 20.0)), unit="mm")
    if kind == "joint_drag":
        joint = int(rng.integers(0, dof))
        top = 150.0 if joint < 3 else 30.0
        torque = float(rng.uniform(0.1 * top, top)) * (1.0 if rng.random() < 0.5 else -1.0)
        return Fault(kind=kind, at_s=at, magnitude=torque, unit="N m", joint=joint)
    if kind == "sensor_bias":
        return Fault(kind=kind, at_s=at, magnitude=float(rng.uniform(2.0, 60.0)), unit="N", direction=_unit_3d(rng))
    if kind == "sensor_dropout":
        return Fault(kind=kind, at_s=at)
    if kind == "jitter_burst":
        return Fault(kind=kind, at_s=at, magnitude=float(rng.uniform(0.1, 3.0)), unit="s", duration_s=float(rng.uniform(2.0, 10.0)))
    # link_cut, link_stall, console_frozen
    return Fault(kind=kind, at_s=at, duration_s=float(rng.uniform(0.3, 5.0)))
