"""Shared dependencies of the API routers: the session and the caller's client id."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Header, HTTPException, Request

from server.session import Session


def get_session(request: Request) -> Session:
    console = getattr(request.app.state, "console", None)
    if console is None:
        raise HTTPException(503, "the console session is not running yet")
    return console.session


def get_client(x_teleprog_client: Annotated[str | None, Header()] = None) -> str | None:
    """The caller's id from the ``X-Teleprog-Client`` header (``None``: the page)."""
    return x_teleprog_client or None


SessionDep = Annotated[Session, Depends(get_session)]
ClientDep = Annotated[str | None, Depends(get_client)]
