"""The Drive tab shows the statements the drags write (issue 37, smaller point): without leaving
the tab, the operator sees each drag become a statement."""

from __future__ import annotations

import viser

from server.console import Session
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.language.parser import parse_program
from support import free_port
from webui.console import build_console
from webui.panels import written_markdown


def test_the_drive_tab_shows_the_last_statements_written() -> None:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    session = Session(load_cell(DEFAULT_CELL))
    try:
        drive = build_console(server, session).drive
        view = session.program.view()
        assert view.auto_generate and written_markdown(view).startswith("Writing: nothing yet")
        for text in ("DRIVE J1 TO 5 deg", "DRIVE J1 TO 6 deg", "DRIVE J1 TO 7 deg", "DRIVE J1 TO 8 deg"):
            view = session.program.insert(parse_program(text).statements[0])
        drive.show_program(view)  # what a connected page is sent
        assert drive.written.content == ("Written last:  \n2: `DRIVE J1 TO 6 deg`  \n3: `DRIVE J1 TO 7 deg`  \n"
                                         "4: `DRIVE J1 TO 8 deg`")
        session.program.set_auto_generate(False)
        drive.show_program(session.program.view())
        assert drive.written.content == "Writing: off (drags move the virtual arm only)"
    finally:
        session.close()
        server.stop()
