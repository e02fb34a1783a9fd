"""Serve viser's 3D page from our FastAPI app, on the app's own port.

viser cannot be mounted as an ASGI sub-app: ``ViserServer`` runs its own ``websockets`` server
in a daemon thread with its own asyncio loop. So:

* :func:`start_viser` starts viser on ``127.0.0.1`` with an OS-assigned port (``port=0``; viser
  reports the port it really bound through ``server.get_port()``);
* :func:`add_viser_routes` serves viser's built client (``viser/client/build/``, a single
  self-contained ``index.html`` in viser 1.1.1) under ``prefix + "/"`` and relays the WebSocket
  at ``prefix`` to viser's port.

How the client finds its WebSocket: without a ``?websocket=<url>`` query parameter it takes
``window.location.href``, swaps ``http``/``https`` for ``ws``/``wss``, drops the query string and
one trailing slash. The page at ``/viser/`` therefore connects to ``ws://<host>/viser``. It offers
one subprotocol, ``viser-v<version>``; viser closes with code 1002 when the version differs, so the
relay passes the subprotocol (and close codes) through unchanged. After connecting, the client
writes ``?websocket=ws://<host>/viser`` into the address bar (cosmetic; viser's "is it the default
server" test never matches a URL with a path).

Run uvicorn with the settings of :func:`uvicorn_config_kwargs` (and one worker)::

    uvicorn.Config(app, host=..., port=..., workers=1, **uvicorn_config_kwargs())
    # command line: uvicorn ... --ws-max-size 52428800 --ws-per-message-deflate false

``ws_max_size`` must be at least viser's own 50 MB (meshes, images and renders arrive as single
large messages), and per-message deflate must be off: viser itself sends uncompressed, and
deflating multi-megabyte scene messages on uvicorn's event loop stalls every request.
"""

from __future__ import annotations

import asyncio
import gzip
import logging
import mimetypes
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import rich
import viser
import websockets
from fastapi import FastAPI, HTTPException, Request, WebSocket
from fastapi.responses import RedirectResponse, Response
from starlette.websockets import WebSocketState
from websockets.asyncio.client import ClientConnection, connect

from server.viser_page import served_page

log = logging.getLogger(__name__)

#: viser's own limit for one WebSocket message (``viser.infra.WebsockServer``).
WS_MAX_SIZE = 50 * 1024 * 1024
#: Where the installed viser keeps its built client.
CLIENT_BUILD_DIR = Path(viser.__file__).resolve().parent / "client" / "build"
#: The subprotocol viser's client offers and viser's server requires.
VISER_SUBPROTOCOL = f"viser-v{viser.__version__}"

# Close codes that may be sent in a close frame (RFC 6455 7.4; 1004-1006 and 1015 are reserved).
_SENDABLE = frozenset({1000, 1001, 1002, 1003, 1007, 1008, 1009, 1010, 1011, 1012, 1013, 1014})


def uvicorn_config_kwargs() -> dict[str, Any]:
    """Settings uvicorn needs for the relayed viser WebSocket (pass to ``uvicorn.Config``/``run``)."""
    # httptools: the compiled HTTP parser (h11, uvicorn's pure-Python fallback, cost about 0.3 ms
    # of console CPU per HTTP jog more); the loop is uvicorn's "auto" (uvloop, a dependency)
    return {"ws_max_size": WS_MAX_SIZE, "ws_per_message_deflate": False, "http": "httptools"}


def start_viser(*, label: str | None = None, verbose: bool = False) -> viser.ViserServer:
    """Start viser on 127.0.0.1 on a free port; ``server.get_port()`` gives the port it bound.

    Never the default ``0.0.0.0:8080``: viser would be reachable from the network and, when 8080
    is busy, silently take the next port. Unless ``verbose``, viser prints nothing while it
    starts (no banner: the console prints the one URL to open). Stop it with ``server.stop()``.
    """
    # viser 1.1.1 prints its banner (its private URL, which is not the page to open) with rich
    # whatever ``verbose`` says; rich's console stays quiet while viser starts, unless verbose
    console = rich.get_console()
    was_quiet = console.quiet
    console.quiet = was_quiet or not verbose
    try:
        server = viser.ViserServer(host="127.0.0.1", port=0, label=label, verbose=verbose)
    finally:
        console.quiet = was_quiet
    port = server.get_port()
    if port == 0:  # an older viser echoing the requested port instead of the bound one
        server.stop()
        raise RuntimeError("viser did not report the port it bound")
    log.info("viser %s listening on 127.0.0.1:%d", viser.__version__, port)
    return server


def _close_code(code: int | None, default: int) -> int:
    if code is None:
        return default
    return code if code in _SENDABLE or 3000 <= code <= 4999 else default


