"""The header shows long work under way (a line and a bar) and hides it when the work ends."""

from __future__ import annotations

import viser

from server.console import Session, WorkProgress
from shared.cells.loader import DEFAULT_CELL, load_cell
from support import free_port
from webui.console import build_console


def test_the_header_shows_running_work_and_hides_it_when_it_ends() -> None:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    session = Session(load_cell(DEFAULT_CELL))
    try:
        status = build_console(server, session).status
        assert not status.work_bar.visible and not status.work_line.visible
        load = dict(id=7, work="load", what="loading big.tp", elapsed_s=0.5)
        session.bus.emit([WorkProgress(phase="plan", fraction=0.42, **load)])
        assert status.work_bar.visible and status.work_bar.value == 42.0
        assert "Loading big.tp" in status.work_line.content and "plan" in status.work_line.content
        play = dict(id=8, work="task_play", what="recognising the task in 900 statement(s) sent", elapsed_s=0.4)
        session.bus.emit([WorkProgress(phase="recognise", fraction=0.1, **play)])
        assert "Recognising" in status.work_line.content and "1 more" in status.work_line.content
        session.bus.emit([WorkProgress(phase="recognise", fraction=1.0, finished=True, **play)])
        assert "Loading big.tp" in status.work_line.content and status.work_bar.value == 42.0
        session.bus.emit([WorkProgress(phase="format", fraction=1.0, finished=True, **load)])
        assert not status.work_bar.visible and not status.work_line.visible
    finally:
        session.close()
        server.stop()
