"""The program desk as an editor: a selected range in the view, a refusal kept on its line until
the next edit, planned durations per statement, range deletion through the HTTP API."""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from server.console import RefusedByRule, Session
from shared.motion.interpreter import plan_program

UP = "DRAW TO (0, -80, 200) mm IN WORK"
ACROSS = "DRAW TO (60, -80, 200) mm IN WORK"


def _program(session: Session, *lines: str) -> None:
    for line in lines:
        session.program.insert(line)


def test_the_view_carries_the_selected_range(session: Session) -> None:
    _program(session, UP, "SPEED 50 %", ACROSS)
    session.program.select(0)
    view = session.program.select(2, extend=True)
    assert view.selected_range == (0, 2) and view.selected == 2
    view = session.program.move_selection(-1, extend=True)
    assert view.selected_range == (0, 1)
    assert session.program.move_selection(1).selected_range == (2, 2)


def test_a_refusal_stays_on_its_line_until_the_next_edit(session: Session) -> None:
    session.program.set_strict_editing(True)  # the thesis's rules refuse a motion from the middle
    _program(session, UP, "SPEED 50 %", ACROSS)
    session.program.select_range(0, 1)
    with pytest.raises(RefusedByRule):
        session.program.delete()
    view = session.program.view()
    assert view.refusal is not None
    assert view.refusal.rule == "delete.action-not-last" and view.refusal.index == 0
    assert len(view.entries) == 4  # nothing deleted
    assert session.program.select(1).refusal is None  # the next selection clears it


def test_a_range_delete_is_one_undo_step(session: Session) -> None:
    _program(session, UP, "SPEED 50 %", "SPEED 20 %", ACROSS)
    view = session.program.delete(1, 2)
    assert [e.kind for e in view.entries] == ["DRAW", "DRAW", "EMPTY"]
    assert view.selected == 1  # the statement after the range, not the empty one
    view = session.program.undo()
    assert [e.kind for e in view.entries] == ["DRAW", "SPEED", "SPEED", "DRAW", "EMPTY"]


def test_a_submission_from_the_middle_is_refused_on_its_first_line(session: Session) -> None:
    _program(session, UP, ACROSS)
    session.dispatch.robot, session.dispatch.loop = object(), object()  # connected, never reached
    try:
        with pytest.raises(RefusedByRule) as refused:
            session.dispatch.submit(1, 2)
    finally:
        session.dispatch.robot = session.dispatch.loop = None
    assert refused.value.refusal.rule.value == "submit.prefix"
    refusal = session.program.view().refusal
    assert refusal is not None and refusal.index == 1 and "submit 1..2 instead" in refusal.message


def test_each_statement_has_its_planned_duration(session: Session) -> None:
    _program(session, UP, "SPEED 50 %", ACROSS)
    view = session.program.view()
    statements = [e.statement for e in view.entries[:-1]]
    plan = plan_program(statements, session.robot, session.cell, start_q=np.asarray(view.start_q))
    durations = [e.duration_s for e in view.entries]
    assert durations[:3] == pytest.approx(list(plan.durations))
    assert durations[0] > 0.1 and durations[1] == 0.0 and durations[2] > 0.1
    assert durations[3] is None  # the empty statement


def test_the_http_api_selects_moves_and_deletes_ranges(session: Session) -> None:
    from fastapi import FastAPI

    from server.api.program import router
    from server.http_errors import add_error_handler

    app = FastAPI()
    app.state.console = type("C", (), {"session": session})()
    add_error_handler(app)
    app.include_router(router)
    http = TestClient(app)
    assert http.put("/api/program/editing", json={"strict": True}).json()["strict_editing"] is True
    _program(session, UP, "SPEED 50 %", "SPEED 20 %", ACROSS)
    assert http.post("/api/program/select", json={"index": 1}).json()["selected_range"] == [1, 1]
    assert http.post("/api/program/move", json={"by": 1, "extend": True}).json()["selected_range"] == [1, 2]
    refused = http.post("/api/program/delete-range", json={"first": 0, "last": 1})
    assert refused.status_code == 409 and refused.json()["rule"] == "delete.action-not-last"
    body = http.post("/api/program/delete").json()  # the selected range 2..3
    assert [e["kind"] for e in body["entries"]] == ["DRAW", "DRAW", "EMPTY"]
    assert http.post("/api/program/move", json={"by": 2}).status_code == 422
