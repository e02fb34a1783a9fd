"""The console draws the arm and its collision line only while a page is connected, and catches up
when one connects."""

from __future__ import annotations

import numpy as np
import viser

from server.console import Session
from shared.cells.loader import DEFAULT_CELL, load_cell
from support import free_port
from webui.console import build_console


def test_jogs_without_a_page_are_drawn_when_a_page_connects() -> None:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    session = Session(load_cell(DEFAULT_CELL))
    try:
        console = build_console(server, session)
        tool_link = console.scene._links[-1]
        first = np.array(tool_link.position)
        line = console.drive.collision.content
        session.arm.jog_tool(frame="world", constraint="x", motion="translate", displacement=np.array([0.02, 0.0, 0.0]))
        assert np.allclose(tool_link.position, first), "no page: the links are not placed"
        assert console.drive.collision.content == line, "no page: the collision line is not rewritten"
        console.on_page_connect()  # what viser calls when a page connects
        assert not np.allclose(tool_link.position, first), "the page sees the jogged arm"
        view = session.arm.collision_view()
        assert f"at {view.min_distance * 1e3:.1f} mm" in console.drive.collision.content
        assert console.drive.collision.content != line, "the page sees the collision line of the jogged arm"
        assert console.drive.sliders[0].value == round(float(np.degrees(session.arm.state.q[0])), 1)
    finally:
        session.close()
        server.stop()
