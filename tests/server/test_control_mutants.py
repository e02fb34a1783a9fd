"""The control lock (server.console.control) on its own, stated exactly: pinned by its mutation run
(issue 38). One client at a time changes the session; only the holder's token proves anything."""

from __future__ import annotations

import logging
import threading
from types import SimpleNamespace

import pytest

from server.console.control import ControlLock, as_caller
from server.console.errors import ControlLockError
from server.console.events import ControlChanged, Notice
from server.console.views import Caller, ControlTakeover, ControlView
from shared.errors import InputError


class _Bus:
    def __init__(self) -> None:
        self.emitted: list[list] = []

    def emit(self, events) -> None:
        self.emitted.append(list(events))


class _Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        self.now += 1.0
        return self.now


@pytest.fixture
def lock() -> ControlLock:
    ctx = SimpleNamespace(lock=threading.RLock(), bus=_Bus(), wall_clock=_Clock())
    return ControlLock(ctx)


def _bus(lock: ControlLock) -> _Bus:
    return lock._ctx.bus


def test_as_caller():
    alice = Caller("alice", "tok")
    assert as_caller(alice) is alice
    assert as_caller("bob") == Caller("bob", None)
    assert as_caller(None) == Caller(None, None)
    assert as_caller("") == Caller(None, None)


def test_nobody_holds_control_at_first_and_anybody_may_change_things(lock):
    assert lock.view() == ControlView(holder=None, since=None, last_takeover=None)
    assert lock.holder == Caller(None, None)
    assert lock.holds(None) is False
    assert lock.holds(Caller("alice", "anything")) is False
    lock.check(None)
    lock.check(Caller("alice", "anything"))
    assert _bus(lock).emitted == []


def test_a_request_needs_a_name(lock):
    for nameless in (None, "", Caller(None, "t")):
        with pytest.raises(InputError) as err:
            lock.request(nameless)
        assert str(err.value) == "a client name is needed to take control (header X-Teleprog-Client)"
    assert lock.view().holder is None


def test_a_request_gives_the_lock_and_a_token_that_alone_proves_holding(lock, caplog):
    caplog.set_level(logging.INFO, logger="server.console.control")
    grant = lock.request("alice")
    assert (grant.holder, grant.since, grant.last_takeover) == ("alice", 1001.0, None)
    assert len(grant.token) == 22  # 128 random bits as URL-safe text
    view = lock.view()
    assert view == ControlView(holder="alice", since=1001.0, last_takeover=None)
    assert "token" not in view.model_dump()
    assert _bus(lock).emitted == [[ControlChanged(control=view)]]
    assert lock.holder == Caller("alice", grant.token)
    assert lock.holds(Caller("alice", grant.token)) is True
    assert lock.holds(Caller("anyone", grant.token)) is True  # the token proves, the name is a label
    assert lock.holds("alice") is False
    assert lock.holds(Caller("alice", grant.token + "x")) is False
    assert [r.getMessage() for r in caplog.records] == ["control taken by 'alice'"]


def test_asking_again_with_the_token_gives_the_same_grant(lock):
    grant = lock.request("alice")
    again = lock.request(Caller("alice", grant.token))
    assert again == grant
    assert len(_bus(lock).emitted) == 1  # nothing changed, nothing published


def test_a_request_while_another_holds_is_refused(lock):
    grant = lock.request("alice")
    for other in ("bob", Caller("bob", "not-the-token"), Caller("alice", None)):
        with pytest.raises(ControlLockError) as err:
            lock.request(other)
        assert str(err.value) == ("control is held by 'alice'; ask it to release control, or take over "
                                  "explicitly with POST /api/control/takeover")
    assert lock.view().holder == "alice"
    assert lock.holds(Caller("alice", grant.token)) is True


def test_check_refuses_a_caller_without_the_holders_token_and_says_why(lock):
    grant = lock.request("alice")
    lock.check(Caller("alice", grant.token))
    with pytest.raises(ControlLockError) as err:
        lock.check(None)
    assert str(err.value) == ("control is held by 'alice': this page can only observe "
                              "(to change anything, present the holder's token in the X-Teleprog-Token header)")
    with pytest.raises(ControlLockError) as err:
        lock.check("bob")
    assert str(err.value) == ("control is held by 'alice': 'bob' can only observe "
                              "(to change anything, present the holder's token in the X-Teleprog-Token header)")
    with pytest.raises(ControlLockError) as err:
        lock.check(Caller("bob", "forged"))
    assert str(err.value) == ("control is held by 'alice' and the token 'bob' presented is not its token: "
                              "cannot change anything")


