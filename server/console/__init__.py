"""The console's session in parts (see ``README.md`` here for the map): ``Session`` and its
typed views, events, enums and errors."""

from server.console import events as _events
from server.console import views as _views
from server.console.context import SessionSettings
from server.console.enums import FINAL_SENT, DisplayMode, Regime, SentStatus
from server.console.errors import (
    ConflictError,
    ControlLockError,
    NotConnectedError,
    RefusedByRule,
)
from server.console.events import *  # noqa: F403 - the event types are the package's vocabulary
from server.console.session import CellOffers, Session
from server.console.views import *  # noqa: F403 - the view types are the package's vocabulary

__all__ = [
    "CellOffers", "ConflictError", "ControlLockError", "DisplayMode", "FINAL_SENT", "NotConnectedError",
    "RefusedByRule", "Regime", "SentStatus", "Session", "SessionSettings", *_events.__all__, *_views.__all__,
]