def add_viser_routes(
    app: FastAPI,
    viser_port: Callable[[], int] | int,
    prefix: str = "/viser",
    send_intervals_ms: Mapping[str, int] | None = None,
) -> None:
    """Serve viser's page under ``prefix + "/"`` and relay the WebSocket at ``prefix`` to viser.

    ``viser_port`` is the port viser listens on (127.0.0.1), or a callable returning it when the
    WebSocket connects (it may raise while viser is not running yet: the connection is refused).
    ``send_intervals_ms``: the served page's senders re-paced, by name (``{"gizmo": 10}``:
    ``server.viser_page.SENDERS``); empty or None keeps viser's pacing. Number boxes of the
    served page commit on Enter or on leaving the box (``server.viser_page.NUMBER_COMMIT_JS``).
    """
    prefix = "/" + prefix.strip("/")
    build_dir = CLIENT_BUILD_DIR
    # number boxes commit on Enter or on leaving them (server.viser_page), always; senders re-paced on request
    index_bytes = served_page((build_dir / "index.html").read_text("utf-8"), send_intervals_ms).encode("utf-8")
    index_gzip = gzip.compress(index_bytes, compresslevel=6)

    def resolve_port() -> int:
        return viser_port() if callable(viser_port) else viser_port

    def _index(request: Request) -> Response:
        headers = {"Cache-Control": "no-cache", "Vary": "Accept-Encoding"}
        if "gzip" in request.headers.get("accept-encoding", ""):
            headers["Content-Encoding"] = "gzip"
            return Response(index_gzip, media_type="text/html; charset=utf-8", headers=headers)
        return Response(index_bytes, media_type="text/html; charset=utf-8", headers=headers)

    @app.get(prefix, include_in_schema=False)
    def viser_page_redirect(request: Request) -> RedirectResponse:
        query = request.url.query
        return RedirectResponse(prefix + "/" + ("?" + query if query else ""))

    @app.get(prefix + "/", include_in_schema=False)
    def viser_page(request: Request) -> Response:
        return _index(request)

    @app.get(prefix + "/{path:path}", include_in_schema=False)
    def viser_asset(path: str, request: Request) -> Response:
        segments = [s for s in path.replace("\\", "/").split("/") if s and s != "."]
        if not segments or segments == ["index.html"]:
            return _index(request)
        if ".." in segments or not (build_dir.joinpath(*segments)).is_file():
            raise HTTPException(404)
        file = build_dir.joinpath(*segments)
        media_type = mimetypes.guess_type(file.name)[0] or "application/octet-stream"
        return Response(file.read_bytes(), media_type=media_type)

    async def relay(websocket: WebSocket) -> None:
        try:
            port = resolve_port()
        except Exception as exc:  # noqa: BLE001 - e.g. HTTPException(503) before the lifespan ran
            log.warning("refusing viser WebSocket: no viser port (%s)", exc)
            await websocket.close(code=1013)
            return
        offered = list(websocket.scope.get("subprotocols") or [])
        try:
            upstream = await connect(
                f"ws://127.0.0.1:{port}/",
                subprotocols=[websockets.Subprotocol(p) for p in offered] or None,
                compression=None,
                max_size=None,  # uvicorn already limits what the browser sends
                ping_interval=None,  # viser pings us; loopback needs no keepalive of its own
                open_timeout=10,
                close_timeout=2,
            )
        except (OSError, asyncio.TimeoutError, websockets.InvalidHandshake) as exc:
            log.warning("cannot reach viser on 127.0.0.1:%d: %s", port, exc)
            await websocket.close(code=1011)
            return
        try:
            await websocket.accept(subprotocol=upstream.subprotocol)
        except BaseException:  # the browser left during the upstream handshake
            await upstream.close()
            raise
        log.debug("relaying %s to viser port %d (subprotocol %s)", websocket.client, port, upstream.subprotocol)
        await _pump_both(websocket, upstream)

    app.add_api_websocket_route(prefix, relay, name="viser_ws")
    app.add_api_websocket_route(prefix + "/", relay, name="viser_ws_slash")


async def _pump_both(browser: WebSocket, upstream: ClientConnection) -> None:
    """Copy frames both ways until either side closes, then close the other side."""

    async def browser_to_viser() -> tuple[int, str]:
        while True:
            message = await browser.receive()
            if message["type"] == "websocket.disconnect":
                return int(message.get("code") or 1005), str(message.get("reason") or "")
            if message.get("bytes") is not None:
                await upstream.send(message["bytes"])
            elif message.get("text") is not None:
                await upstream.send(message["text"])

    async def viser_to_browser() -> None:
        async for data in upstream:
            if isinstance(data, bytes):
                await browser.send_bytes(data)
            else:
                await browser.send_text(data)

    to_viser = asyncio.create_task(browser_to_viser(), name="browser_to_viser")
    to_browser = asyncio.create_task(viser_to_browser(), name="viser_to_browser")
    browser_code, browser_reason = 1001, ""
    try:
        await asyncio.wait({to_viser, to_browser}, return_when=asyncio.FIRST_COMPLETED)
        if to_viser.done() and not to_viser.cancelled() and to_viser.exception() is None:
            browser_code, browser_reason = to_viser.result()
    finally:
        for task in (to_viser, to_browser):
            task.cancel()
        for task, result in zip(
            (to_viser, to_browser), await asyncio.gather(to_viser, to_browser, return_exceptions=True)
        ):
            if isinstance(result, Exception):
                quiet = isinstance(result, websockets.ConnectionClosed) or type(result).__name__ in {
                    "ClientDisconnected", "WebSocketDisconnect"}
                log.log(logging.DEBUG if quiet else logging.WARNING, "viser relay: %s ended: %r", task.get_name(), result)
        # Close whichever side is still open, passing the other side's close code on.
        await upstream.close(_close_code(browser_code, 1000), browser_reason[:120])
        if browser.application_state == WebSocketState.CONNECTED and browser.client_state == WebSocketState.CONNECTED:
            try:
                await browser.close(code=_close_code(upstream.close_code, 1011), reason=(upstream.close_reason or "")[:120])
            except Exception as exc:  # noqa: BLE001 - the browser may vanish at the same moment
                log.debug("viser relay: closing browser side: %r", exc)
        log.debug(
            "viser relay closed by %s (browser code %s, viser code %s)",
            "the browser" if to_viser.done() and not to_viser.cancelled() else "viser",
            browser_code if to_viser.done() and not to_viser.cancelled() else "-",
            upstream.close_code,
        )
