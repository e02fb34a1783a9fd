"""The console's HTTP API against hostile input and rival clients, on a real ``teleprog up``
(telerobot, link and console as processes on loopback).

* A refused request changes nothing: every editing endpoint, given NaN, infinity, a key twice,
  a number too large to be finite, a ``"NaN"`` string, deep nesting or bytes that are not UTF-8,
  answers 4xx with one clear line, and the program, the sent list, the arm, the objects and the
  control lock read exactly as before (issue 14, findings 3 and 7).
* No request answers 5xx: a DRAW at 1e308 m cannot be submitted or previewed into a 500, four
  identical pixels do not reach the pose solver (finding 7).
* The control lock means something: a token only the holder gets, needed by every call that
  changes state and by release, never published; an explicit take-over is logged and the
  former holder sees it; the lock is checked before any work (finding 9).
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator

import httpx
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from websockets.sync.client import connect

from support import RunningConsole, start_console, stop_process, wait_for

JSON = {"content-type": "application/json"}


@pytest.fixture(scope="module")
def up(tmp_path_factory) -> Iterator[RunningConsole]:
    running = start_console(tmp_path_factory.mktemp("refusals"), "--delay-ms", "20")
    try:
        wait_for(lambda: running.api("GET", "/api/link").json()["connected"], 30, 0.1, "the link")
        yield running
    finally:
        stop_process(running.proc)


def raw(up: RunningConsole, method: str, path: str, body: str | bytes | None = None, headers: dict | None = None) -> httpx.Response:
    """A request with the body exactly as given (NaN and repeated keys reach the server)."""
    return up.api(method, path, content=body, headers={**JSON, **(headers or {})})


def ok(response: httpx.Response) -> dict:
    assert response.status_code == 200, f"{response.request.method} {response.request.url.path}: {response.status_code} {response.text}"
    return response.json()


def state(up: RunningConsole) -> dict:
    """Everything a refused request must leave as it was (not the link's ages or telemetry, and
    not the program's ``refusal``: the refusal shown on its line is the answer, not a change)."""
    snap = ok(up.api("GET", "/api/session"))
    kept = {key: snap[key] for key in ("arm", "program", "preview", "sent", "regime", "display", "control")}
    kept["program"] = {k: v for k, v in kept["program"].items() if k != "refusal"}
    return kept


def assert_clear_refusal(response: httpx.Response) -> dict:
    assert 400 <= response.status_code < 500, f"{response.request.url.path}: {response.status_code} {response.text[:300]}"
    body = response.json()
    assert body["error"] and body["detail"] and "\n" not in body["detail"] and "Traceback" not in body["detail"], body
    return body


@pytest.fixture
def program(up: RunningConsole) -> Iterator[None]:
    """A small program with its first statement selected; emptied afterwards."""
    ok(up.api("POST", "/api/program/load", json={"text": "DRIVE J1 TO 10 deg\nSPEED 50 %\nEVENT mark\n", "filename": "p.tp"}))
    ok(up.api("POST", "/api/program/select", json={"index": 0}))
    yield
    up.api("POST", "/api/preview/end")
    ok(up.api("POST", "/api/program/load", json={"text": "", "filename": "empty.tp"}))


# ------------------------------------------------------------------ a refused request changes nothing

NAN_DRIVE = '{"statement": {"kind": "DRIVE", "joint": 1, "target": NaN}}'


def test_an_insert_refused_for_a_nan_inserts_nothing(up: RunningConsole, program: None) -> None:
    ok(up.api("POST", "/api/program/select", json={"index": 3}))  # the trailing empty statement
    before = state(up)
    refused = raw(up, "POST", "/api/program/insert", NAN_DRIVE)
    assert refused.status_code == 400 and "NaN" in assert_clear_refusal(refused)["detail"]
    assert state(up) == before
    # the console is not wedged: the program still reads and takes a good statement
    after = ok(raw(up, "POST", "/api/program/insert", '{"text": "DRIVE J2 TO 5 deg"}'))
    assert [e["kind"] for e in after["entries"]] == ["DRIVE", "SPEED", "EVENT", "DRIVE", "EMPTY"]


HOSTILE_BODIES = {
    "NaN": '{"statement": {"kind": "DRIVE", "joint": 1, "target": NaN}}',
    "Infinity": '{"statement": {"kind": "DRIVE", "joint": 1, "target": -Infinity}}',
    "too large": '{"statement": {"kind": "DRIVE", "joint": 1, "target": 1e400}}',
    "key twice": '{"text": "DRIVE J1 TO 5 deg", "text": "DRIVE J1 TO 6 deg"}',
    "NaN string": '{"statement": {"kind": "DRIVE", "joint": 1, "target": "NaN"}}',
    "deep": '{"statement": ' + "[" * 200 + "]" * 200 + "}",
    "not UTF-8": b'{"text": "DRIVE J1 TO 5 deg \xff"}',
    "not JSON": "{text: DRIVE}",
    "wrong shape": '{"statement": {"kind": "DRIVE", "joint": "one", "target": 0.1}}',
    "both forms": '{"text": "DRIVE J1 TO 5 deg", "statement": {"kind": "DRIVE", "joint": 1, "target": 0.1}}',
    "unwritable text": '{"text": "DRIVE J1 TO nan deg"}',
}

ENDPOINT_BODIES = [
    *(("POST", "/api/program/insert", name, body) for name, body in HOSTILE_BODIES.items()),
    *(("POST", "/api/program/modify", name, body) for name, body in HOSTILE_BODIES.items()),
    ("POST", "/api/program/conditions", "NaN speed", '{"speed": {"value": NaN, "unit": "fraction"}}'),
    ("POST", "/api/program/conditions", "NaN string", '{"until": {"kind": "force", "newtons": "NaN"}}'),
    ("POST", "/api/program/select", "key twice", '{"index": 1, "index": 0}'),
    ("POST", "/api/program/select", "huge", '{"index": 1e400}'),
    ("PUT", "/api/program/auto", "key twice", '{"on": true, "on": false}'),
    ("POST", "/api/program/load", "JSON form with NaN",
     json.dumps({"text": '{"statements": [{"kind": "DRIVE", "joint": 1, "target": NaN}]}', "filename": "p.json"})),
    ("POST", "/api/program/load", "Infinity", '{"text": "EVENT a", "filename": "p.tp", "x": Infinity}'),
    ("POST", "/api/program/load", "broken text", json.dumps({"text": "DRIVE J1 TO nan deg\n", "filename": "p.tp"})),
    ("POST", "/api/program/upload?filename=p.tp", "not UTF-8", b"DRIVE J1 TO 5 deg \xff\n"),
    ("POST", "/api/preview/begin", "NaN", '{"start": 0, "stop": NaN}'),
    ("POST", "/api/preview/seek", "NaN string", '{"t": "NaN"}'),
    ("POST", "/api/submit", "key twice", '{"start": 0, "stop": 1, "stop": 3}'),
    ("PUT", "/api/robot/joints", "NaN", '{"deg": [NaN, 0, 0, 0, 0, 0]}'),
    ("PUT", "/api/robot/joints", "NaN string", '{"deg": ["NaN", 0, 0, 0, 0, 0]}'),
    ("PUT", "/api/robot/joints", "huge", '{"deg": [1e308, 0, 0, 0, 0, 0]}'),
    ("POST", "/api/jog/joint", "Infinity", '{"joint": 1, "delta_deg": Infinity}'),
    ("POST", "/api/jog/joint", "huge joint", '{"joint": 1e30, "delta_deg": 1}'),
    ("POST", "/api/jog/tool", "inf string", '{"displacement": ["inf", 0, 0]}'),
    ("POST", "/api/jog/tool", "huge", '{"displacement": [1e308, 0, 0]}'),
    ("POST", "/api/objects/peg/locate", "NaN", '{"camera": "front", "pixels": [[NaN, 1], [2, 2], [3, 4], [5, 1]]}'),
    ("POST", "/api/objects/peg/locate", "same pixel", '{"camera": "front", "pixels": [[1, 1], [1, 1], [1, 1], [1, 1]]}'),
    ("POST", "/api/objects/peg/locate", "off any image", '{"camera": "front", "pixels": [[1e300, 1], [2, 2], [3, 4], [5, 1]]}'),
    ("PUT", "/api/regime", "key twice", '{"regime": "free", "regime": "operation"}'),
    ("PUT", "/api/display", "NaN", '{"mode": NaN}'),
    ("POST", "/api/terrain/placement", "NaN", '{"target_mm": [NaN, 0, 0]}'),
]


@pytest.mark.parametrize(("method", "path", "what", "body"), ENDPOINT_BODIES, ids=[f"{p} {w}" for _, p, w, _ in ENDPOINT_BODIES])
def test_every_editing_endpoint_refuses_bad_bodies_without_change(
    up: RunningConsole, program: None, method: str, path: str, what: str, body: str | bytes
) -> None:
    before = state(up)
    assert_clear_refusal(raw(up, method, path, body, headers={} if "upload" not in path else {"content-type": "text/plain"}))
    assert state(up) == before, f"{method} {path} ({what}) was refused but changed the session"


# ------------------------------------------------------------------ no 5xx where there were

def test_a_draw_at_1e308_m_is_refused_by_submit_and_preview_not_a_500(up: RunningConsole, program: None) -> None:
    ok(up.api("POST", "/api/program/load", json={"text": "", "filename": "empty.tp"}))
    ok(up.api("PUT", "/api/regime", json={"regime": "free"}))
    try:
        inserted = raw(up, "POST", "/api/program/insert", '{"statement": {"kind": "DRAW", "position": [1e308, 0, 0]}}')
        if inserted.status_code != 200:  # refused by the statement's own bounds: the best answer
            assert_clear_refusal(inserted)
            return
        before = state(up)
        for path, body in (("/api/submit", {"start": 0, "stop": 1}), ("/api/preview/begin", {"start": 0, "stop": 1})):
            assert_clear_refusal(up.api("POST", path, json=body))
            assert state(up) == before, f"{path} refused the DRAW but changed the session"
        assert ok(up.api("GET", "/api/sent")) == before["sent"]
    finally:
        ok(up.api("PUT", "/api/regime", json={"regime": None}))


def test_four_identical_pixels_are_degenerate_not_a_500(up: RunningConsole) -> None:
    camera = ok(up.api("GET", "/api/cameras"))[0]["name"]
    before = state(up)
    refused = up.api("POST", "/api/objects/peg/locate", json={"camera": camera, "pixels": [[320, 240]] * 4})
    assert refused.status_code == 400 and "pixels are degenerate" in assert_clear_refusal(refused)["detail"], refused.text
    assert state(up) == before
    # collinear and far-apart pixels: refused with a reason too, never a 500
    for pixels in ([[10, 10], [20, 20], [30, 30], [40, 40]], [[0, 0], [1e6, 0], [0, 1e6], [-1e6, -1e6]]):
        assert_clear_refusal(up.api("POST", "/api/objects/peg/locate", json={"camera": camera, "pixels": pixels}))
        assert state(up) == before


# ------------------------------------------------------------------ the control lock

class Events:
    """The /api/events WebSocket read on a thread: every message as text and decoded."""

    def __init__(self, up: RunningConsole) -> None:
        self.ws = connect(up.url.replace("http", "ws") + "/api/events", max_size=None)
        self.texts: list[str] = []
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self) -> None:
        try:
            for text in self.ws:
                self.texts.append(text)
        except Exception:  # noqa: BLE001 - closed at the end of the test
            pass

    def of_type(self, kind: str) -> list[dict]:
        return [m for m in map(json.loads, list(self.texts)) if m.get("type") == kind]

    def close(self) -> None:
        self.ws.close()


