"""viser's page served from our FastAPI app on one port: static client, WebSocket relay, browser.

Real servers throughout: a ViserServer on a private loopback port and uvicorn in a background
thread. The browser test uses the shared ``page`` fixture (headless Debian Chromium) from
tests/conftest.py and stays synchronous (Playwright's sync API refuses a running asyncio loop).
"""

from __future__ import annotations

import re
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import httpx
import msgspec
import numpy as np
import pytest
import uvicorn
import viser
import zstandard
from fastapi import FastAPI, HTTPException
from fastapi.responses import RedirectResponse
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import ClientConnection, connect

from server.viser_host import (
    CLIENT_BUILD_DIR,
    VISER_SUBPROTOCOL,
    add_viser_routes,
    start_viser,
    uvicorn_config_kwargs,
)
from server.viser_page import read_send_intervals_ms, served_page, unpack

pytestmark = pytest.mark.timeout(120)

BOX_NAME = "/relay_test_box"
# What the page sends first: msgpack of the message's fields plus its type name.
CAMERA_MESSAGE = msgspec.msgpack.encode(
    {
        "type": "ViewerCameraMessage",
        "wxyz": (1.0, 0.0, 0.0, 0.0),
        "position": (0.0, 0.0, -3.0),
        "fov": 1.0,
        "near": 0.01,
        "far": 100.0,
        "image_height": 480,
        "image_width": 640,
        "look_at": (0.0, 0.0, 0.0),
        "up_direction": (0.0, -1.0, 0.0),
    }
)


# ---------------------------------------------------------------- fixtures and helpers


def port_is_closed(port: int) -> bool:
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1.0):
            return False
    except OSError:
        return True


