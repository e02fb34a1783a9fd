"""What the 3D view's colours mean, in a small block on the Drive tab (issue 16): the operator
tells the arm being driven from the robot's last report at a glance.

The swatches take their colours from the constants that draw each thing (``webui.scene``,
``webui.ghost``, ``webui.overlays``), so the legend cannot drift from the picture.
"""

from __future__ import annotations

import html

import viser

from webui.ghost import GHOST_COLOR, GHOST_OPACITY
from webui.overlays import HIT_COLOR, PATH_COLOR
from webui.scene import arm_colour

Rgb = tuple[int, int, int]


def _swatch(key: str, rgb: Rgb, label: str, opacity: float = 1.0, line: bool = False) -> str:
    r, g, b = rgb
    shape = "height:3px;margin:6px 0" if line else "height:12px"
    return (f'<div data-legend="{key}" data-rgb="{r},{g},{b}" style="display:flex;align-items:center;gap:6px">'
            f'<span style="display:inline-block;width:22px;{shape};border-radius:2px;'
            f'background:rgba({r},{g},{b},{opacity:g});border:1px solid rgba(0,0,0,.25)"></span>'
            f"<span>{html.escape(label)}</span></div>")


def legend_html(arm: Rgb, ghost: Rgb = GHOST_COLOR, path: Rgb = PATH_COLOR, hit: Rgb = HIT_COLOR) -> str:
    """The legend: virtual arm, remote arm (ghost), predicted path, collision."""
    rows = [
        _swatch("virtual", arm, "virtual arm: what you drive and the program plans"),
        _swatch("ghost", ghost, "remote arm (ghost): the robot's last report, with its age", GHOST_OPACITY),
        _swatch("path", path, "predicted path of the statements sent", line=True),
        _swatch("collision", hit, "collision: touching triangles and their label"),
    ]
    return f'<div data-legend-block style="font-size:12px;line-height:1.5">{"".join(rows)}</div>'


class Legend:
    """The legend's block, added where the caller's GUI context is (the Drive tab)."""

    def __init__(self, server: viser.ViserServer, robot) -> None:
        self.html = server.gui.add_html(legend_html(arm_colour(robot)))