def _as(name: str, token: str | None = None) -> dict[str, str]:
    return {"X-Teleprog-Client": name, **({"X-Teleprog-Token": token} if token else {})}


@pytest.fixture
def nobody_holds(up: RunningConsole) -> Iterator[None]:
    yield
    grant = ok(up.api("POST", "/api/control/takeover", headers=_as("cleanup")))
    ok(up.api("POST", "/api/control/release", headers=_as("cleanup", grant["token"])))


def test_control_needs_the_token_the_holder_alone_was_given(up: RunningConsole, nobody_holds: None) -> None:
    events = Events(up)
    try:
        grant = ok(up.api("POST", "/api/control/request", headers=_as("alice")))
        token = grant["token"]
        assert grant["holder"] == "alice" and len(token) >= 16
        wait_for(lambda: events.of_type("control"), 10, 0.05, "a control event")
        # others see the label, never the token
        assert ok(up.api("GET", "/api/control"))["holder"] == "alice"
        for path in ("/api/control", "/api/session"):
            assert token not in up.api("GET", path).text
        assert not any(token in text for text in events.texts)
        # the name alone proves nothing; the token does
        jog = {"joint": 1, "delta_deg": 1.0}
        for who in (_as("alice"), _as("bob"), {}):
            refused = up.api("POST", "/api/jog/joint", json=jog, headers=who)
            assert refused.status_code == 409 and "alice" in assert_clear_refusal(refused)["detail"]
        ok(up.api("POST", "/api/jog/joint", json=jog, headers=_as("alice", token)))
        # asking again with the token gives the same grant; without it, a refusal, not the token
        assert ok(up.api("POST", "/api/control/request", headers=_as("alice", token)))["token"] == token
        again = up.api("POST", "/api/control/request", headers=_as("alice"))
        assert again.status_code == 409 and token not in again.text
        # release needs the token too
        for who in (_as("bob"), _as("alice"), _as("bob", "guessed-token-0123456789")):
            assert up.api("POST", "/api/control/release", headers=who).status_code == 409
        assert ok(up.api("GET", "/api/control"))["holder"] == "alice"
        assert ok(up.api("POST", "/api/control/release", headers=_as("alice", token)))["holder"] is None
        ok(up.api("POST", "/api/jog/joint", json={"joint": 1, "delta_deg": -1.0}, headers=_as("bob")))  # nobody holds: open
        # STOP stays open to anybody while someone holds control
        ok(up.api("POST", "/api/control/request", headers=_as("carol")))
        ok(up.api("POST", "/api/robot/stop", headers=_as("bob")))
    finally:
        events.close()


