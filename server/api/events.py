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

    async def watch_receive() -> None:
        """Read (and ignore) what the client sends, e.g. pings; when it leaves, tell the writer."""
        try:
            while True:
                await websocket.receive_text()
        except Exception:  # noqa: BLE001 - WebSocketDisconnect, or the connection broke
            pass
        finally:
            queue.put_nowait(None)

    unsubscribe = session.subscribe_events(push)
    receiver: asyncio.Task | None = None
    try:
        # the snapshot takes the session's lock: on a worker thread, so a busy session never holds the loop
        await websocket.send_text(await asyncio.to_thread(snapshot_text))
        # one long-lived reader; the writer only awaits the queue (no task and no wait set per
        # message: at jogging rates that was a good part of the stream's cost)
        receiver = asyncio.create_task(watch_receive())
        while True:
            text = await queue.get()
            if text is None:
                break
            if overflow:
                while not queue.empty():
                    if queue.get_nowait() is None:
                        return
                overflow = False
                text = await asyncio.to_thread(snapshot_text)
            await websocket.send_text(text)
    except WebSocketDisconnect:
        pass
    except Exception as exc:  # noqa: BLE001 - the watcher went away mid-send (uvicorn's ClientDisconnected)
        log.debug("events watcher ended: %r", exc)
    finally:
        unsubscribe()
        if receiver is not None and not receiver.done():
            receiver.cancel()
