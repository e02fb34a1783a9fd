"""The Drive tab's "Nearest" line names what the tool is about to meet: an object or the ground,
never the arm's own links (issue 37: the rover cell showed "link1 / link3", a self-distance)."""

from __future__ import annotations

import re

import viser

from server.console import Session
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision import SceneModel
from shared.paths import ASSETS_DIR
from support import free_port
from webui.console import build_console

ROVER_TERRAIN = ASSETS_DIR / "cells" / "rover_terrain.toml"
EMPTY = ASSETS_DIR / "cells" / "puma562_empty.toml"


def _drive_line(cell, scene=None) -> tuple[str, object]:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    session = Session(cell, scene=scene) if scene is not None else Session(cell)
    try:
        console = build_console(server, session)
        console.on_page_connect()  # draw as for a page
        console.drive.show_collision(session.arm.collision_view())
        return console.drive.collision.content, session.arm.collision_view()
    finally:
        session.close()
        server.stop()


def test_the_rover_names_the_ground() -> None:
    cell = load_cell(ROVER_TERRAIN)
    text, view = _drive_line(cell, SceneModel.from_cell(cell, leaf_size=8, exclude=("terrain",)))
    m = re.search(r"Nearest: (\S+) at ([\d.]+) mm", text)
    assert m, text
    assert m.group(1) == "terrain" and "link" not in m.group(0)
    assert float(m.group(2)) == round(view.min_distance * 1e3, 1)
    assert view.nearest == ("link3", "terrain")


def test_the_peg_cell_names_the_peg_and_an_empty_cell_names_nothing() -> None:
    text, view = _drive_line(load_cell(DEFAULT_CELL))
    assert re.search(r"Nearest: peg at [\d.]+ mm", text), text
    text, view = _drive_line(load_cell(EMPTY))
    assert "Nearest" not in text and view.nearest is None and view.min_distance is None
