"""The jog lane (``server.api.jog_lane``) answers the two jog routes exactly as the routes do.

The same requests go to two fresh consoles: one as ``application/json`` (the lane answers),
one as ``application/merge-patch+json``, a JSON media type the lane leaves to FastAPI's route.
Every answer - jogs, refusals of the control lock, malformed bodies, long headers - must be the
same, and the lane must have run the jog itself only for the first."""

from __future__ import annotations

import json

import pytest
from fastapi.testclient import TestClient

import server.api.jog_lane as jog_lane
from server.app import create_app
from server.settings import ConsoleSettings

LANE = "application/json"
ROUTE = "application/merge-patch+json"


@pytest.fixture
def spied(monkeypatch) -> list[str]:
    """The paths whose jog the lane ran itself."""
    ran: list[str] = []
    for path, (model, handler) in list(jog_lane.ROUTES.items()):
        def spy(session, body, client, _handler=handler, _path=path):
            ran.append(_path)
            return _handler(session, body, client)
        monkeypatch.setitem(jog_lane.ROUTES, path, (model, spy))
    return ran


def _post(client: TestClient, path: str, body: str, media: str, headers: dict[str, str] | None = None):
    reply = client.post(path, content=body.encode("utf-8"), headers={"content-type": media, **(headers or {})})
    return reply.status_code, reply.json()


def _session_script(client: TestClient, media: str) -> list[tuple[int, object]]:
    """A short session: jogs of both kinds, a refused one, the lock, malformed bodies."""
    answers = [(200, client.get("/api/state").json())]
    jogs = [
        ("/api/jog/tool", '{"frame": "world", "constraint": "xy", "motion": "translate", "displacement": [4, -2, 0]}'),
        ("/api/jog/tool", '{"frame": "tool", "constraint": "z", "motion": "rotate", "displacement": [0, 0, 5]}'),
        ("/api/jog/joint", '{"joint": 2, "delta_deg": -3.5}'),
        ("/api/jog/joint", '{"joint": 1, "delta_deg": 400}'),  # past joint 1's limit: stops there
        ("/api/jog/tool", '{"displacement": [NaN, 0, 0]}'),  # not strict JSON: 400
        ("/api/jog/tool", '{"displacement": [1, 2]}'),  # wrong shape: 422
        ("/api/jog/joint", '{"joint": 1, "delta_deg": 1, "joint": 2}'),  # a key twice: 400
        ("/api/jog/joint", ""),  # no body: 422
        ("/api/jog/joint", "[1, 2]"),
    ]
    for path, body in jogs:
        answers.append(_post(client, path, body, media))
    answers.append(_post(client, "/api/jog/joint", '{"joint": 1, "delta_deg": 1}', media, {"X-Teleprog-Client": "x" * 201}))
    grant = client.post("/api/control/request", headers={"X-Teleprog-Client": "alice"}).json()
    answers.append(_post(client, "/api/jog/joint", '{"joint": 1, "delta_deg": 1}', media, {"X-Teleprog-Client": "bob"}))
    answers.append(_post(client, "/api/jog/joint", '{"joint": 2, "delta_deg": 1}', media,
                         {"X-Teleprog-Client": "alice", "X-Teleprog-Token": grant["token"]}))
    answers.append((200, client.get("/api/state").json()))
    return answers


def _run(media: str) -> list[tuple[int, object]]:
    with TestClient(create_app(ConsoleSettings(no_robot=True), build_page=False)) as client:
        return _session_script(client, media)


def test_the_lane_answers_as_the_routes_do(spied: list[str]) -> None:
    through_route = _run(ROUTE)
    assert spied == []  # another JSON media type: FastAPI's route answered every one
    through_lane = _run(LANE)
    # every well-formed body, refused by the session or not (the lock, a jog too large)
    assert spied.count("/api/jog/tool") == 2 and spied.count("/api/jog/joint") == 4

    assert [status for status, _ in through_lane] == [status for status, _ in through_route]
    assert [status for status, _ in through_lane] == [200, 200, 200, 200, 200, 400, 422, 400, 422, 422, 422, 409, 200, 200]
    for (_, lane), (_, route) in zip(through_lane, through_route):
        assert json.dumps(lane, sort_keys=True) == json.dumps(route, sort_keys=True)
    start, moved = through_lane[0][1], through_lane[1][1]
    assert moved["tool_xyz_mm"][0] == pytest.approx(start["tool_xyz_mm"][0] + 4, abs=1e-6)  # a real move
    assert through_lane[4][1]["q_deg"][0] == pytest.approx(160.0)  # joint 1's upper limit
    assert through_lane[-1][1]["q_deg"][1] == pytest.approx(through_lane[4][1]["q_deg"][1] + 1)  # alice's jog
    assert through_lane[-1][1]["version"] > moved["version"] > start["version"]


def test_other_methods_and_paths_pass_through(spied: list[str]) -> None:
    with TestClient(create_app(ConsoleSettings(no_robot=True), build_page=False)) as client:
        assert client.get("/api/jog/tool").status_code == 405
        assert client.post("/api/jog/release").status_code == 200
    assert spied == []
