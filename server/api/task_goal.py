"""Task-level commands (issue 40). ``POST /api/task/goal`` plans a goal of the cell's task space
from the virtual marking (:func:`shared.tasknet.goals.plan_goal`); ``POST /api/task/action``
takes one action the virtual marking enables (``GET /api/task/actions`` lists them). Either
inserts the actions' statements (:mod:`shared.tasknet.action_program`, filled from where the
virtual cell's objects are now) before the selection as one edit, each line marked with the
action it serves, so the operator previews, edits and submits them as any others."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException
from pydantic import BaseModel, Field

from server.api.deps import ClientDep, SessionDep
from server.api_models import ApiIn
from server.console import ProgramView, Session

router = APIRouter(prefix="/api", tags=["task"])


class GoalIn(ApiIn):
    goal: list[Annotated[str, Field(max_length=200)]] = Field(min_length=1, max_length=64, description="atoms of the task space, e.g. PEGINHOLE(PEG,HOLE2)")
    keep: bool = Field(True, description="also keep the atoms of the marking the goal does not ask to change")


class ActionIn(ApiIn):
    action: str = Field(min_length=1, max_length=200, description="an action of the task space, e.g. grasp(PEG)")


class GoalActionOut(BaseModel):
    action: str
    statements: list[str]


class GoalOut(BaseModel):
    goal: list[str]
    actions: list[str]
    statements: list[GoalActionOut]
    states_visited: int
    final_marking: list[str]
    deferred: list[str] = Field(default_factory=list, description="actions of the plan not inserted: they would move "
                                "the arm after a task whose end only the robot knows; plan the goal again once it reports")
    warnings: list[str] = Field(default_factory=list, description="what the preview's check finds on the inserted lines "
                                "(collision, joint limits, a refused plan), each naming its line")
    program: ProgramView


class ActionOut(BaseModel):
    action: str
    statements: list[str]
    warnings: list[str] = Field(default_factory=list, description="as GoalOut's")
    program: ProgramView


class ActionsOut(BaseModel):
    marking: list[str] = Field(description="the virtual cell's marking")
    enabled: list[str] = Field(description="the actions it enables, in the task space's order")


def _space(session: Session) -> None:
    if session.task.space is None:
        raise HTTPException(404, "this cell has no task file (assets/tasks/<cell>.toml): there are no task actions")


@router.get("/task/actions", response_model=ActionsOut)
def task_actions(session: SessionDep) -> ActionsOut:
    """The actions the virtual marking enables (what the Task tab offers as buttons)."""
    _space(session)
    return ActionsOut(marking=list(session.task.view().virtual_marking), enabled=session.task_commands.offered())


@router.post("/task/goal", response_model=GoalOut)
def task_goal(body: GoalIn, session: SessionDep, client: ClientDep) -> GoalOut:
    """Plan the goal from the virtual marking and insert its statements before the selection (one
    undo step); a goal no reachable marking meets is a 400 naming the atom."""
    session.control.check(client)  # before any work
    _space(session)
    done = session.task_commands.goal(body.goal, keep=body.keep, client=client)
    plan = done.plan
    return GoalOut(goal=list(plan.goal), actions=plan.action_texts,
                   statements=[GoalActionOut(action=r.action, statements=list(r.statements)) for r in done.rows],
                   states_visited=plan.states_visited, final_marking=list(plan.final), deferred=list(done.deferred),
                   warnings=list(done.warnings), program=done.program)


@router.post("/task/action", response_model=ActionOut)
def task_action(body: ActionIn, session: SessionDep, client: ClientDep) -> ActionOut:
    """Insert the statements of one action the virtual marking enables (one undo step); an action
    it does not enable is a 409 naming what does not hold."""
    session.control.check(client)
    _space(session)
    done = session.task_commands.action(body.action, client=client)
    (row,) = done.rows
    return ActionOut(action=row.action, statements=list(row.statements), warnings=list(done.warnings),
                     program=done.program)
