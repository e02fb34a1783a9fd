"""Hand-over of control (issue 41): another client asks, the holder hands over or refuses, and a
holder who says nothing for the hand-over timeout loses control to the asker. Every change is a
control event and a notice. The lock on its own in virtual time, then through the API."""

from __future__ import annotations

import logging
import threading
from types import SimpleNamespace

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.console.control import ControlLock
from server.console.errors import ControlLockError
from server.console.events import ControlChanged, Notice
from server.console.views import Caller, ControlAsk, ControlAskGrant, ControlGrant, ControlTakeover
from server.settings import ConsoleSettings
from shared.errors import InputError

TIMEOUT_S = 30.0


class _Bus:
    def __init__(self) -> None:
        self.emitted: list[list] = []

    def emit(self, events) -> None:
        self.emitted.append(list(events))


class _Time:
    """Virtual time: the monotonic clock and Unix time move together, only when told."""

    def __init__(self) -> None:
        self.now = 100.0

    def monotonic(self) -> float:
        return self.now

    def unix(self) -> float:
        return 1_000_000.0 + self.now


@pytest.fixture
def time_() -> _Time:
    return _Time()


@pytest.fixture
def lock(time_: _Time) -> ControlLock:
    ctx = SimpleNamespace(lock=threading.RLock(), bus=_Bus(), clock=time_.monotonic, wall_clock=time_.unix,
                          settings=SimpleNamespace(handover_timeout_s=TIMEOUT_S))
    return ControlLock(ctx)


def _events(lock: ControlLock) -> list[list]:
    return lock._ctx.bus.emitted


def _notices(lock: ControlLock) -> list[str]:
    return [e.message for batch in _events(lock) for e in batch if isinstance(e, Notice)]


def test_asking_while_nobody_holds_control_takes_it_at_once(lock):
    answer = lock.ask("bob")
    assert answer.holder == "bob" and answer.asked is None
    lock.check(Caller("bob", answer.token))
    with pytest.raises(ControlLockError):
        lock.check(Caller("carol", None))


def test_a_request_is_shown_and_changes_nothing_until_the_holder_answers(lock, time_, caplog):
    caplog.set_level(logging.INFO, logger="server.console.control")
    alice = lock.request("alice")
    answer = lock.ask("bob")
    asked = ControlAsk(by="bob", at=time_.unix(), passes_at=time_.unix() + TIMEOUT_S)
    assert answer == ControlAskGrant(holder="alice", since=alice.since, last_takeover=None, asked=asked, token=answer.token)
    assert len(answer.token) == len(alice.token) == 22 and answer.token != alice.token
    assert lock.view().asked == asked
    assert _events(lock)[-1][0] == ControlChanged(control=lock.view())
    assert _notices(lock)[-1] == ("'bob' asks 'alice' for control: hand over or refuse; "
                                  "it passes in 30 s if 'alice' says nothing")
    assert caplog.records[-1].getMessage() == "'bob' asks 'alice' for control" and caplog.records[-1].levelname == "INFO"
    # the asker's token proves nothing yet; the holder's still does, and its grant shows the request
    with pytest.raises(ControlLockError, match="held by 'alice'"):
        lock.check(Caller("bob", answer.token))
    lock.check(Caller("alice", alice.token))
    assert lock.request(Caller("alice", alice.token)) == ControlGrant(
        holder="alice", since=alice.since, last_takeover=None, asked=asked, token=alice.token)
    # asking again with the token repeats the answer; another asker waits its turn
    assert lock.ask(Caller("bob", answer.token)) == answer
    with pytest.raises(ControlLockError) as err:
        lock.ask("carol")
    assert str(err.value) == ("'bob' already asked 'alice' for control; ask once that request is answered, "
                              "or take over explicitly with POST /api/control/takeover")
    with pytest.raises(InputError) as err:
        lock.ask(Caller(None, None))
    assert str(err.value) == "a client name is needed to ask for control (header X-Teleprog-Client)"


def test_a_request_after_a_takeover_shows_the_takeover(lock, time_):
    lock.request("alice")
    carol = lock.takeover("carol")
    answer = lock.ask("bob")
    assert answer.last_takeover == ControlTakeover(by="carol", former="alice", at=carol.since)
    assert answer.since == carol.since and answer.holder == "carol"


def test_the_holder_hands_over_and_the_roles_swap(lock, caplog):
    caplog.set_level(logging.INFO, logger="server.console.control")
    alice = lock.request("alice")
    answer = lock.ask("bob")
    view = lock.hand_over(Caller("alice", alice.token))
    assert (view.holder, view.asked) == ("bob", None)
    lock.check(Caller("bob", answer.token))
    with pytest.raises(ControlLockError, match="not its token"):
        lock.check(Caller("alice", alice.token))
    assert _events(lock)[-1] == [ControlChanged(control=lock.view()),
                                 Notice(level="warning", message="control handed over by 'alice' to 'bob'")]
    assert caplog.records[-1].getMessage() == "control handed over by 'alice' to 'bob'"


