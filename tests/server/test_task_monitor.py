"""Task monitoring on the session (thesis §3.5): each sent statement is expected to make the actions
the console's play of its range recognised, and the robot's reports are matched against them in
order. A repeated action (grasp, release, grasp) is matched to its own occurrence, never to an
earlier one the robot already made.

The robot here is the monitor's input only: the session's events, with the robot's cell as the
same play on the object world shows it after each statement."""

from __future__ import annotations

import numpy as np
import pytest

from server.console import Session
from server.console.enums import SentStatus
from server.console.events import RangeSubmitted, RemoteArmChanged, SentChanged
from server.console.views import RemoteArmView, SentListView, SentView
from shared.cells.object_world import ObjectWorld
from shared.language.parser import parse_program
from shared.motion import plan_program
from shared.motion.frames import CellFrames
from shared.tasknet.playback import play

GRASP_RELEASE_TWICE = ["SPEED 50 %", "MOVES TO (0, -80, 160) mm (180, 0, 0) deg IN WORK", "DRAW TO (0, -80, 75) mm IN WORK",
                       "TASK grasp(peg)", "TASK release(peg)", "TASK grasp(peg)", "TASK release(peg)"]
OPEN_M = 0.04  # a gripper opening well above the monitor's closed threshold


def robot_views(session: Session, texts: list[str]) -> dict[int, RemoteArmView]:
    """Per statement number (1-based), the robot's cell when that statement has run as planned:
    the same play the monitor's expectations come from."""
    cell = session.cell
    statements = parse_program("\n".join(texts)).statements
    plan = plan_program(statements, cell.robot, cell, cell.q_home)
    frames = CellFrames.from_cell(cell)
    world = ObjectWorld(cell)

    def view(q: np.ndarray, number: int) -> RemoteArmView:
        tcp = frames.world_T_tcp(cell.robot, q)
        return RemoteArmView(
            q=list(map(float, q)), world_T_tcp=np.asarray(tcp).tolist(), age_s=0.0, state="running", statement=number,
            gripper=0.0 if world.held is not None else OPEN_M, force_n=[0.0, 0.0, 0.0], held=world.held,
            object_poses={k: np.asarray(v).tolist() for k, v in world.poses(tcp).items()})

    views = {0: view(np.asarray(cell.q_home), 0)}
    for q, _t, number in play(plan, cell, world):
        views[number] = view(q, number)
    for number in range(1, len(statements) + 1):  # a statement that takes no time (SPEED) leaves the cell as it was
        views.setdefault(number, views[number - 1].model_copy(update={"statement": number}))
    return views


def sent(texts: list[str], statuses: list[SentStatus]) -> SentChanged:
    statements = parse_program("\n".join(texts)).statements
    items = [SentView(id=i + 1, number=i + 1, text=texts[i], statement=statements[i], status=status, submitted_at=0.0)
             for i, status in enumerate(statuses)]
    return SentChanged(sent=SentListView(items=items, pending=len(texts) - len(statuses)))


def test_a_repeated_action_is_matched_to_its_own_occurrence_never_an_earlier_one(session: Session) -> None:
    """grasp, release, grasp, release: the robot grasps, releases and grasps again, then its
    second release fails. Each expected action is matched to the robot's next action, never to an
    earlier occurrence of the same one: the third statement's grasp is the robot's third action,
    and the last release, which the robot never made, is a deviation naming statement 7."""
    monitor = session.task
    if not monitor.available:
        pytest.fail(f"the default cell has no task monitoring: {monitor.error}")
    texts = GRASP_RELEASE_TWICE
    done = SentStatus.DONE
    views = robot_views(session, texts)
    monitor.on_event(RangeSubmitted(ids=list(range(1, 8)), texts=texts, start_q=list(map(float, session.cell.q_home))))
    assert monitor.settled()
    for k in range(1, 7):  # statements 1..6 run as planned: grasp, release, grasp
        monitor.on_event(RemoteArmChanged(remote=views[k]))
        monitor.on_event(sent(texts[:k], [done] * k))
        monitor.on_event(RemoteArmChanged(remote=views[k]))
    task = monitor.view()
    assert [(a.action, a.statement) for a in task.robot_actions] == [("grasp(PEG)", 4), ("release(PEG)", 5), ("grasp(PEG)", 6)]
    assert task.deviations == []
    # the second release fails: the robot's cell stays as the second grasp left it
    monitor.on_event(sent(texts, [done] * 6 + [SentStatus.FAILED]))
    monitor.on_event(RemoteArmChanged(remote=views[6].model_copy(update={"statement": 7})))
    task = monitor.view()
    assert len(task.robot_actions) == 3
    missing = [d for d in task.deviations if d.kind == "missing"]
    assert [(d.expected, d.statement, d.status) for d in missing] == [("release(PEG)", 7, "failed")]
    assert missing[0].observed["HOLDING(PEG)"] is True
