"""The remote mirror (thesis §4.2.3): the robot as its telemetry and reports show it, next to
the virtual world the operator edits.

* The remote arm from the newest telemetry frame (published at ``remote_event_hz``, and at once
  when the robot's state changes) and the objects where the robot reports them, or, for a robot
  that reports none, where the grasps and releases it finished left them.
* Telemetry from a robot client comes through a gate (``gate_frame``, on the client's loop): each
  frame becomes the newest at once (one assignment, no lock), and only the frames that matter
  (another robot state, the publication due, or every frame while ``bus.telemetry`` has
  listeners) go on to ``take_frame`` on the client's listeners' thread. The frames between two
  publications cost the console their decoding and the gate, not a thread's wake each.
* The predicted path: the statements sent and not yet final, planned from the reported arm.
* Divergence: once the robot is at rest, the reported arm against where the program expects it
  and the reported objects against the virtual world's; beyond the thresholds, the operator is
  told and offered a re-sync, which takes the robot's state as the program's new start.
* The robot's report is the truth where contact decides a task's end: when the statement that
  last moved the arm is a task whose declared effect has a tolerance (``insert_peg``'s seat,
  ``extract_peg``'s lift; ``shared.motion.task_effects.contact_end``), it and everything after it
  finished done, and the robot stands within that tolerance of the predicted end, the console
  takes the robot's arm and objects as the program's start (as a re-sync would) and tells no
  divergence: a successful task ends where the robot says, not in a warning.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from server.console.context import ConsoleContext
from server.console.control import as_caller
from server.console.enums import SentStatus
from server.console.errors import ConflictError
from server.console.events import (
    ActionTaken,
    DivergenceChanged,
    PredictedPathChanged,
    ProgramChanged,
    RemoteArmChanged,
)
from server.console.views import (
    Caller,
    DivergenceView,
    PredictedPathView,
    RemoteArmView,
    SessionSnapshot,
    matrix_list,
)
from shared.cells.object_world import ObjectWorld
from shared.errors import TeleprogError
from shared.language.statements import Statement, TaskCall
from shared.motion.expectation import arm_offset, tool_path
from shared.motion.task_effects import TaskObjects, contact_end, within_tolerance
from shared.motion.plan_check import plan_or_refuse
from shared.robots.jog import world_T_tcp
from shared.spatial import pose_to_transform
from shared.wire.messages import RobotSnapshot, StatusReport
from shared.wire.telemetry import TelemetryFrame

if TYPE_CHECKING:
    from server.console.arm import VirtualArm
    from server.console.control import ControlLock
    from server.console.dispatch import Dispatch
    from server.console.ports import LinkRead
    from server.console.program_desk import ProgramDesk


class RemoteMirror:
    """Telemetry, reported objects, the predicted path, divergence and re-sync."""

    def __init__(self, ctx: ConsoleContext, control: ControlLock, desk: ProgramDesk, arm: VirtualArm, dispatch: Dispatch, link: LinkRead | None = None) -> None:
        self._ctx = ctx
        self._control, self._desk, self._arm, self._dispatch = control, desk, arm, dispatch
        self.link = link  # the link's status (``LinkStatus``), set by the session
        self._newest: tuple[TelemetryFrame, float] | None = None
        """The newest frame and when it arrived (``ctx.clock``): one tuple, swapped whole, so a
        reader on any thread gets a frame and its time together without the lock."""
        self._state = None  # the robot state of the last frame taken (``_take``)
        self._emitted_at = float("-inf")
        self.objects = ObjectWorld(ctx.cell)
        s = ctx.settings
        self._predicted = PredictedPathView()
        self._predicted_seq = 0  # bumped by every refresh of the predicted path
        self._divergence = DivergenceView(threshold_joint=s.divergence_joint, threshold_tool=s.divergence_tool)

    def _world_T_tcp(self, q: np.ndarray) -> np.ndarray:
        return world_T_tcp(self._ctx.robot, q, self._ctx.frames)

    @property
    def telemetry(self) -> TelemetryFrame | None:
        """The newest telemetry frame (None before the first)."""
        newest = self._newest
        return None if newest is None else newest[0]

    @property
    def telemetry_at(self) -> float | None:
        """When the newest frame arrived (``ctx.clock``; None before the first)."""
        newest = self._newest
        return None if newest is None else newest[1]

    def newest(self) -> tuple[TelemetryFrame, float] | None:
        """The newest frame with its arrival time, read together."""
        return self._newest

    # -- views ---------------------------------------------------------------------------------
    def view(self) -> RemoteArmView | None:
        """The remote arm from the newest telemetry frame, or ``None`` before the first one."""
        with self._ctx.lock:
            frame = self.telemetry
            if frame is None:
                return None
            q = np.array(frame.q, dtype=float)
            age = self.link.telemetry_age_s()
            world_T = self._world_T_tcp(q)
            return RemoteArmView(
                q=q.tolist(), world_T_tcp=matrix_list(world_T), age_s=age,
                state=frame.state.name.lower(), statement=frame.statement, gripper=frame.gripper,
                force_n=list(frame.wrench[:3]), held=self.objects.held,
                object_poses={k: matrix_list(v) for k, v in self.objects.poses(world_T).items()},
            )

    def predicted_view(self) -> PredictedPathView:
        with self._ctx.lock:
            return self._predicted

    def divergence_view(self) -> DivergenceView:
        with self._ctx.lock:
            return self._divergence

    # -- what the robot says -------------------------------------------------------------------
    def on_telemetry(self, frame: TelemetryFrame) -> None:
        """A telemetry frame from a source without a gate (a replay, a test; any thread): it
        becomes the newest, then is taken as ``take_frame`` takes one."""
        self._newest = (frame, self._ctx.clock())
        self._take(frame)

    def gate_frame(self, frame: TelemetryFrame) -> bool:
        """The robot client's gate (``RobotClient.on_telemetry``), on its loop as each frame
        arrives, so it never waits: ``frame`` becomes the newest, and the answer says whether
        ``take_frame`` must see it: a frame with another robot state than the one before (checked
        at once), one that arrives when the remote arm's publication is due, and every frame while
        anyone listens to ``bus.telemetry`` (a recorder writes each)."""
        now = self._ctx.clock()
        old = self._newest
        self._newest = (frame, now)
        return (old is None or old[0].state != frame.state or len(self._ctx.bus.telemetry) > 0
                or now - self._emitted_at >= 1.0 / self._ctx.settings.remote_event_hz)

    def take_frame(self, frame: TelemetryFrame) -> None:
        """A frame its gate let through (the robot client's listeners' thread)."""
        self._take(frame)

    def _take(self, frame: TelemetryFrame) -> None:
        """Hand ``frame`` to ``bus.telemetry``; publish the remote arm (the newest frame) at
        ``remote_event_hz``, and at once with a divergence check when the robot's state changes."""
        now = self._ctx.clock()
        self._ctx.bus.telemetry.call((frame,))
        with self._ctx.lock:
            changed_state = self._state is None or self._state != frame.state
            self._state = frame.state
            due = now - self._emitted_at >= 1.0 / self._ctx.settings.remote_event_hz
            if due or changed_state:
                self._emitted_at = now
        if due or changed_state:
            view = self.view()
            if view is not None:
                self._ctx.bus.emit([RemoteArmChanged(remote=view)])
        if changed_state:
            self.check_divergence()

    def take_reported_objects(self, snap: RobotSnapshot | None) -> bool:
        """Take the objects where the robot reports them (with a final status or an ack; under
        the lock). False when the robot does not report objects."""
        if snap is None or snap.objects is None:
            return False
        world_T_base = np.asarray(self._ctx.cell.world_T_base, dtype=float)
        poses = {o.name: world_T_base @ pose_to_transform(o.base_p, o.base_rpy) for o in snap.objects}
        self.objects.take_reported(poses, snap.held, self._world_T_tcp(np.array(snap.q, dtype=float)))
        return True

    def take_report(self, done: Statement | None, report: StatusReport) -> None:
        """A final report (under the lock): the objects it reports, or, when it reports none and
        ``done`` is a finished task, what that task did to them at the robot's pose."""
        if self.take_reported_objects(report.robot) or not isinstance(done, TaskCall):
            return
        snap = report.robot
        q = np.array(snap.q, dtype=float) if snap is not None else (
            np.array(self.telemetry.q, dtype=float) if self.telemetry is not None else None)
        if q is not None:
            self.objects.apply_task(done.name, done.args, self._world_T_tcp(q))

    # -- derived -------------------------------------------------------------------------------
    def refresh_predicted(self) -> None:
        """Plan the submitted-not-done statements from the remote arm (or the last known start).
        The planning (a second at thousands of statements) runs outside the session's lock; a
        refresh that a newer one overtook is dropped."""
        ctx = self._ctx
        with ctx.lock:
            pending = self._dispatch.pending()
            numbers = [s.number for s in pending if s.number is not None]
            self._predicted_seq += 1
            seq = self._predicted_seq
            if pending:
                frame = self.telemetry
                start = np.array(frame.q, dtype=float) if frame is not None else self._desk.start.q.copy()
                held = self.objects  # the robot's grip: an insertion's seat follows from it
                objects = TaskObjects.of_world(ctx.cell, held.placed, held.held, held.tcp_T_held)
                statements = [s.statement for s in pending]
        view = PredictedPathView()
        if pending:
            try:
                plan = plan_or_refuse(statements, ctx.robot, ctx.cell, start, objects)
            except TeleprogError:
                plan = None
            if plan is None or plan.duration <= 0:
                view = PredictedPathView(numbers=numbers)
            else:
                points = tool_path(plan, ctx.robot, ctx.frames, ctx.settings.predicted_points)
                view = PredictedPathView(points=points.tolist(), numbers=numbers, end_q=plan.q_final.tolist())
        with ctx.lock:
            if seq != self._predicted_seq:
                return  # a newer refresh started meanwhile: it publishes
            self._predicted = view
        ctx.bus.emit([PredictedPathChanged(predicted=view)])

    def check_divergence(self) -> None:
        """Compare the reported arm and objects with where they should be, once the robot is at rest."""
        s = self._ctx.settings
        with self._ctx.lock:
            frame = self.telemetry
            if frame is None:
                return
            state = frame.state.name.lower()
            at_rest = state in ("stopped", "fault") or (state == "idle" and not self._dispatch.pending())
            if not at_rest:
                if self._divergence.checked:
                    self._divergence = self._divergence.model_copy(update={"checked": False})
                return
            q_robot = np.array(frame.q, dtype=float)
            offset = arm_offset(self._ctx.robot, self._ctx.frames, q_robot, self._desk.start.q)
            unknown = self._desk.start.unknown
            arm_off = offset.beyond(s.divergence_joint, s.divergence_tool)
            if (unknown or arm_off) and self._take_contact_end(q_robot):
                unknown, arm_off, adopted = False, False, True
                offset = arm_offset(self._ctx.robot, self._ctx.frames, q_robot, self._desk.start.q)
            else:
                adopted = False
            obj, oerr = self.objects.divergence(self._arm.objects)
            objects_off = oerr > s.divergence_tool
            diverged = unknown or arm_off or objects_off
            msg = ""
            if diverged and (arm_off or unknown or not objects_off):
                msg = (f"the robot stopped {np.degrees(offset.joint):.2f} deg / {offset.tool * 1e3:.1f} mm away from where the program "
                       "expects it; re-sync to continue from there")
            elif diverged:
                where = "is held on one side only" if not np.isfinite(oerr) else f"lies {oerr * 1e3:.1f} mm from its modelled place"
                msg = f"the robot reports that {obj} {where}; re-sync to take the objects as the robot sees them"
            view = DivergenceView(diverged=diverged, joint_error=offset.joint if np.isfinite(offset.joint) else 0.0,
                                  tool_error=offset.tool if np.isfinite(offset.tool) else 0.0,
                                  object_error=oerr if np.isfinite(oerr) else 0.0, object=obj if objects_off else None,
                                  threshold_joint=s.divergence_joint, threshold_tool=s.divergence_tool, checked=True, message=msg)
            changed = view != self._divergence
            self._divergence = view
        if adopted:
            self._publish_adopted()
        if changed:
            self._ctx.bus.emit([DivergenceChanged(divergence=view)])

    def _take_contact_end(self, q_robot: np.ndarray) -> bool:
        """The robot at rest at ``q_robot`` after a task whose end contact decides (module
        docstring): within the task's declared tolerance of the predicted end, its arm and
        objects become the program's start (under the lock). False, changing nothing, otherwise."""
        finished = [(s.statement, s.status is SentStatus.DONE) for s in self._dispatch.sent]
        effect = contact_end(finished)
        start = self._desk.start
        # where the task leaves the tool by the model: the program's predicted start, or, while
        # the virtual gripper still holds what an insertion seated, the seat the object world's
        # contract put the tool at (a plan that did not know the grip stopped before the task)
        expected = self._arm.objects.world_T_tcp_inserted
        if expected is None:
            expected = self._world_T_tcp(start.q)
        if effect is None or not within_tolerance(effect, self._world_T_tcp(q_robot), expected):
            return False
        q = self._ctx.robot.as_q(q_robot)
        self._arm.objects.take(self.objects, self._arm.state.world_T_tcp)
        start.q, start.source, start.unknown = q.copy(), "telemetry", False
        self._desk.reset_generator()
        self._desk.withdraw_confirmation()
        return True

    def _publish_adopted(self) -> None:
        """After ``_take_contact_end``: the arm where the robot stands (when nothing of the
        operator's stands between), its objects redrawn, the program's new start."""
        if not self._arm.follow_start():
            with self._ctx.lock:
                events = self._arm.refresh()
            self._ctx.bus.emit(events)
        self._ctx.bus.emit([ProgramChanged(program=self._desk.view())])

    def resync(self, *, client: Caller | str | None = None, snapshot=None) -> SessionSnapshot:
        """Put the virtual arm (and the objects) where the robot's state says, and start the
        program from there (§4.2.3 error correction). ``snapshot()`` makes the answer."""
        ctx = self._ctx
        with ctx.lock:
            self._control.check(client)
            self._desk.check_not_previewing("re-sync")
            frame = self.telemetry
            if frame is None:
                raise ConflictError("no telemetry from the robot yet: nothing to re-sync from")
            q = ctx.robot.as_q(np.array(frame.q, dtype=float))
            # objects as the robot's state implies: the held one in the remote gripper, released
            # ones where the robot let them go
            self._arm.objects.take(self.objects, self._arm.state.world_T_tcp)
            events = self._arm.put(q)
            start = self._desk.start
            start.q, start.source, start.unknown = q.copy(), "telemetry", False
            self._desk.reset_generator()
            self._desk.withdraw_confirmation()
            self._divergence = self._divergence.model_copy(update={"diverged": False, "message": "re-synced from telemetry"})
        self._arm.publish_state()
        ctx.bus.emit([ActionTaken(action="resync", client=as_caller(client).name), *events,
                      ProgramChanged(program=self._desk.view()), DivergenceChanged(divergence=self.divergence_view())])
        return snapshot()