def test_only_the_holder_answers_and_only_a_request(lock):
    alice = lock.request("alice")
    for answer, what in ((lock.hand_over, "hand over control"), (lock.refuse, "refuse the request for control")):
        with pytest.raises(ControlLockError) as err:
            answer(Caller("alice", alice.token))
        assert str(err.value) == f"nobody asked for control: cannot {what}"
    asked = lock.ask("bob")
    for answer, what in ((lock.hand_over, "hand over control"), (lock.refuse, "refuse the request for control")):
        with pytest.raises(ControlLockError) as err:
            answer(Caller("bob", asked.token))
        assert str(err.value) == f"control is held by 'alice' and the token 'bob' presented is not its token: cannot {what}"
        with pytest.raises(ControlLockError) as err:
            answer(None)
        assert str(err.value) == (f"control is held by 'alice': this page can only observe (to {what}, "
                                  "present the holder's token in the X-Teleprog-Token header)")
    assert lock.view().holder == "alice" and lock.view().asked is not None


def test_a_refusal_keeps_control_and_the_askers_token_never_works(lock, time_, caplog):
    caplog.set_level(logging.INFO, logger="server.console.control")
    alice = lock.request("alice")
    answer = lock.ask("bob")
    view = lock.refuse(Caller("alice", alice.token))
    assert (view.holder, view.asked) == ("alice", None)
    assert _events(lock)[-1][0] == ControlChanged(control=lock.view())
    assert _notices(lock)[-1] == "'alice' keeps control: 'bob''s request refused"
    assert caplog.records[-1].getMessage() == "'alice' refused 'bob''s request for control"
    time_.now += 10 * TIMEOUT_S
    lock.tick()  # nothing pending: nothing passes
    assert lock.view().holder == "alice"
    with pytest.raises(ControlLockError):
        lock.check(Caller("bob", answer.token))
    # bob may ask again, and gets a fresh token
    again = lock.ask("bob")
    assert again.token != answer.token


def test_a_silent_holder_loses_control_to_the_asker_after_the_timeout(lock, time_):
    alice = lock.request("alice")
    answer = lock.ask("bob")
    time_.now += TIMEOUT_S - 0.01
    lock.tick()
    assert lock.view().holder == "alice"
    time_.now += 0.01
    lock.tick()
    view = lock.view()
    assert (view.holder, view.asked, view.since) == ("bob", None, time_.unix())
    lock.check(Caller("bob", answer.token))
    with pytest.raises(ControlLockError):
        lock.check(Caller("alice", alice.token))
    assert _notices(lock)[-1] == "'alice' did not answer 'bob''s request for control within 30 s: control passed to 'bob'"
    batches = len(_events(lock))
    lock.tick()  # passed once
    assert len(_events(lock)) == batches


def test_releasing_with_a_request_waiting_hands_control_to_the_asker(lock):
    alice = lock.request("alice")
    answer = lock.ask("bob")
    view = lock.release(Caller("alice", alice.token))
    assert view.holder == "bob"
    lock.check(Caller("bob", answer.token))
    assert _notices(lock)[-1] == "control released by 'alice': handed to 'bob', who asked"


def test_a_takeover_ends_a_waiting_request(lock, time_):
    lock.request("alice")
    answer = lock.ask("bob")
    carol = lock.takeover("carol")
    assert (lock.view().holder, lock.view().asked) == ("carol", None)
    assert _notices(lock)[-2:] == ["control taken over by 'carol' from 'alice'",
                                   "'bob''s request for control ended: 'carol' took over"]
    time_.now += 2 * TIMEOUT_S
    lock.tick()
    assert lock.view().holder == "carol"
    lock.check(Caller("carol", carol.token))
    with pytest.raises(ControlLockError):
        lock.check(Caller("bob", answer.token))


def test_the_hand_over_through_the_api():
    settings = ConsoleSettings(no_robot=True, record=False, handover_timeout_s=0.2)
    with TestClient(create_app(settings, build_page=False)) as client:
        alice = client.post("/api/control/request", headers={"X-Teleprog-Client": "alice"}).json()
        asked = client.post("/api/control/ask", headers={"X-Teleprog-Client": "bob"})
        assert asked.status_code == 200 and asked.json()["asked"]["by"] == "bob"
        bob = asked.json()["token"]
        refused = client.post("/api/control/handover", headers={"X-Teleprog-Client": "bob", "X-Teleprog-Token": bob})
        assert refused.status_code == 409
        # an observer changes nothing while alice holds control
        assert client.put("/api/regime", json={"regime": "free"}, headers={"X-Teleprog-Client": "bob"}).status_code == 409
        ok = client.post("/api/control/handover", headers={"X-Teleprog-Client": "alice", "X-Teleprog-Token": alice["token"]})
        assert ok.status_code == 200 and ok.json()["holder"] == "bob"
        assert client.put("/api/regime", json={"regime": "free"},
                          headers={"X-Teleprog-Client": "bob", "X-Teleprog-Token": bob}).status_code == 200
        # alice asks back; bob says nothing; the session's clock passes control after 0.2 s
        back = client.post("/api/control/ask", headers={"X-Teleprog-Client": "alice"}).json()
        assert back["holder"] == "bob" and back["asked"]["by"] == "alice"
        deadline = threading.Event()
        for _ in range(100):
            if client.get("/api/control").json()["holder"] == "alice":
                break
            deadline.wait(0.05)
        assert client.get("/api/control").json() | {"since": None} == {
            "holder": "alice", "since": None, "last_takeover": None, "asked": None}
        assert client.put("/api/regime", json={"regime": None},
                          headers={"X-Teleprog-Client": "alice", "X-Teleprog-Token": back["token"]}).status_code == 200
