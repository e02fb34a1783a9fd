"""The regime as a coloured banner in the console's header, always in view (thesis §4.2.1,
segmented composite control): what the regime does with the operator's motion, in words, and
whether the zone chose it or the operator's override did.

* ONLINE (free zone): motions run on the robot as you drive (while automatic generation is on
  and a robot is there; the banner says when they do not);
* OFFLINE (quasi-operation): preview, then send;
* SINGLE STEP (operation): one statement with its end condition.

The banner only shows the session's views (the regime, and whether generated statements
stream, from ``SubmitReadiness.streams``); ``data-regime`` and ``data-regime-source`` carry the
same facts for tests and other readers.
"""

from __future__ import annotations

import html

import viser

from server.console import Regime, RegimeView

LOOK = {  # colour, name, what it does; distinct from the robot state's red, amber, green and grey
    Regime.FREE: ("#0b7285", "ONLINE", "free zone", "motions run on the robot as you drive"),
    Regime.QUASI: ("#364fc7", "OFFLINE", "quasi-operation", "preview, then send"),
    Regime.OPERATION: ("#a61e4d", "SINGLE STEP", "operation", "one statement with its end condition"),
}
ZONE_WORDS = {Regime.FREE: "free", Regime.QUASI: "quasi-operation", Regime.OPERATION: "operation"}


def banner_html(view: RegimeView | None, *, streams: bool = False, auto_generate: bool = False,
                robot: bool = False) -> str:
    """The banner for ``view``; ``streams``: generated statements go to the robot as they are
    made now; ``auto_generate``/``robot``: why they do not, when they do not."""
    if view is None:
        return '<div data-regime="">Regime: -</div>'
    colour, name, zone_name, does = LOOK[view.regime]
    if view.regime is Regime.FREE and not streams:
        why = "automatic generation is off" if not auto_generate else ("no robot is configured" if not robot else "")
        does = "statements go to the robot as they are" + (f"; {why}, so drags send nothing" if why else "")
    if view.override is None:
        source, source_text = "zone", f"set by the zone ({ZONE_WORDS[view.zone]})"
    else:
        source, source_text = "override", f"the operator's override (the zone is {ZONE_WORDS[view.zone]})"
    return (
        f'<div data-regime="{view.regime.value}" data-regime-source="{source}" data-streams="{str(streams).lower()}" '
        f'style="background:{colour};color:#fff;padding:4px 8px;border-radius:4px;margin:2px 0">'
        f'<b>{html.escape(name)}</b> ({html.escape(zone_name)}): {html.escape(does)}'
        f'<div style="font-size:0.85em;opacity:0.9">{html.escape(source_text)}</div></div>'
    )


class RegimeBanner:
    """One HTML element under STOP; redrawn when the regime or its streaming changes."""

    def __init__(self, server: viser.ViserServer, *, robot: bool) -> None:
        self._robot = robot
        self._view: RegimeView | None = None
        self._streams = False
        self._auto = False
        self.html = server.gui.add_html(banner_html(None))

    def show_regime(self, view: RegimeView) -> None:
        self._view = view
        self._draw()

    def show_streaming(self, streams: bool) -> None:
        self._streams = streams
        self._draw()

    def show_auto_generate(self, on: bool) -> None:
        self._auto = on
        self._draw()

    def _draw(self) -> None:
        content = banner_html(self._view, streams=self._streams, auto_generate=self._auto, robot=self._robot)
        if self.html.content != content:
            self.html.content = content