def test_a_takeover_is_explicit_logged_and_seen_by_the_former_holder(up: RunningConsole, nobody_holds: None) -> None:
    alice = ok(up.api("POST", "/api/control/request", headers=_as("alice")))["token"]
    events = Events(up)
    try:
        wait_for(lambda: events.texts, 10, 0.05, "the events snapshot")
        grant = ok(up.api("POST", "/api/control/takeover", headers=_as("bob")))
        assert grant["holder"] == "bob" and grant["token"] != alice
        # alice's token no longer works, and the refusal says why
        refused = up.api("POST", "/api/jog/joint", json={"joint": 1, "delta_deg": 1.0}, headers=_as("alice", alice))
        assert refused.status_code == 409 and "took over" in assert_clear_refusal(refused)["detail"]
        # alice sees who took over when: in the control view and on the events stream
        view = ok(up.api("GET", "/api/control"))
        assert view["holder"] == "bob" and view["last_takeover"]["by"] == "bob" and view["last_takeover"]["former"] == "alice"
        changed = wait_for(lambda: [m for m in events.of_type("control") if m["control"]["last_takeover"]], 10, 0.05, "a take-over event")
        assert changed[-1]["control"]["holder"] == "bob"
        wait_for(lambda: [m for m in events.of_type("notice") if "taken over" in m["message"]], 10, 0.05, "a take-over notice")
        assert grant["token"] not in "".join(events.texts)
        wait_for(lambda: "taken over by 'bob' from 'alice'" in up.log_path.read_text(), 10, 0.1, "the take-over in the log")
    finally:
        events.close()


