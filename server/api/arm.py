"""Driving the virtual arm (§4.3.4): joint and tool jogs, letting go, collision and zone; and
backing the remote arm out of a contact fault in one call."""

from __future__ import annotations

import numpy as np
from starlette.concurrency import run_in_threadpool
from fastapi import APIRouter

from server.api.deps import ClientDep, SessionDep
from server.api_models import JogJointIn, JogToolIn, SetJointsIn, StateOut
from server.console import ArmView, Caller, CollisionView, ProgramView, SentListView, Session

router = APIRouter(prefix="/api", tags=["arm"])


@router.get("/state", response_model=StateOut)
def get_state(session: SessionDep) -> StateOut:
    return StateOut.from_state(session.arm.state)


@router.get("/arm", response_model=ArmView)
def get_arm(session: SessionDep) -> ArmView:
    return session.arm.view()


@router.put("/robot/joints", response_model=StateOut)
def set_joints(body: SetJointsIn, session: SessionDep, client: ClientDep) -> StateOut:
    """Put the virtual arm at a joint vector (degrees); 422 names a joint outside its range."""
    return StateOut.from_state(session.arm.set_q(np.radians(body.deg), client=client))


def jog_joint_state(session: Session, body: JogJointIn, client: Caller) -> StateOut:
    """What ``POST /api/jog/joint`` does (also answered by ``server.api.jog_lane``)."""
    return StateOut.from_state(session.arm.jog_joint(body.joint, float(np.radians(body.delta_deg)), client=client))


def jog_tool_state(session: Session, body: JogToolIn, client: Caller) -> StateOut:
    """What ``POST /api/jog/tool`` does (also answered by ``server.api.jog_lane``)."""
    scale = 1e-3 if body.motion == "translate" else np.pi / 180.0
    return StateOut.from_state(
        session.arm.jog_tool(
            frame=body.frame, constraint=body.constraint, motion=body.motion,
            displacement=np.array(body.displacement) * scale, client=client,
        )
    )


# The jogs run on the event loop (``async def`` without awaiting): they are short, CPU-bound and
# take the arm's lock themselves; a plain ``def`` route costs a thread-pool hand-off each way,
# about a fifth of the console's CPU per jog at jogging rates. Their ordinary requests are
# answered ahead of FastAPI by ``server.api.jog_lane`` with the same functions; these routes
# document them and give every other answer (a malformed body, a header too long).
@router.post("/jog/joint", response_model=StateOut)
async def jog_joint(body: JogJointIn, session: SessionDep, client: ClientDep) -> StateOut:
    if session.busy():  # a long computation holds the session: wait on a worker, not on the loop
        return await run_in_threadpool(jog_joint_state, session, body, client)
    return jog_joint_state(session, body, client)


@router.post("/jog/tool", response_model=StateOut)
async def jog_tool(body: JogToolIn, session: SessionDep, client: ClientDep) -> StateOut:
    if session.busy():
        return await run_in_threadpool(jog_tool_state, session, body, client)
    return jog_tool_state(session, body, client)


@router.post("/jog/release", response_model=ProgramView)
def release(session: SessionDep, client: ClientDep) -> ProgramView:
    """The operator let go: the open generated segment becomes a statement."""
    return session.arm.release(client=client)


@router.get("/collision", response_model=CollisionView)
def collision(session: SessionDep) -> CollisionView:
    """Collision report and control zone of the virtual arm now."""
    return session.arm.collision_view()


@router.post("/robot/back_away", response_model=SentListView)
def back_away(session: SessionDep, client: ClientDep) -> SentListView:
    """After a contact fault: abort what the robot has not finished, then move the tool 30 mm
    straight back along the way it was pressing (up when that is not known) at 10 mm/s. 409 when
    the robot is not in fault or neither motion can be planned from where it stopped."""
    return session.recovery.back_away(client=client)
