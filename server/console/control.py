"""The control lock: one client at a time changes the session; everybody else observes.

A client takes the lock with a name (``X-Teleprog-Client``) and gets a token; while it holds the
lock only calls presenting that token change anything (STOP excepted: anybody may stop the
robot). An explicit take-over is logged and shown to the former holder. Views and events name the
holder by its label, never its token. A bare name or ``None`` (the page served by this console)
presents no token.

Hand-over (a team at one console): another client asks for control and gets the token it will
hold; the holder hands over or refuses, and if it says nothing for ``handover_timeout_s`` control
passes to the asker (a holder who walked away must not keep the robot from its team). Every
change, asked, handed over, refused, passed on silence, is a control event and a notice on every
page, and so in the recording.
"""

from __future__ import annotations

import logging
import secrets
from dataclasses import dataclass

from server.console.context import ConsoleContext
from server.console.errors import ControlLockError
from server.console.events import ControlChanged, Notice, SessionEvent
from server.console.views import Caller, ControlAsk, ControlAskGrant, ControlGrant, ControlTakeover, ControlView
from shared.errors import InputError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class _Request:
    """A request for control: what everybody sees, the token the asker will hold, and when
    (``ctx.clock()`` s) control passes if the holder says nothing."""

    ask: ControlAsk
    token: str
    deadline: float


def as_caller(client: Caller | str | None) -> Caller:
    """A ``Caller`` from what the session's methods accept as ``client``."""
    if isinstance(client, Caller):
        return client
    return Caller(name=client or None)


