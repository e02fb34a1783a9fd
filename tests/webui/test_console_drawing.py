"""The console draws the arm only while a page is connected, and catches up when one connects."""

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
        session.arm.jog_tool(frame="world", constraint="x", motion="translate", displacement=np.array([0.02, 0.0, 0.0]))
        assert np.allclose(tool_link.position, first), "no page: the links are not placed"
        console.on_page_connect()  # what viser calls when a page connects
        assert not np.allclose(tool_link.position, first), "the page sees the jogged arm"
        assert console.drive.sliders[0].value == round(float(np.degrees(session.arm.state.q[0])), 1)
    finally:
        session.close()
        server.stop()
