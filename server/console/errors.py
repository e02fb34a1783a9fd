"""The console's refusals: what the HTTP API answers with 409 (the action is well-formed but
the session's state does not allow it now). Malformed input is ``shared.errors.InputError``."""

from __future__ import annotations

from shared.errors import TeleprogError
from shared.program.rules import Refusal


class ConflictError(TeleprogError):
    """The action is well-formed but the session's state does not allow it now (HTTP 409):
    another client holds control, a preview is running, the regime forbids it, ..."""


class RefusedByRule(ConflictError):
    """An editor operation refused by a rule of thesis §4.3.6 (HTTP 409); ``refusal`` names it."""

    def __init__(self, refusal: Refusal) -> None:
        self.refusal = refusal
        super().__init__(str(refusal))


class NotConnectedError(ConflictError):
    """An action that needs the robot, while the console has no robot configured (HTTP 409)."""


class ControlLockError(ConflictError):
    """Another client holds the control lock, or the token presented is not the holder's (HTTP 409)."""


class ConsoleLineAdded(ConflictError):
    """A submission the regime needs a line for (a MODE statement): the console put the line into
    the program, where the operator sees it, and refused; submitting again sends it (HTTP 409)."""