def test_the_lock_is_checked_before_any_work(up: RunningConsole, program: None, nobody_holds: None) -> None:
    ok(up.api("POST", "/api/control/request", headers=_as("alice")))
    camera = ok(up.api("GET", "/api/cameras"))[0]["name"]
    before = state(up)
    # degenerate pixels and an unparsable statement from a non-holder: the lock answers, not the solver or parser
    refused = up.api("POST", "/api/objects/peg/locate", json={"camera": camera, "pixels": [[1, 1]] * 4}, headers=_as("bob"))
    assert refused.status_code == 409 and "alice" in refused.json()["detail"]
    refused = up.api("POST", "/api/program/insert", json={"text": "DRIVE J9 TO banana"}, headers=_as("bob"))
    assert refused.status_code == 409 and "alice" in refused.json()["detail"]
    assert state(up) == before


# ------------------------------------------------------------------ fuzzed statement bodies

TEMPLATES = [
    {"kind": "DRIVE", "joint": 1, "target": 0.2},
    {"kind": "DRAW", "position": [0.6, 0.0, 0.3], "speed": {"value": 0.2, "unit": "fraction"}},
    {"kind": "MOVES", "position": [0.6, 0.0, 0.3], "rpy": [3.14, 0.0, 0.0], "until": {"kind": "force", "newtons": 5.0}},
    {"kind": "SPEED", "speed": {"value": 0.5, "unit": "fraction"}},
    {"kind": "DRAW", "position": [0.6, 0.0, 0.3], "until": {"kind": "time", "seconds": 2.0}},
]
NON_FINITE = ["NaN", "Infinity", "-Infinity", "1e400", "-1e999", '"NaN"', '"inf"', '"-Infinity"']
HUGE = ["1e308", "-1e308", "1.7976931348623157e308", "123456789012345678901234567890", "5e-324"]


