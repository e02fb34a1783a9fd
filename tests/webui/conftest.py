"""The console's scene and panels built in this process on a real viser server, one per module."""

from __future__ import annotations

import pytest
import viser

from server.console import Session
from shared.cells.loader import DEFAULT_CELL, load_cell
from support import free_port
from webui.console import build_console


@pytest.fixture(scope="module")
def built_console():
    """``(session, console)``: a session on the default cell and the page built for it."""
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    session = Session(load_cell(DEFAULT_CELL))
    try:
        yield session, build_console(server, session)
    finally:
        session.close()
        server.stop()
