"""Task-level commands (issue 40): ``POST /api/task/goal`` plans a goal of the cell's task space
from the virtual marking (:func:`shared.tasknet.goals.plan_goal`) and inserts the plan's
statements (:mod:`shared.tasknet.action_program`) before the selection, one ordinary statement
at a time, so the operator previews, edits and submits them as any others."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException
from pydantic import BaseModel, Field

from server.api.deps import ClientDep, SessionDep
from server.api_models import ApiIn
from server.console import ProgramView

router = APIRouter(prefix="/api", tags=["task"])


class GoalIn(ApiIn):
    goal: list[Annotated[str, Field(max_length=200)]] = Field(min_length=1, max_length=64, description="atoms of the task space, e.g. PEGINHOLE(PEG,HOLE2)")
    keep: bool = Field(True, description="also keep the atoms of the marking the goal does not ask to change")


class GoalActionOut(BaseModel):
    action: str
    statements: list[str]


class GoalOut(BaseModel):
    goal: list[str]
    actions: list[str]
    statements: list[GoalActionOut]
    states_visited: int
    final_marking: list[str]
    program: ProgramView


@router.post("/task/goal", response_model=GoalOut)
def task_goal(body: GoalIn, session: SessionDep, client: ClientDep) -> GoalOut:
    """Plan the goal from the virtual marking and insert its statements before the selection;
    a goal no reachable marking meets is a 400 naming the atom."""
    from shared.tasknet.action_program import action_statements
    from shared.tasknet.goals import plan_goal

    space = session.task.space
    if space is None:
        raise HTTPException(404, "this cell has no task file (assets/tasks/<cell>.toml): there are no goals")
    plan = plan_goal(space, frozenset(session.task.view().virtual_marking), body.goal, keep=body.keep)
    rows = action_statements(space, session.cell, plan.actions)
    view = session.program.view()
    for row in rows:
        for text in row.statements:
            view = session.program.insert(text, client=client)
    return GoalOut(goal=list(plan.goal), actions=plan.action_texts,
                   statements=[GoalActionOut(action=r.action, statements=list(r.statements)) for r in rows],
                   states_visited=plan.states_visited, final_marking=list(plan.final), program=view)
