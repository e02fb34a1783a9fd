"""The jog lane: ``POST /api/jog/joint`` and ``POST /api/jog/tool`` answered ahead of FastAPI.

A client dragging the arm sends a jog every few milliseconds. Through FastAPI each one paid for
route matching over every route of the API, dependency solving (the caller's headers, the
strict-JSON check, the body), response validation and the route wrappers: about a third of the
console's CPU per jog (py-spy, issue 21), more than the jog itself. This ASGI middleware answers
the two routes' ordinary requests itself, with the routes' own functions
(``server.api.arm.jog_joint_state`` / ``jog_tool_state``), body models and refusals
(``server.http_errors.teleprog_refusal``). Every request it would not answer exactly as the
route does - a body that is not strict JSON or not of the model's shape, a media type other than
``application/json``, a header longer than the route takes, the console not running yet - goes
on to the app with the body it read, untouched, and gets the documented answer from there. The
routes stay in the OpenAPI document; a failure nobody expected propagates to the app's own
500 handler as from a route.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pydantic import BaseModel, ValidationError
from starlette.concurrency import run_in_threadpool
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from server.api.arm import jog_joint_state, jog_tool_state
from server.api.deps import CLIENT_HEADER, MAX_HEADER_CHARS, TOKEN_HEADER
from server.api_models import JogJointIn, JogToolIn, StateOut
from server.console import Caller, Session
from server.http_errors import teleprog_refusal
from shared.errors import TeleprogError
from shared.wire.strict_json import StrictJSONError, loads_strict

Handler = Callable[[Session, Any, Caller], StateOut]

ROUTES: dict[str, tuple[type[BaseModel], Handler]] = {
    "/api/jog/joint": (JogJointIn, jog_joint_state),
    "/api/jog/tool": (JogToolIn, jog_tool_state),
}
"""Path -> (body model, what the route does)."""

_JSON_HEADERS = [(b"content-type", b"application/json")]
_CLIENT = CLIENT_HEADER.lower().encode("latin-1")  # ASGI gives header names in lower case
_TOKEN = TOKEN_HEADER.lower().encode("latin-1")


class JogLane:
    """ASGI middleware in front of the console's routes (installed by ``server.app``)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        route = ROUTES.get(scope["path"]) if scope["type"] == "http" and scope["method"] == "POST" else None
        if route is None:
            await self.app(scope, receive, send)
            return
        body = bytearray()
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                return  # the client went away before its jog arrived whole: nothing was done
            body += message.get("body", b"")
            if not message.get("more_body", False):
                break
        if not await self._answer(scope, receive, send, bytes(body), route):
            await self.app(scope, _replay(bytes(body), receive), send)

    async def _answer(self, scope: Scope, receive: Receive, send: Send, body: bytes,
                      route: tuple[type[BaseModel], Handler]) -> bool:
        """Answer the jog; False (nothing done, nothing sent) when the route should answer it."""
        state = getattr(scope["app"].state, "console", None)
        if state is None:
            return False
        content_type = name = token = None
        for key, value in scope["headers"]:
            if key == b"content-type" and content_type is None:
                content_type = value
            elif key == _CLIENT and name is None:
                name = value.decode("latin-1")
            elif key == _TOKEN and token is None:
                token = value.decode("latin-1")
        if content_type is None or content_type.split(b";", 1)[0].strip().lower() != b"application/json":
            return False
        if (name is not None and len(name) > MAX_HEADER_CHARS) or (token is not None and len(token) > MAX_HEADER_CHARS):
            return False
        model, handler = route
        try:
            parsed = model.model_validate(loads_strict(body))
        except (StrictJSONError, ValidationError):
            return False
        caller = Caller(name=name or None, token=token or None)
        try:
            if state.session.busy():  # a long computation holds the session: wait on a worker, not on this loop
                out = await run_in_threadpool(handler, state.session, parsed, caller)
            else:
                out = handler(state.session, parsed, caller)
        except TeleprogError as exc:
            await teleprog_refusal(exc)(scope, receive, send)
            return True
        payload = out.model_dump_json().encode()
        await send({"type": "http.response.start", "status": 200,
                    "headers": [*_JSON_HEADERS, (b"content-length", str(len(payload)).encode())]})
        await send({"type": "http.response.body", "body": payload})
        return True


def _replay(body: bytes, receive: Receive) -> Receive:
    """A ``receive`` that gives the body already read, then defers to the connection's."""
    sent = False

    async def replay() -> Message:
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": body, "more_body": False}
        return await receive()

    return replay
