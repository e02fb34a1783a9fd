"""The task net (thesis 3.5): rules, the generated net, the virtual and robot markings, the
recognised actions and the deviations (``server.console.task_monitor``)."""

from __future__ import annotations

from fastapi import APIRouter

from server.api.deps import SessionDep
from server.console.views import TaskView

router = APIRouter(prefix="/api", tags=["task"])


@router.get("/task", response_model=TaskView)
def task(session: SessionDep) -> TaskView:
    """The cell's task space and both markings; ``available`` is false for a cell with no task
    file (``assets/tasks/<cell>.toml``)."""
    return session.task.view()