def _leaves(value, path=()):
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _leaves(v, (*path, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _leaves(v, (*path, i))
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        yield path


def _with_token(value, path, token: str) -> str:
    """``value`` as JSON text with the number at ``path`` written as ``token`` verbatim."""
    marker = "__HOSTILE__"
    target = value = json.loads(json.dumps(value))
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = marker
    return json.dumps(value).replace(f'"{marker}"', token)


@st.composite
def hostile_statement_bodies(draw) -> tuple[str, str, bool]:
    """(endpoint, body text, whether the body must be refused)."""
    template = draw(st.sampled_from(TEMPLATES))
    path = draw(st.sampled_from(list(_leaves(template))))
    kind = draw(st.sampled_from(["non-finite", "huge", "key twice", "garbage"]))
    endpoint = draw(st.sampled_from(["/api/program/insert", "/api/program/modify"]))
    if kind == "non-finite":
        body = '{"statement": ' + _with_token(template, path, draw(st.sampled_from(NON_FINITE))) + "}"
    elif kind == "huge":
        body = '{"statement": ' + _with_token(template, path, draw(st.sampled_from(HUGE))) + "}"
    elif kind == "key twice":
        inner = json.dumps(template)
        body = '{"statement": ' + inner[:-1] + ', "kind": "EVENT"}}'
    else:
        text = '{"statement": ' + json.dumps(template) + "}"
        cut = draw(st.integers(1, len(text) - 1))
        body = text[:cut] + draw(st.sampled_from(["", "}", "]]", "\x00", ",,", "\ud800"]))
    return endpoint, body, kind != "huge"


@settings(max_examples=25, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(case=hostile_statement_bodies())
def test_statement_endpoints_refuse_hostile_numbers_and_odd_json_without_change(up: RunningConsole, case: tuple[str, str, bool]) -> None:
    endpoint, body, must_refuse = case
    ok(up.api("POST", "/api/program/load", json={"text": "DRIVE J1 TO 10 deg\n", "filename": "p.tp"}))
    ok(up.api("POST", "/api/program/select", json={"index": 0 if endpoint.endswith("modify") else 1}))
    before = state(up)
    response = raw(up, "POST", endpoint, body.encode("utf-8", "surrogatepass"))
    assert response.status_code < 500, f"{endpoint} {body}: {response.status_code} {response.text[:300]}"
    if must_refuse or response.status_code != 200:
        assert_clear_refusal(response)
        assert state(up) == before, f"{endpoint} {body}: refused but changed the session"
    else:  # a huge but finite number the statement's model took: the console still shows its program
        assert ok(up.api("GET", "/api/program"))["entries"]
