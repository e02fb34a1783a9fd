"""``/api/events``: the snapshot first, then every event of a jog in order; a watcher that
leaves stops being fed, and the others keep theirs."""

from __future__ import annotations

import json

from fastapi.testclient import TestClient

from server.app import create_app
from server.settings import ConsoleSettings


def _next(ws) -> dict:
    """The next event that is not the link view's timer (published every 0.25 s from the session's
    clock thread, so it may fall anywhere between a jog's events)."""
    while (event := json.loads(ws.receive_text()))["type"] == "link":
        pass
    return event


def _types(ws, n: int) -> list[str]:
    return [_next(ws)["type"] for _ in range(n)]


def test_events_follow_jogs_in_order_and_a_leaving_watcher_is_dropped() -> None:
    app = create_app(ConsoleSettings(no_robot=True), build_page=False)
    with TestClient(app) as client:
        session = app.state.console.session
        watchers_before = len(session.bus.events._listeners)
        with client.websocket_connect("/api/events") as first, client.websocket_connect("/api/events") as second:
            assert _types(first, 1) == ["snapshot"] and _types(second, 1) == ["snapshot"]
            assert len(session.bus.events._listeners) == watchers_before + 2
            versions = []
            for k in range(5):
                reply = client.post("/api/jog/joint", json={"joint": 1, "delta_deg": 1.0 + k})
                assert reply.status_code == 200
                for ws in (first, second):
                    arm = _next(ws)
                    assert arm["type"] == "arm"
                    assert _types(ws, 1) == ["collision"]
                versions.append(arm["arm"]["version"])
            assert versions == sorted(versions) and len(set(versions)) == 5
            first.send_text("ping")  # what a client sends is read and ignored
            first.close()
            # the one that left is dropped; the other still gets every event
            client.post("/api/jog/joint", json={"joint": 1, "delta_deg": -1.0})
            assert _types(second, 2) == ["arm", "collision"]
            for _ in range(100):
                if len(session.bus.events._listeners) == watchers_before + 1:
                    break
                client.get("/api/health")
            assert len(session.bus.events._listeners) == watchers_before + 1
        for _ in range(100):
            if len(session.bus.events._listeners) == watchers_before:
                break
            client.get("/api/health")
        assert len(session.bus.events._listeners) == watchers_before