@contextmanager
def serve_in_thread(app: FastAPI) -> Iterator[str]:
    """Run ``app`` under a real uvicorn on a free loopback port; yield its base URL."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind(("127.0.0.1", 0))
    port = int(sock.getsockname()[1])
    config = uvicorn.Config(app, log_level="warning", lifespan="off", **uvicorn_config_kwargs())
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, name="test-uvicorn", daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + 15
        while not server.started:
            if not thread.is_alive() or time.monotonic() > deadline:
                raise RuntimeError("uvicorn did not start")
            time.sleep(0.02)
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(timeout=15)
        sock.close()
        assert not thread.is_alive(), "uvicorn thread still running"
        assert port_is_closed(port), f"port {port} still accepts connections"


@pytest.fixture
def viser_server() -> Iterator[viser.ViserServer]:
    server = start_viser()
    port = server.get_port()
    assert port != 0 and server.get_host() == "127.0.0.1"
    server.scene.add_box(BOX_NAME, dimensions=(0.2, 0.2, 0.2), color=(255, 0, 0))
    yield server
    server.stop()
    assert not any(t.is_alive() for t in [server._websock_server._server_thread] if t is not None)
    assert port_is_closed(port), f"viser port {port} still accepts connections"


def make_app(viser_port: Any, send_intervals_ms: dict[str, int] | None = None) -> FastAPI:
    app = FastAPI()

    @app.get("/", include_in_schema=False)
    def index() -> RedirectResponse:
        return RedirectResponse("/viser/")

    add_viser_routes(app, viser_port, send_intervals_ms=send_intervals_ms)
    return app


@pytest.fixture
def relay_url(viser_server: viser.ViserServer) -> Iterator[str]:
    """Base URL (http://127.0.0.1:PORT) of a FastAPI app relaying to ``viser_server``."""
    with serve_in_thread(make_app(viser_server.get_port)) as url:
        yield url


def ws_url(base: str) -> str:
    return base.replace("http://", "ws://") + "/viser"


def decode_frame(frame: bytes) -> dict[str, Any]:
    """Decode one viser wire frame: [u64 raw size][u64 zstd size][zstd msgpack][binary buffers]."""
    raw_size = int.from_bytes(frame[:8], "little")
    zstd_size = int.from_bytes(frame[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(frame[16 : 16 + zstd_size], max_output_size=raw_size)
    return msgspec.msgpack.decode(inner)


def receive_until(
    ws: ClientConnection, predicate: Any, timeout: float = 10.0, frame_sizes: list[int] | None = None
) -> list[dict[str, Any]]:
    """Collect viser messages until one satisfies ``predicate``; fail on a text frame or timeout."""
    messages: list[dict[str, Any]] = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        frame = ws.recv(timeout=max(0.05, deadline - time.monotonic()))
        assert isinstance(frame, bytes), f"viser sends binary frames, got {type(frame)}"
        if frame_sizes is not None:
            frame_sizes.append(len(frame))
        messages.extend(decode_frame(frame)["messages"])
        if any(predicate(m) for m in messages):
            return messages
    raise AssertionError(f"no matching message within {timeout} s; got types {[m['type'] for m in messages]}")


# ---------------------------------------------------------------- (a) static page


def test_page_is_served_with_its_assets(relay_url: str) -> None:
    with httpx.Client(base_url=relay_url, timeout=10.0) as client:
        root = client.get("/")
        assert root.status_code in (302, 307) and root.headers["location"] == "/viser/"
        assert client.get("/viser").headers["location"] == "/viser/"

        page = client.get("/viser/")
        assert page.status_code == 200
        assert page.headers["content-type"].startswith("text/html")
        assert "<title>Viser</title>" in page.text
        assert page.content == served_page((CLIENT_BUILD_DIR / "index.html").read_text("utf-8")).encode("utf-8")
        plain = client.get("/viser/", headers={"Accept-Encoding": "identity"})
        assert plain.headers.get("content-encoding") is None and plain.content == page.content
        assert client.get("/viser/index.html").content == page.content

        # Every same-origin asset the page references must load (viser 1.1.1 inlines everything
        # into index.html, so this list may well be empty; the build directory is checked too).
        refs = re.findall(r'(?:src|href)="([^"#]+)"', page.text)
        local = [r for r in refs if not re.match(r"^(?:[a-z]+:|//)", r)]
        built = [p.relative_to(CLIENT_BUILD_DIR).as_posix() for p in CLIENT_BUILD_DIR.rglob("*") if p.is_file()]
        for ref in {*(r.lstrip("./") for r in local), *built}:
            url = "/viser/" + ref if not ref.startswith("/") else ref
            assert client.get(url).status_code == 200, url

        assert client.get("/viser/no-such-file.js").status_code == 404
        assert client.get("/viser/..%2f..%2fpyproject.toml").status_code == 404


def test_page_can_be_served_with_the_gizmo_paced_faster() -> None:
    with serve_in_thread(make_app(1, send_intervals_ms={"gizmo": 12})) as url:  # no viser needed for the page
        with httpx.Client(base_url=url, timeout=10.0) as client:
            page = client.get("/viser/")
            plain = client.get("/viser/", headers={"Accept-Encoding": "identity"})
    original = (CLIENT_BUILD_DIR / "index.html").read_text("utf-8")
    assert page.status_code == 200 and page.content == plain.content
    assert read_send_intervals_ms(page.text) == {"gizmo": 12} and read_send_intervals_ms(original) == {"gizmo": 50}
    assert unpack(page.text).style == unpack(original).style


# ---------------------------------------------------------------- (b) WebSocket relay


def test_websocket_relay_delivers_viser_messages_and_closes_both_sides(
    viser_server: viser.ViserServer, relay_url: str
) -> None:
    connected = threading.Event()
    disconnected = threading.Event()
    viser_server.on_client_connect(lambda _client: connected.set())
    viser_server.on_client_disconnect(lambda _client: disconnected.set())

    with connect(ws_url(relay_url), subprotocols=[VISER_SUBPROTOCOL], max_size=None, open_timeout=10) as ws:
        assert ws.subprotocol == VISER_SUBPROTOCOL
        messages = receive_until(ws, lambda m: m.get("name") == BOX_NAME)
        assert any(m["type"] == "BoxMessage" for m in messages)

        # Client -> viser: viser counts a client as connected once its first camera message
        # arrives (the page sends one as soon as it renders).
        ws.send(CAMERA_MESSAGE)
        assert connected.wait(5), "the camera message did not reach viser"
        assert len(viser_server.get_clients()) == 1

        # Later scene updates flow through the same connection, large binary ones included
        # (600k points: a 3.6 MB frame, beyond websockets' 1 MiB default limit).
        points = np.random.default_rng(0).random((600_000, 3), dtype=np.float32)
        viser_server.scene.add_point_cloud("/later_cloud", points=points, colors=(0, 0, 255))
        sizes: list[int] = []
        messages = receive_until(ws, lambda m: m.get("name") == "/later_cloud", frame_sizes=sizes)
        assert any(m["type"] == "PointCloudMessage" for m in messages)
        assert max(sizes) > 3_000_000  # viser sends the positions as float16: 3.6 MB

    # The client closed: the relay must close its upstream connection, so viser sees it leave.
    assert disconnected.wait(5), "viser never saw the relayed client disconnect"
    deadline = time.monotonic() + 5
    while viser_server.get_clients() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert viser_server.get_clients() == {}


def test_viser_closing_closes_the_client(viser_server: viser.ViserServer, relay_url: str) -> None:
    with connect(ws_url(relay_url), subprotocols=[VISER_SUBPROTOCOL], max_size=None) as ws:
        receive_until(ws, lambda m: m.get("name") == BOX_NAME)
        # Documented in viser.infra.WebsockServer as the way to drop clients from tests.
        viser_server._websock_server.disconnect_all_clients()
        with pytest.raises(ConnectionClosed) as closed:
            while True:
                ws.recv(timeout=10)
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 1000


def test_subprotocol_and_close_code_pass_through(relay_url: str) -> None:
    # viser rejects a client of another version with close code 1002, which its page shows as a
    # version mismatch; the relay must not turn that into a generic error.
    with connect(ws_url(relay_url), subprotocols=["viser-v0.0.0"]) as ws:
        assert ws.subprotocol == "viser-v0.0.0"
        with pytest.raises(ConnectionClosed) as closed:
            ws.recv(timeout=10)
    assert closed.value.rcvd is not None and closed.value.rcvd.code == 1002
    assert "Version mismatch" in closed.value.rcvd.reason


def test_relay_refuses_while_viser_is_not_running() -> None:
    def no_scene() -> int:
        raise HTTPException(503, "the 3D scene is not running yet")

    with serve_in_thread(make_app(no_scene)) as url:
        with pytest.raises(InvalidStatus):
            connect(ws_url(url), subprotocols=[VISER_SUBPROTOCOL], open_timeout=10)
        assert httpx.get(url + "/viser/", timeout=10).status_code == 200  # the page itself still loads


# ---------------------------------------------------------------- (c) headless Chromium


@pytest.mark.browser
def test_browser_renders_page_and_button_click_reaches_python(
    viser_server: viser.ViserServer, relay_url: str, page: Any
) -> None:
    clicked = threading.Event()
    left = threading.Event()
    viser_server.on_client_disconnect(lambda _client: left.set())
    button = viser_server.gui.add_button("Hello")
    button.on_click(lambda _event: clicked.set())

    sockets: list[str] = []
    page.on("websocket", lambda ws: sockets.append(ws.url))
    requested: list[str] = []
    page.on("request", lambda request: requested.append(request.url))

    page.goto(relay_url + "/")
    page.wait_for_selector("canvas", state="attached", timeout=30_000)
    hello = page.get_by_role("button", name="Hello")
    hello.wait_for(state="visible", timeout=30_000)
    assert page.get_by_text("Hello").first.is_visible()
    assert page.evaluate("() => !!document.querySelector('canvas')")

    hello.click()
    assert clicked.wait(10), "the click did not reach the Python on_click callback"

    # One port: the page and its WebSocket all go through our app, never viser's private port.
    base = relay_url + "/"
    assert sockets and all(u.startswith(ws_url(relay_url)) for u in sockets), sockets
    assert all(u.startswith(base) or u.startswith("data:") or u.startswith("blob:") for u in requested), requested
    assert f":{viser_server.get_port()}" not in " ".join(sockets + requested)
    assert len(viser_server.get_clients()) == 1

    # Leaving the page closes the relayed connection all the way to viser.
    page.goto("about:blank")
    assert left.wait(10), "viser did not see the browser leave"
