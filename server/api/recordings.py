"""The session recordings: the one being written now and those in the recordings folder.

Any app that serves this router (the console, the replay) puts a ``RecordingsSource`` on
``app.state.recordings``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from fastapi import APIRouter, HTTPException, Request
from pydantic import BaseModel, Field

from server.recording.reader import list_recordings

router = APIRouter(prefix="/api", tags=["session"])


@dataclass
class RecordingsSource:
    folder: Path
    current: Callable[[], "RecordingNow | None"] = lambda: None


class RecordingNow(BaseModel):
    path: str
    written: int = Field(description="messages written so far")
    dropped: int = Field(description="messages dropped because the writer fell behind")
    failed: str | None = Field(None, description="why recording stopped, if it did")


class RecordingOut(BaseModel):
    name: str
    path: str
    size: int = Field(description="bytes")
    modified: float = Field(description="Unix s")


class SessionsOut(BaseModel):
    folder: str
    recording: RecordingNow | None = Field(None, description="the recording this console writes now")
    sessions: list[RecordingOut] = Field(description="recordings in the folder, newest first")


@router.get("/sessions", response_model=SessionsOut)
def sessions(request: Request) -> SessionsOut:
    source: RecordingsSource | None = getattr(request.app.state, "recordings", None)
    if source is None:
        raise HTTPException(503, "the console is not running yet")
    found = [RecordingOut(name=r.name, path=r.path, size=r.size, modified=r.modified) for r in list_recordings(source.folder)]
    return SessionsOut(folder=str(source.folder), recording=source.current(), sessions=found)