class ControlLock:
    """Who holds control, and the check every changing call makes."""

    def __init__(self, ctx: ConsoleContext) -> None:
        self._ctx = ctx
        self._holder: str | None = None
        self._since: float | None = None
        self._token: str | None = None
        self._takeover: ControlTakeover | None = None
        self._pending: _Request | None = None  # a request for control waiting on the holder

    def view(self) -> ControlView:
        """Who holds control, as everybody may see it: the holder's label, never its token."""
        with self._ctx.lock:
            return ControlView(holder=self._holder, since=self._since, last_takeover=self._takeover, asked=self._asked())

    @property
    def holder(self) -> Caller:
        """The holder as a caller (for what the session does on its behalf, e.g. streaming)."""
        with self._ctx.lock:
            return Caller(self._holder, self._token)

    def request(self, client: Caller | str) -> ControlGrant:
        """Take the lock for the caller (a non-empty name); the grant holds the token later calls
        present. Refused while another holds it; asking again with the token gives the same grant."""
        caller = as_caller(client)
        if not caller.name:
            raise InputError("a client name is needed to take control (header X-Teleprog-Client)")
        with self._ctx.lock:
            if self._holder is not None:
                if self._presents_token(caller):
                    return self._grant()
                raise ControlLockError(
                    f"control is held by {self._holder!r}; ask it to release control, or take over "
                    "explicitly with POST /api/control/takeover"
                )
            self._give(caller.name)
            grant = self._grant()
        log.info("control taken by %r", caller.name)
        self._ctx.bus.emit([ControlChanged(control=self.view())])
        return grant

    def takeover(self, client: Caller | str) -> ControlGrant:
        """Take the lock whoever holds it (explicit and logged): the former holder's token stops
        working, and the control view and a notice say who took over when."""
        caller = as_caller(client)
        if not caller.name:
            raise InputError("a client name is needed to take over control (header X-Teleprog-Client)")
        with self._ctx.lock:
            if self._holder is not None and self._presents_token(caller):
                return self._grant()
            former = self._holder
            voided = self._pending.ask.by if self._pending is not None else None
            self._pending = None
            self._give(caller.name)
            if former is not None:
                self._takeover = ControlTakeover(by=caller.name, former=former, at=self._since)
            grant = self._grant()
        events: list[SessionEvent] = [ControlChanged(control=self.view())]
        if former is not None:
            log.warning("control taken over by %r from %r", caller.name, former)
            events.append(Notice(level="warning", message=f"control taken over by {caller.name!r} from {former!r}"))
        else:
            log.info("control taken by %r (nobody held it)", caller.name)
        if voided is not None and voided != caller.name:
            events.append(Notice(level="info", message=f"{voided!r}'s request for control ended: {caller.name!r} took over"))
        self._ctx.bus.emit(events)
        return grant

    def release(self, client: Caller | str | None) -> ControlView:
        """Give the lock back; it needs the holder's token. Releasing when nobody holds control
        changes nothing."""
        caller = as_caller(client)
        with self._ctx.lock:
            if self._holder is None:
                return self.view()
            if not self._presents_token(caller):
                raise ControlLockError(self._refusal(caller, "release control"))
            former = self._holder
            self._holder = self._since = self._token = None
            if self._pending is not None:  # somebody asked for it: released is handed over
                events = self._pass_to_asker(f"control released by {former!r}: handed to {self._pending.ask.by!r}, who asked")
            else:
                log.info("control released by %r", former)
                events = [ControlChanged(control=self.view())]
        self._ctx.bus.emit(events)
        return self.view()

    # -- hand-over -------------------------------------------------------------------------------
    def ask(self, client: Caller | str) -> ControlAskGrant:
        """Ask the holder for control (a non-empty name). Nobody holding it: taken at once. The
        answer's token becomes the holder's when control passes (see the module docstring).
        Refused while another client's request waits; asking again with the token repeats the answer."""
        caller = as_caller(client)
        if not caller.name:
            raise InputError("a client name is needed to ask for control (header X-Teleprog-Client)")
        with self._ctx.lock:
            free = self._holder is None
        if free:  # (request() refuses should another take it in between)
            return ControlAskGrant(**self.request(caller).model_dump())
        with self._ctx.lock:
            if self._presents_token(caller):
                return ControlAskGrant(**self._grant().model_dump())
            if self._pending is not None:
                if caller.token is not None and secrets.compare_digest(caller.token.encode(), self._pending.token.encode()):
                    return self._ask_grant()
                raise ControlLockError(
                    f"{self._pending.ask.by!r} already asked {self._holder!r} for control; ask once that request is "
                    "answered, or take over explicitly with POST /api/control/takeover")
            timeout = self._ctx.settings.handover_timeout_s
            now = self._ctx.wall_clock()
            self._pending = _Request(ControlAsk(by=caller.name, at=now, passes_at=now + timeout),
                                     token=secrets.token_urlsafe(16), deadline=self._ctx.clock() + timeout)
            holder, answer = self._holder, self._ask_grant()
        log.info("%r asks %r for control", caller.name, holder)
        self._ctx.bus.emit([
            ControlChanged(control=self.view()),
            Notice(level="warning", message=f"{caller.name!r} asks {holder!r} for control: hand over or refuse; "
                                            f"it passes in {timeout:g} s if {holder!r} says nothing"),
        ])
        return answer

    def hand_over(self, client: Caller | str | None) -> ControlView:
        """The holder consents: control passes to the client that asked."""
        with self._ctx.lock:
            self._answerable(as_caller(client), "hand over control")
            events = self._pass_to_asker(f"control handed over by {self._holder!r} to {self._pending.ask.by!r}")
        self._ctx.bus.emit(events)
        return self.view()

    def refuse(self, client: Caller | str | None) -> ControlView:
        """The holder refuses the pending request; it keeps control."""
        with self._ctx.lock:
            self._answerable(as_caller(client), "refuse the request for control")
            asker = self._pending.ask.by
            self._pending = None
            holder = self._holder
        log.info("%r refused %r's request for control", holder, asker)
        view = self.view()
        self._ctx.bus.emit([ControlChanged(control=view),
                            Notice(level="info", message=f"{holder!r} keeps control: {asker!r}'s request refused")])
        return view

    def tick(self) -> None:
        """On the session's clock: a request the holder left unanswered past its timeout passes control.
        Nothing waiting (the usual case, 30 times a second): one read, no lock."""
        pending = self._pending
        if pending is None or self._ctx.clock() < pending.deadline:
            return
        with self._ctx.lock:
            if self._pending is not pending:  # answered (or another asked) in between
                return
            holder, asker = self._holder, self._pending.ask.by
            events = self._pass_to_asker(f"{holder!r} did not answer {asker!r}'s request for control within "
                                         f"{self._ctx.settings.handover_timeout_s:g} s: control passed to {asker!r}")
        self._ctx.bus.emit(events)

    def _answerable(self, caller: Caller, what: str) -> None:
        """Only the holder answers, and only a request (a request waits only while control is held)."""
        if self._pending is None:
            raise ControlLockError(f"nobody asked for control: cannot {what}")
        if not self._presents_token(caller):
            raise ControlLockError(self._refusal(caller, what))

    def _pass_to_asker(self, why: str) -> list[SessionEvent]:
        """Give control to the asker with the token it was given (under the lock); the events to
        publish once the lock is released."""
        assert self._pending is not None
        request, self._pending = self._pending, None
        self._holder, self._since, self._token = request.ask.by, self._ctx.wall_clock(), request.token
        log.info(why)
        return [ControlChanged(control=self.view()), Notice(level="warning", message=why)]

    def _asked(self) -> ControlAsk | None:
        return self._pending.ask if self._pending is not None else None

    def _ask_grant(self) -> ControlAskGrant:
        assert self._pending is not None
        return ControlAskGrant(holder=self._holder, since=self._since, last_takeover=self._takeover,
                               asked=self._pending.ask, token=self._pending.token)

    def holds(self, client: Caller | str | None) -> bool:
        """Whether the caller holds control (presents the holder's token); nobody does while it is
        free. One read of the token, no lock: ``GET /api/link`` asks this, and must answer while a
        long computation holds the session's lock (the token is set and cleared with the holder)."""
        token, caller = self._token, as_caller(client)
        return token is not None and caller.token is not None and secrets.compare_digest(caller.token.encode(), token.encode())

    def check(self, client: Caller | str | None) -> None:
        """Refuse a call that changes state unless nobody holds control or the caller presents
        the holder's token."""
        with self._ctx.lock:
            if self._holder is None:
                return
            caller = as_caller(client)
            if not self._presents_token(caller):
                raise ControlLockError(self._refusal(caller, "change anything"))

    def _give(self, name: str) -> None:
        self._holder, self._since = name, self._ctx.wall_clock()
        self._token = secrets.token_urlsafe(16)

    def _grant(self) -> ControlGrant:
        assert self._token is not None
        return ControlGrant(holder=self._holder, since=self._since, last_takeover=self._takeover,
                            asked=self._asked(), token=self._token)

    def _presents_token(self, caller: Caller) -> bool:
        return (
            self._token is not None
            and caller.token is not None
            and secrets.compare_digest(caller.token.encode(), self._token.encode())
        )

    def _refusal(self, caller: Caller, what: str) -> str:
        who = "this page" if caller.name is None else repr(caller.name)
        if caller.token is None:
            return (f"control is held by {self._holder!r}: {who} can only observe "
                    f"(to {what}, present the holder's token in the X-Teleprog-Token header)")
        takeover = self._takeover
        since = f"; {takeover.by!r} took over from {takeover.former!r}" if takeover is not None else ""
        return f"control is held by {self._holder!r} and the token {who} presented is not its token{since}: cannot {what}"
