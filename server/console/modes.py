"""The regime (segmented composite control, thesis §4.2.1) and the display mode (§4.3.7).

The regime follows the control zone of the virtual arm (free, quasi-operation, operation: set by
the tool's distance to the objects) unless the operator overrides it; it decides how statements
reach the robot (``server.console.dispatch``). The display mode says what the 3D view shows:
the operator's arm, a task preview, or the remote scene rebuilt from telemetry.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from server.console.context import ConsoleContext
from server.console.enums import DisplayMode, Regime
from server.console.errors import ConflictError
from server.console.events import DisplayModeChanged, RegimeChanged, SessionEvent
from server.console.views import Caller, RegimeView

if TYPE_CHECKING:
    from server.console.control import ControlLock


class Modes:
    """Regime (zone and override) and display mode."""

    def __init__(self, ctx: ConsoleContext, control: ControlLock) -> None:
        self._ctx = ctx
        self._control = control
        self._zone = Regime.FREE
        self._override: Regime | None = None
        self._display = DisplayMode.TELEPROGRAMMING
        self._display_before_preview = DisplayMode.TELEPROGRAMMING
        self._previewing = False

    # -- regime ------------------------------------------------------------------------------
    @property
    def regime(self) -> Regime:
        with self._ctx.lock:
            return self._override or self._zone

    def regime_view(self) -> RegimeView:
        with self._ctx.lock:
            return RegimeView(regime=self._override or self._zone, zone=self._zone, override=self._override)

    def set_zone(self, zone: Regime) -> list[SessionEvent]:
        """The virtual arm's zone now (under the lock); the event when it changed."""
        zone = Regime(zone)
        if zone == self._zone:
            return []
        self._zone = zone
        return [RegimeChanged(regime=self.regime_view())]

    def set_regime_override(self, regime: Regime | None, *, client: Caller | str | None = None) -> RegimeView:
        """Force a regime (``None``: follow the zone again)."""
        with self._ctx.lock:
            self._control.check(client)
            self._override = None if regime is None else Regime(regime)
            view = self.regime_view()
        self._ctx.bus.emit([RegimeChanged(regime=view)])
        return view

    # -- display -----------------------------------------------------------------------------
    @property
    def display(self) -> DisplayMode:
        with self._ctx.lock:
            return self._display

    def set_display_mode(self, mode: DisplayMode, *, client: Caller | str | None = None) -> DisplayMode:
        with self._ctx.lock:
            self._control.check(client)
            mode = DisplayMode(mode)
            if self._previewing and mode is not DisplayMode.TASK_PREVIEW:
                raise ConflictError("a preview is running: end it to leave the task preview display")
            self._display = mode
        self._ctx.bus.emit([DisplayModeChanged(display=mode)])
        return mode

    def enter_preview(self) -> DisplayModeChanged:
        """A preview began (under the lock): show it, remembering what was shown."""
        self._previewing = True
        self._display_before_preview = self._display
        self._display = DisplayMode.TASK_PREVIEW
        return DisplayModeChanged(display=self._display)

    def leave_preview(self) -> DisplayModeChanged:
        """The preview ended (under the lock): show what was shown before it."""
        self._previewing = False
        self._display = self._display_before_preview
        return DisplayModeChanged(display=self._display)
