"""How a refused request reads over HTTP, for every app of the console (one definition).

``{"error": <type>, "detail": <one line saying what and where>}`` with 400 for malformed input
(a body that is not strict JSON included), 409 for an action the state does not allow now (a
rule of the editor, the control lock, a running preview; ``rule`` names an editor rule) and 422
for what is impossible (a joint limit, an unreachable pose) or a body of the wrong shape; a 422
of the request's validation also lists ``errors`` (where, what, and the input made finite, so
that a NaN in the input can be shown). An exception nobody expected is logged with its traceback
and answers 500 with one line: a bug to fix, never an answer by design.
"""

from __future__ import annotations

import logging
from http import HTTPStatus
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from pydantic import BaseModel, Field
from starlette.exceptions import HTTPException as StarletteHTTPException

from server.console import ConflictError, RefusedByRule
from shared.errors import InputError, TeleprogError
from shared.wire.strict_json import dumps_finite

log = logging.getLogger(__name__)

MAX_ERRORS_LISTED = 20


class FieldErrorOut(BaseModel):
    loc: list[str | int] = Field(description="where: 'body', then the path into it")
    msg: str
    type: str
    input: Any = Field(None, description="the value refused; non-finite numbers as strings")


class ErrorOut(BaseModel):
    """Every refusal of the console's API."""

    error: str = Field(description="what kind of refusal (an exception type or an HTTP reason)")
    detail: str = Field(description="one line saying what and where")
    rule: str | None = Field(None, description="the §4.3.6 editor rule that refused it")
    errors: list[FieldErrorOut] | None = Field(None, description="each field a body's validation refused")


def _refusal(description: str) -> dict[str, Any]:
    # JSON whatever the route's own media type (a file download refuses in JSON too)
    return {"model": ErrorOut, "description": description,
            "content": {"application/json": {"schema": {"$ref": "#/components/schemas/ErrorOut"}}}}


ERROR_RESPONSES: dict[int | str, dict[str, Any]] = {
    400: _refusal("malformed input"),
    404: _refusal("nothing there (yet)"),
    409: _refusal("not allowed now: a rule, the control lock, the regime, a preview"),
    422: _refusal("not possible, or a body of the wrong shape"),
    503: _refusal("the console is starting or stopping"),
}
"""The refusals every API route may answer, for the OpenAPI document."""


def _json(body: dict[str, Any], status: int, headers: dict[str, str] | None = None) -> Response:
    return Response(dumps_finite(body), status_code=status, media_type="application/json", headers=headers)


def _where(loc: tuple | list) -> str:
    return ".".join(str(part) for part in loc) or "body"


def teleprog_refusal(exc: TeleprogError) -> Response:
    """The answer to a refusal the console raised: 400 malformed input, 409 not allowed now, 422
    not possible (also what the jog lane answers, ``server.api.jog_lane``)."""
    if isinstance(exc, InputError):
        status = 400
    elif isinstance(exc, ConflictError):
        status = 409
    else:
        status = 422
    body: dict[str, str] = {"error": type(exc).__name__, "detail": str(exc)}
    if isinstance(exc, RefusedByRule):
        body["rule"] = exc.refusal.rule.value
    return _json(body, status)


def add_error_handler(app: FastAPI) -> None:
    @app.exception_handler(TeleprogError)
    async def _teleprog_error(request: Request, exc: TeleprogError) -> Response:
        return teleprog_refusal(exc)

    @app.exception_handler(RequestValidationError)
    async def _validation_error(request: Request, exc: RequestValidationError) -> Response:
        errors = list(exc.errors())
        listed = [
            {"loc": list(e.get("loc", ())), "msg": str(e.get("msg", "")), "type": str(e.get("type", "")), "input": e.get("input")}
            for e in errors[:MAX_ERRORS_LISTED]
        ]
        first = listed[0] if listed else {"loc": [], "msg": "invalid request"}
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        detail = f"{request.method} {request.url.path}: {_where(first['loc'])}: {first['msg']}{more}"
        return _json({"error": "RequestValidationError", "detail": detail, "errors": listed}, 422)

    @app.exception_handler(StarletteHTTPException)
    async def _http_error(request: Request, exc: StarletteHTTPException) -> Response:
        try:
            reason = HTTPStatus(exc.status_code).phrase
        except ValueError:
            reason = "HTTPException"
        detail = exc.detail if isinstance(exc.detail, str) else dumps_finite(exc.detail)
        return _json({"error": reason, "detail": detail}, exc.status_code, headers=getattr(exc, "headers", None))

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> Response:
        # never by design: log the traceback so the cause can be found and fixed
        log.error("%s %s failed unexpectedly", request.method, request.url.path, exc_info=exc)
        first = str(exc).splitlines()[0][:200] if str(exc) else ""
        return JSONResponse(
            {"error": "InternalError", "detail": f"{request.method} {request.url.path}: unexpected {type(exc).__name__}: {first}"},
            status_code=500,
        )
