"""The control lock: one client at a time changes the session; everybody else observes.

A client takes the lock with a name (``X-Teleprog-Client``) and gets a token; while it holds the
lock only calls presenting that token change anything (STOP excepted: anybody may stop the
robot). An explicit take-over is logged and shown to the former holder. Views and events name the
holder by its label, never its token. A bare name or ``None`` (the page served by this console)
presents no token.
"""

from __future__ import annotations

import logging
import secrets

from server.console.context import ConsoleContext
from server.console.errors import ControlLockError
from server.console.events import ControlChanged, Notice, SessionEvent
from server.console.views import Caller, ControlGrant, ControlTakeover, ControlView
from shared.errors import InputError

log = logging.getLogger(__name__)


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

    def view(self) -> ControlView:
        """Who holds control, as everybody may see it: the holder's label, never its token."""
        with self._ctx.lock:
            return ControlView(holder=self._holder, since=self._since, last_takeover=self._takeover)

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
        log.info("control released by %r", former)
        view = self.view()
        self._ctx.bus.emit([ControlChanged(control=view)])
        return view

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
        return ControlGrant(holder=self._holder, since=self._since, last_takeover=self._takeover, token=self._token)

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
