"""The virtual arm the operator drives (thesis §4.3.2-4.3.3): joint and tool jogs under the jog
rules (``shared.robots.jog``), the objects of the virtual world and what the gripper holds
(``shared.cells.object_world``), and after every change the collision report and control zone
of the arm (``shared.collision.cell_check``).

Every change is atomic under the session lock (two callers on different threads never lose each
other's step), is offered to the program desk as a sample of the operator's stroke (automatic
generation), and is published: the fast path for the 3D scene, then typed events.

Where the arm stands between strokes (:meth:`VirtualArm.follow_start`): the virtual arm shows
where the program starts plus what the operator has added. So when statements leave for the
robot and after every report that finishes one, the arm is put at the program's start state (the
predicted end of what was sent, or the robot's state after a re-sync) and the held object rides
along, provided the program is empty, no preview runs and no stroke is open (between the first
move of a drag or slider and its release). When the operator has been driving ahead, the program
has statements and the arm stands at their end: it is left there. A pose driven without
generation and not written into the program is not the program's: the next report puts the arm
back at the start.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from server.console.context import ConsoleContext
from server.console.errors import ConflictError
from server.console.events import (
    ArmChanged,
    CollisionChanged,
    SessionEvent,
    TerrainChanged,
)
from server.console.views import (
    ArmView,
    Caller,
    CollisionView,
    VirtualState,
    matrix_list,
)
from shared.cells.object_world import ObjectWorld
from shared.collision.cell_check import CellCollision, CellReport
from shared.errors import InputError
from shared.program.generator import JogMode
from shared.motion.task_effects import TaskObjects
from shared.robots.handles import ToolHandle, fine_gain, handle_turn, joint_handle, scaled_step, tool_goal, tool_handle
from shared.robots.jog import JogResult, jog_joint, jog_tool, jog_tool_to, world_T_tcp
from shared.spatial import invert, matrix_to_rpy

if TYPE_CHECKING:
    from server.console.control import ControlLock
    from server.console.modes import Modes
    from server.console.ports import GroundContacts, PreviewRun, StrokeTaker

Step = Callable[[np.ndarray], "JogResult | np.ndarray"]


class VirtualArm:
    """The operator's arm and the virtual world's objects."""

    def __init__(self, ctx: ConsoleContext, collision: CellCollision, control: ControlLock, modes: Modes, desk: StrokeTaker, preview: PreviewRun, terrain: GroundContacts) -> None:
        self._ctx = ctx
        self.robot = ctx.robot
        self.collision = collision
        self._control, self._modes, self._desk, self._preview, self._terrain = control, modes, desk, preview, terrain
        q0 = ctx.cell.q_home.copy()
        self._state = VirtualState(q0, world_T_tcp(self.robot, q0, ctx.frames))
        self.objects = ObjectWorld(ctx.cell)
        self._data = collision.new_data()
        self._report: CellReport | None = None
        self._view: CollisionView | None = None
        self._stroke_open = False  # between the first move of a stroke and its release
        self._drag_handle: np.ndarray | None = None  # the tool handle's last pose in this drag (world)
        self._drag_goal: np.ndarray | None = None  # where the handle asks the tool's grip to be, fine near objects
        with ctx.lock:
            self.refresh()

    # -- reading -----------------------------------------------------------------------------
    @property
    def state(self) -> VirtualState:
        with self._ctx.lock:
            return self._state

    def subscribe(self, listener: Callable[[VirtualState], None]) -> Callable[[], None]:
        """Call ``listener(VirtualState)`` after every change of the virtual arm (fast path)."""
        return self._ctx.bus.arm.add(listener)

    def view(self) -> ArmView:
        with self._ctx.lock:
            s = self._state
            jog = s.last_jog
            return ArmView(
                q=s.q.tolist(), q_deg=np.degrees(s.q).tolist(), world_T_tcp=matrix_list(s.world_T_tcp),
                tool_xyz_mm=(s.world_T_tcp[:3, 3] * 1e3).tolist(),
                tool_rpy_deg=np.degrees(matrix_to_rpy(s.world_T_tcp[:3, :3])).tolist(),
                blocked=jog.blocked if jog else None, message=jog.message if jog else "", version=s.version,
                held=self.objects.held, object_poses={k: matrix_list(v) for k, v in self.object_poses().items()},
            )

    def collision_view(self) -> CollisionView:
        with self._ctx.lock:
            assert self._view is not None
            return self._view

    def object_poses(self) -> dict[str, np.ndarray]:
        """The moved objects' poses, the held one in the virtual gripper (under the lock)."""
        return self.objects.poses(self._state.world_T_tcp)

    def object_poses_now(self) -> dict[str, np.ndarray]:
        """:meth:`object_poses`, taking the lock (from any thread)."""
        with self._ctx.lock:
            return self.object_poses()

    # -- driving -----------------------------------------------------------------------------
    def set_q(self, q: np.ndarray, *, client: Caller | str | None = None) -> VirtualState:
        """Put the virtual robot at ``q`` (rad; checked against the joint ranges)."""
        q = self.robot.as_q(q)
        self.robot.check_limits(q)
        return self._apply(lambda _: q, JogMode.JOINT, client)

    def jog_joint(self, joint: int, delta: float, *, client: Caller | str | None = None) -> VirtualState:
        """Turn joint ``joint`` (1-based) by ``delta`` rad about its own z axis, stopping at its limit."""
        return self._apply(lambda q: jog_joint(self.robot, q, joint, delta), JogMode.JOINT, client)

    def set_joint(self, joint: int, value: float, *, client: Caller | str | None = None) -> VirtualState:
        """Turn joint ``joint`` (1-based) to ``value`` rad, stopping at its limit."""
        if not 1 <= joint <= self.robot.dof:
            raise InputError(f"joint {joint} does not exist: the robot has joints 1..{self.robot.dof}")
        return self._apply(lambda q: jog_joint(self.robot, q, joint, value - q[joint - 1]), JogMode.JOINT, client)

    def jog_tool(self, *, frame: str, constraint: str, motion: str, displacement: np.ndarray,
                 client: Caller | str | None = None) -> VirtualState:
        """Move the tool point by ``displacement`` (m, or a rotation vector in rad) in ``frame``
        along the axis or plane ``constraint``."""
        frames = self._ctx.frames
        return self._apply(
            lambda q: jog_tool(self.robot, q, frames=frames, frame=frame, constraint=constraint, motion=motion, displacement=displacement),
            JogMode.TOOL, client, frame,
        )

    def jog_tool_to(self, world_T_goal: np.ndarray, *, frame: str, constraint: str, motion: str,
                    client: Caller | str | None = None) -> VirtualState:
        """Move the tool point toward ``world_T_goal`` (the gizmo's pose) under the constraint."""
        frames = self._ctx.frames
        return self._apply(
            lambda q: jog_tool_to(self.robot, q, world_T_goal, frames=frames, frame=frame, constraint=constraint, motion=motion),
            JogMode.TOOL, client, frame,
        )

    # -- drag handles (shared.robots.handles) ------------------------------------------------------
    def tool_handle(self, frame: str) -> ToolHandle:
        """The tool's drag handle for jogs in ``frame``: at the tool point with the frame's axes,
        and the grip to pass back with :meth:`drag_tool_handle`."""
        with self._ctx.lock:
            return tool_handle(frame, self._ctx.frames, self._state.world_T_tcp)

    def drag_tool_handle(self, world_T_handle: np.ndarray, handle_T_tcp: np.ndarray, *, frame: str, constraint: str,
                         motion: str, client: Caller | str | None = None) -> VirtualState:
        """The tool's handle was dragged to ``world_T_handle``: follow it with the grip it was
        placed with, under the constraint, finer near objects: each step of the handle moves the
        goal by ``fine_gain`` of it at the tool's clearance then (``shared.robots.handles``), so
        the tool lags the handle near contact; the stroke's release puts the handle back on it."""
        with self._ctx.lock:
            was = self._drag_handle
            if was is None:  # the stroke's first step starts where the handle stood on the tool
                was = self._state.world_T_tcp @ invert(np.asarray(handle_T_tcp, dtype=float))
                self._drag_goal = was
            clearance = self._view.min_distance if self._view is not None else None
            self._drag_goal = scaled_step(self._drag_goal, was, world_T_handle, fine_gain(clearance))
            self._drag_handle = np.asarray(world_T_handle, dtype=float).copy()
            goal = tool_goal(self._drag_goal, handle_T_tcp)
        return self.jog_tool_to(goal, frame=frame, constraint=constraint, motion=motion, client=client)

    def task_objects(self) -> TaskObjects:
        """The movable objects and the grip as the virtual cell has them now, for the planner:
        a task's end (an insertion's seat) follows from what the gripper holds and how."""
        with self._ctx.lock:
            o = self.objects
            return TaskObjects.of_world(self._ctx.cell, o.placed, o.held, o.tcp_T_held)

    def joint_handle(self, joint: int) -> np.ndarray:
        """Joint ``joint``'s drag handle (world): at the joint, z along its axis."""
        with self._ctx.lock:
            return joint_handle(self.robot, self._state.q, joint, self._ctx.cell.world_T_base)

    def turn_joint_to_handle(self, joint: int, world_T_handle: np.ndarray, *, client: Caller | str | None = None) -> VirtualState:
        """Joint ``joint``'s ring was turned to ``world_T_handle``: turn the joint by the ring's
        turn about the joint's axis from where the joint stands, stopping at its limit."""
        world_T_base = self._ctx.cell.world_T_base

        def step(q: np.ndarray) -> JogResult:
            delta = handle_turn(joint_handle(self.robot, q, joint, world_T_base), world_T_handle)
            return jog_joint(self.robot, q, joint, delta)

        return self._apply(step, JogMode.JOINT, client)

    def release(self, *, client: Caller | str | None = None):
        """The operator let go of the gizmo or slider: the program desk closes the open
        generated segment (the stroke is closed first: what it streams may put the arm at the
        start, see :meth:`follow_start`). Returns the program view."""
        with self._ctx.lock:
            self._control.check(client)
            self._stroke_open = False
            self._drag_handle = self._drag_goal = None  # the next drag starts from the tool
        return self._desk.end_stroke(client=client)

    def _apply(self, step: Step, mode: JogMode, client: Caller | str | None, frame: str | None = None) -> VirtualState:
        """Compute the next joint vector from the current one and publish it, atomically
        (``frame``: a tool jog's frame, which generated statements are written in)."""
        with self._ctx.lock:
            self._control.check(client)
            busy = self._preview.running_range()
            if busy is not None:
                raise ConflictError(f"cannot drive the arm while statements {busy[0] + 1}..{busy[1]} are being previewed; end the preview first")
            before = self._state
            self._stroke_open = True
            out = step(before.q)
            result = out if isinstance(out, JogResult) else None
            q = out.q if isinstance(out, JogResult) else out
            self._state = VirtualState(q.copy(), world_T_tcp(self.robot, q, self._ctx.frames), result, before.version + 1)
            generated = self._desk.sample_stroke(before, self._state, mode, frame)
            state = self._state
            events = self.refresh()
        self._ctx.bus.arm.call([state])
        self._ctx.bus.emit(events)
        self._desk.take_generated(generated)
        return state

    def put(self, q: np.ndarray) -> list[SessionEvent]:
        """Stand the arm at ``q`` without a stroke (a re-sync; under the lock); the events."""
        self._state = VirtualState(q.copy(), world_T_tcp(self.robot, q, self._ctx.frames), None, self._state.version + 1)
        return self.refresh()

    def follow_start(self) -> bool:
        """Put the arm at the program's start state when nothing of the operator's stands
        between (see the module docstring): the program is empty, no preview runs, no stroke
        is open. Publishes the change; True when the arm moved or its objects were redrawn."""
        with self._ctx.lock:
            if self._stroke_open or self._preview.running_range() is not None or self._desk.editor.state.statements:
                return False
            q = self._desk.start.q
            if np.array_equal(q, self._state.q):
                return False
            events = self.put(q)
        self.publish_state()
        self._ctx.bus.emit(events)
        return True

    def publish_state(self) -> None:
        """The fast path after :meth:`put` (outside the lock)."""
        self._ctx.bus.arm.call([self.state])

    # -- after every change --------------------------------------------------------------------
    def refresh(self) -> list[SessionEvent]:
        """Collision report, zone and regime of the arm as it stands (under the lock); the
        events to publish."""
        report = self.collision.check(self._state.q, object_poses=self.object_poses() or None, held=self.objects.held, data=self._data)
        self._report = report
        jog = self._state.last_jog
        self._view = CollisionView(
            colliding=report.colliding, pairs=list(report.pairs),
            triangles={b: t.tolist() for b, t in report.triangles.items()},
            min_distance=report.min_distance, nearest=report.nearest,
            zone=report.zone, zone_object=report.zone_object, zone_distance=report.zone_distance,
            joint_limit=jog.message if jog is not None and jog.blocked == "joint_limit" else None,
        )
        events: list[SessionEvent] = [ArmChanged(arm=self.view()), CollisionChanged(collision=self._view)]
        if report.ground is not None:
            events.append(TerrainChanged(terrain=self._terrain.take_contact(report.ground)))
        events += self._modes.set_zone(report.zone)
        return events
