"""Shared dependencies of the API routers: the session, the caller, and strict JSON bodies."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Header, HTTPException, Request

from server.console import Caller, Session
from shared.errors import InputError
from shared.wire.strict_json import StrictJSONError, loads_strict

CLIENT_HEADER = "X-Teleprog-Client"
TOKEN_HEADER = "X-Teleprog-Token"
MAX_HEADER_CHARS = 200
"""The longest caller name or token taken (a longer one is refused, 422)."""


# The two dependencies below are ``async``: they only read the request, and FastAPI runs a
# plain ``def`` dependency in its thread pool (a thread hand-off each, on every request: about a
# fifth of the console's CPU per jog before).
async def get_session(request: Request) -> Session:
    console = getattr(request.app.state, "console", None)
    if console is None:
        raise HTTPException(503, "the console session is not running yet")
    return console.session


async def get_client(
    x_teleprog_client: Annotated[str | None, Header(max_length=MAX_HEADER_CHARS, description="the caller's name (a label others see)")] = None,
    x_teleprog_token: Annotated[str | None, Header(max_length=MAX_HEADER_CHARS, description="the control token POST /api/control/request returned")] = None,
) -> Caller:
    """The caller: the name from ``X-Teleprog-Client`` (none: the page) and the control token from
    ``X-Teleprog-Token`` (none: it holds no control)."""
    return Caller(name=x_teleprog_client or None, token=x_teleprog_token or None)


async def strict_json_body(request: Request) -> None:
    """Refuse a JSON body that Python's ``json`` would take but JSON does not: NaN, Infinity,
    numbers too large to be finite, a key given twice, deep nesting, bytes that are not UTF-8
    (400, naming what). Runs before the body is validated, for every route that takes a JSON body."""
    route = request.scope.get("route")
    if getattr(route, "body_field", None) is None:
        return
    content_type = request.headers.get("content-type", "")
    media = content_type.split(";", 1)[0].strip().lower()
    if not (media == "application/json" or (media.startswith("application/") and media.endswith("+json"))):
        return
    raw = await request.body()
    if not raw:
        return
    try:
        loads_strict(raw)
    except StrictJSONError as exc:
        raise InputError(f"{request.method} {request.url.path}: the body is not strict JSON: {exc}") from None


SessionDep = Annotated[Session, Depends(get_session)]
ClientDep = Annotated[Caller, Depends(get_client)]
