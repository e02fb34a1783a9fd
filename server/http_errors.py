"""How a refused request reads over HTTP, for every app of the console (one definition).

``{"error": <type>, "detail": <one line saying what and where>}`` with 400 for malformed input,
409 for an action the state does not allow now (a rule of the editor, the control lock, a running
preview; ``rule`` names an editor rule) and 422 for what is impossible (a joint limit, an
unreachable pose).
"""

from __future__ import annotations

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse

from server.console_models import ConflictError, RefusedByRule
from shared.errors import InputError, TeleprogError


def add_error_handler(app: FastAPI) -> None:
    @app.exception_handler(TeleprogError)
    async def _teleprog_error(request: Request, exc: TeleprogError) -> JSONResponse:
        if isinstance(exc, InputError):
            status = 400
        elif isinstance(exc, ConflictError):
            status = 409
        else:
            status = 422
        body: dict[str, str] = {"error": type(exc).__name__, "detail": str(exc)}
        if isinstance(exc, RefusedByRule):
            body["rule"] = exc.refusal.rule.value
        return JSONResponse(body, status_code=status)
