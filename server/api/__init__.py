"""HTTP and WebSocket API of the console: one router module per area of the page.

Every action of the web page is here too, so headless clients can run whole sessions. The
caller names itself with the ``X-Teleprog-Client`` header (no header: the page itself); when a
client holds the control lock (``POST /api/control/request`` returns its token), only calls that
present the token as ``X-Teleprog-Token`` change anything, and everybody else may only read
(STOP excepted). JSON bodies are read strictly (no NaN, no infinity, no key twice). Errors come
back as ``{"error": <type>, "detail": <one line saying what and where>}`` with 400 (malformed
input), 409 (not allowed now: a rule, the lock, the regime, a running preview) or 422 (not
possible: a joint limit, an unreachable pose; or a body of the wrong shape); never a 5xx by
design (``server.http_errors``).
"""

from __future__ import annotations

from fastapi import Depends, FastAPI

from server.api import arm, events, objects, preview, program, readiness, recordings, robot, session, task, task_goal, terrain, trials
from server.api.deps import strict_json_body
from server.http_errors import ERROR_RESPONSES


def include_routers(app: FastAPI) -> None:
    for module in (session, arm, objects, program, preview, robot, readiness, terrain, recordings, task, task_goal, trials):
        app.include_router(module.router, dependencies=[Depends(strict_json_body)], responses=ERROR_RESPONSES)
    app.include_router(events.router)