def test_release_needs_the_token_and_frees_the_lock(lock, caplog):
    caplog.set_level(logging.INFO, logger="server.console.control")
    grant = lock.request("alice")
    with pytest.raises(ControlLockError) as err:
        lock.release("alice")
    assert str(err.value) == ("control is held by 'alice': 'alice' can only observe "
                              "(to release control, present the holder's token in the X-Teleprog-Token header)")
    with pytest.raises(ControlLockError) as err:
        lock.release(Caller(None, "forged"))
    assert str(err.value) == ("control is held by 'alice' and the token this page presented is not its token: "
                              "cannot release control")
    assert lock.view().holder == "alice"
    view = lock.release(Caller("alice", grant.token))
    assert view == ControlView(holder=None, since=None, last_takeover=None)
    assert lock.view() == view
    assert lock.holder == Caller(None, None)
    assert _bus(lock).emitted[-1] == [ControlChanged(control=view)]
    assert lock.holds(Caller("alice", grant.token)) is False  # the old token holds nothing
    lock.check(None)
    assert caplog.records[-1].getMessage() == "control released by 'alice'"
    # a new request gets a new token
    assert lock.request("bob").token != grant.token


def test_release_when_nobody_holds_changes_nothing(lock):
    assert lock.release(None) == ControlView()
    assert lock.release(Caller("x", "y")) == ControlView()
    assert _bus(lock).emitted == []


def test_a_takeover_needs_a_name(lock):
    with pytest.raises(InputError) as err:
        lock.takeover(None)
    assert str(err.value) == "a client name is needed to take over control (header X-Teleprog-Client)"
    with pytest.raises(InputError):
        lock.takeover(Caller("", "t"))


def test_a_takeover_of_a_free_lock_is_a_plain_take(lock, caplog):
    caplog.set_level(logging.INFO, logger="server.console.control")
    grant = lock.takeover("carol")
    assert (grant.holder, grant.since, grant.last_takeover) == ("carol", 1001.0, None)
    assert _bus(lock).emitted == [[ControlChanged(control=lock.view())]]
    assert [r.getMessage() for r in caplog.records] == ["control taken by 'carol' (nobody held it)"]
    assert [r.levelname for r in caplog.records] == ["INFO"]


def test_a_takeover_is_shown_to_the_former_holder_whose_token_stops_working(lock, caplog):
    caplog.set_level(logging.INFO, logger="server.console.control")
    alice = lock.request("alice")
    grant = lock.takeover("bob")
    takeover = ControlTakeover(by="bob", former="alice", at=1002.0)
    assert (grant.holder, grant.since, grant.last_takeover) == ("bob", 1002.0, takeover)
    assert grant.token != alice.token
    assert lock.view() == ControlView(holder="bob", since=1002.0, last_takeover=takeover)
    assert _bus(lock).emitted[-1] == [
        ControlChanged(control=lock.view()),
        Notice(level="warning", message="control taken over by 'bob' from 'alice'"),
    ]
    assert caplog.records[-1].getMessage() == "control taken over by 'bob' from 'alice'"
    assert caplog.records[-1].levelname == "WARNING"
    with pytest.raises(ControlLockError) as err:
        lock.check(Caller("alice", alice.token))
    assert str(err.value) == ("control is held by 'bob' and the token 'alice' presented is not its token; "
                              "'bob' took over from 'alice': cannot change anything")
    lock.check(Caller("bob", grant.token))


def test_a_takeover_by_the_holder_with_its_token_changes_nothing(lock):
    grant = lock.request("alice")
    assert lock.takeover(Caller("alice", grant.token)) == grant
    assert len(_bus(lock).emitted) == 1
    # without its token, the holder's own name takes over like anybody's
    again = lock.takeover("alice")
    assert again.token != grant.token
    assert again.last_takeover == ControlTakeover(by="alice", former="alice", at=1002.0)


def test_the_takeover_stays_shown_after_release(lock):
    lock.request("alice")
    bob = lock.takeover("bob")
    view = lock.release(Caller("bob", bob.token))
    assert view.holder is None
    assert view.last_takeover == ControlTakeover(by="bob", former="alice", at=1002.0)
