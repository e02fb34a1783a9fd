"""HTTP and WebSocket API of the console: one router module per area of the page.

Every action of the web page is here too, so headless clients can run whole sessions. The
caller names itself with the ``X-Teleprog-Client`` header (no header: the page itself); when a
client holds the control lock, everybody else may only read. Errors come back as
``{"error": <type>, "detail": <one line saying what and where>}`` with 400 (malformed input),
409 (not allowed now: a rule, the lock, the regime, a running preview) or 422 (not possible: a
joint limit, an unreachable pose).
"""

from __future__ import annotations

from fastapi import FastAPI

from server.api import arm, events, objects, program, preview, robot, session, terrain


def include_routers(app: FastAPI) -> None:
    for module in (session, arm, objects, program, preview, robot, terrain, events):
        app.include_router(module.router)
