"""The task net (thesis 3.5): rules, the generated net, the virtual and robot markings, the
recognised actions and the deviations (``server.console.task_monitor``)."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, HTTPException, Response

from server.api.deps import SessionDep
from server.console.views import TaskView

router = APIRouter(prefix="/api", tags=["task"])


@router.get("/task", response_model=TaskView)
def task(session: SessionDep) -> TaskView:
    """The cell's task space and both markings; ``available`` is false for a cell with no task
    file (``assets/tasks/<cell>.toml``)."""
    return session.task.view()


@router.get("/task/net", responses={200: {"content": {"application/xml": {}, "application/json": {}, "image/png": {}}}})
def task_net(session: SessionDep, format: Literal["pnml", "json", "png"] = "pnml") -> Response:
    """The task net generated from the actions recognised on the virtual cell (3.5.5), as PNML
    (ISO/IEC 15909-2, opens in Petri-net tools), as this project's JSON form of a net, or as a
    PNG picture with its initial marking."""
    from shared.tasknet.jsonform import net_to_json
    from shared.tasknet.pnml import net_to_pnml
    from shared.tasknet.raster import net_to_png

    net = session.task.generated_net()
    if net is None:
        raise HTTPException(404, "this cell has no task file (assets/tasks/<cell>.toml): there is no task net")
    if format == "json":
        return Response(net_to_json(net), media_type="application/json",
                        headers={"Content-Disposition": 'attachment; filename="task_net.json"'})
    if format == "png":
        return Response(net_to_png(net), media_type="image/png",
                        headers={"Content-Disposition": 'attachment; filename="task_net.png"'})
    return Response(net_to_pnml(net), media_type="application/xml",
                    headers={"Content-Disposition": 'attachment; filename="task_net.pnml"'})
