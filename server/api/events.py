"""``/api/events``: a WebSocket streaming every ``SessionEvent`` as one JSON text message.

The first message is ``{"type": "snapshot", ...}`` (a ``SessionSnapshot`` with a type field),
then events as they happen. Events are queued per watcher; a watcher that falls far behind
loses the oldest ones and gets a fresh snapshot instead, so one slow client cannot grow memory.
"""

from __future__ import annotations

import asyncio
import logging

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from pydantic import TypeAdapter

from server.console import SessionEvent
from shared.wire.strict_json import dumps_finite

router = APIRouter(tags=["events"])
log = logging.getLogger(__name__)

_adapter: TypeAdapter[SessionEvent] = TypeAdapter(SessionEvent)
QUEUE_LIMIT = 2000


@router.websocket("/api/events")
async def events(websocket: WebSocket) -> None:
    console = getattr(websocket.app.state, "console", None)
    if console is None:
        await websocket.close(code=1013)
        return
    session = console.session
    await websocket.accept()
    loop = asyncio.get_running_loop()
    queue: asyncio.Queue[str | None] = asyncio.Queue()
    overflow = False

    def push(event) -> None:
        text = _adapter.dump_json(event).decode()

        def put() -> None:
            nonlocal overflow
            if queue.qsize() >= QUEUE_LIMIT:
                overflow = True
                return
            queue.put_nowait(text)

        loop.call_soon_threadsafe(put)

    def snapshot_text() -> str:
        snap = session.snapshot().model_dump(mode="json")
        return dumps_finite({"type": "snapshot", **snap})  # strict JSON even if a view held a NaN

    unsubscribe = session.subscribe_events(push)
    try:
        await websocket.send_text(snapshot_text())
        receiver = asyncio.create_task(websocket.receive_text())
        while True:
            getter = asyncio.create_task(queue.get())
            done, _ = await asyncio.wait({getter, receiver}, return_when=asyncio.FIRST_COMPLETED)
            if receiver in done:
                getter.cancel()
                exc = receiver.exception()
                if exc is not None:
                    break
                receiver = asyncio.create_task(websocket.receive_text())  # clients may send pings; ignored
                continue
            text = getter.result()
            if overflow:
                while not queue.empty():
                    queue.get_nowait()
                overflow = False
                text = snapshot_text()
            await websocket.send_text(text)
    except WebSocketDisconnect:
        pass
    except Exception as exc:  # noqa: BLE001 - the watcher went away mid-send (uvicorn's ClientDisconnected)
        log.debug("events watcher ended: %r", exc)
    finally:
        unsubscribe()
        if "receiver" in locals() and not receiver.done():
            receiver.cancel()
