"""Free editing in the console (issue 37): the statements after an edit are re-planned and checked
against the robot and the cell, a refusal comes in plain words on its line (the rule id only in the
API and the tooltip), harmless keys raise nothing, strict editing is a setting and a switch."""

from __future__ import annotations

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from server.api.program import router
from server.console import RefusedByRule, Session, SessionSettings
from server.console.events import Notice
from server.http_errors import add_error_handler
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision import SceneModel
from webui.program_list import program_html

UP = "DRAW TO (0, -80, 200) mm IN WORK"
ACROSS = "DRAW TO (60, -80, 200) mm IN WORK"
BACK = "DRAW TO (30, -80, 200) mm IN WORK"
# beside the peg (it stands in HOLE1 at work y = -80, its top at z = 90 mm), over it, beside it
# again: without the middle stroke the last one would run the gripper through the peg
WEST = "DRAW TO (-60, -80, 110) mm IN WORK"
OVER = "DRAW TO (0, -80, 200) mm IN WORK"
EAST = "DRAW TO (60, -80, 110) mm IN WORK"


@pytest.fixture(scope="module")
def cell_and_scene():
    cell = load_cell(DEFAULT_CELL)
    return cell, SceneModel.from_cell(cell)


def _session(cell_and_scene, **settings) -> Session:
    cell, scene = cell_and_scene
    return Session(cell, SessionSettings(**settings), scene=scene)


@pytest.fixture
def session(cell_and_scene):
    s = _session(cell_and_scene)
    yield s
    s.close()


def _program(session: Session, *lines: str) -> None:
    for line in lines:
        session.program.insert(line)


def _texts(view) -> list[str]:
    return [e.text for e in view.entries[:-1]]


def test_deleting_the_middle_draw_re_plans_the_rest_and_undo_restores_it(session: Session) -> None:
    _program(session, UP, ACROSS, BACK)
    before = session.program.view()
    session.program.select(1)
    view = session.program.delete()
    assert _texts(view) == [UP, BACK] and view.refusal is None and not view.strict_editing
    durations = [e.duration_s for e in view.entries[:-1]]
    assert all(d is not None and d > 0 for d in durations)  # both re-planned
    assert durations[1] != before.entries[2].duration_s  # BACK now starts where UP ends: a longer way
    view = session.program.undo()
    assert _texts(view) == [UP, ACROSS, BACK] and view.selected == 1


def test_a_delete_that_would_run_the_next_stroke_into_the_peg_is_refused_on_its_line(session: Session) -> None:
    _program(session, WEST, OVER, EAST)
    session.program.select(1)
    with pytest.raises(RefusedByRule) as caught:
        session.program.delete()
    refusal = caught.value.refusal
    assert refusal.rule.value == "edit.path" and refusal.index == 2
    assert refusal.message.startswith("statement 3 (DRAW TO (60, -80, 110) mm IN WORK) could no longer run")
    assert "peg" in refusal.message and "edit.path" not in refusal.message and " at t=" not in refusal.message
    view = session.program.view()
    assert _texts(view) == [WEST, OVER, EAST] and view.refusal.index == 2 and not view.can_redo
    html = program_html(view)
    shown = html.split('data-refusal-for="2"', 1)[1]
    assert 'title="rule edit.path"' in shown.split(">", 1)[0]  # the id in the tooltip
    assert "edit.path" not in shown.split(">", 1)[1].split("</div>", 1)[0]  # not in the visible text
    # what the edit did not touch may stay broken: replacing the middle stroke by one that keeps clear is fine
    view = session.program.modify("DRAW TO (0, -80, 180) mm IN WORK")
    assert view.refusal is None and len(view.entries) == 4


def test_moving_and_inserting_in_the_middle_re_plan_the_rest(session: Session) -> None:
    _program(session, UP, ACROSS, BACK)
    session.program.select(2)
    view = session.program.move_statements(-1)
    assert _texts(view) == [UP, BACK, ACROSS] and view.selected == 1 and view.undo_label == "move statement 3 up"
    view = session.program.insert("DRIVE J1 TO -10 deg")
    assert _texts(view)[1].startswith("DRIVE J1") and all(e.duration_s is not None for e in view.entries[:-1])
    session.program.undo()
    assert _texts(session.program.undo()) == [UP, ACROSS, BACK]


def test_harmless_keys_raise_nothing(session: Session) -> None:
    notices: list[Notice] = []
    session.subscribe_events(lambda event: notices.append(event) if isinstance(event, Notice) else None)
    _program(session, UP, ACROSS)
    view = session.program.move_selection(1)  # ArrowDown on the trailing empty statement
    assert view.selected == 2 and view.refusal is None
    session.program.select(0)
    assert session.program.move_selection(-1).selected == 0  # ArrowUp on the first
    assert session.program.move_statements(-1).refusal is None  # Alt+ArrowUp on the first
    assert _texts(session.program.view()) == [UP, ACROSS] and not notices


def test_strict_editing_is_a_setting_and_a_switch(cell_and_scene) -> None:
    strict = _session(cell_and_scene, strict_editing=True)
    try:
        _program(strict, UP, ACROSS, BACK)
        strict.program.select(1)
        with pytest.raises(RefusedByRule) as caught:
            strict.program.delete()
        assert caught.value.refusal.rule.value == "delete.action-not-last"
        view = strict.program.set_strict_editing(False)
        assert not view.strict_editing and view.undo_label == "insert DRAW"  # the switch is no edit
        assert _texts(strict.program.delete()) == [UP, BACK]
    finally:
        strict.close()


def test_the_api_switches_the_mode_moves_statements_and_undoes_a_load(session: Session) -> None:
    app = FastAPI()
    app.state.console = type("C", (), {"session": session})()
    add_error_handler(app)
    app.include_router(router)
    http = TestClient(app)
    _program(session, UP)
    http.post("/api/program/load", json={"text": f"{UP}\n{ACROSS}\n{BACK}\n", "filename": "three.tp"})
    assert http.post("/api/program/select", json={"index": 1}).status_code == 200
    body = http.post("/api/program/move-statements", json={"by": 1}).json()
    assert [e["text"] for e in body["entries"][:-1]] == [UP, BACK, ACROSS]
    assert http.put("/api/program/editing", json={"strict": True}).json()["strict_editing"] is True
    refused = http.post("/api/program/move-statements", json={"by": -1})
    assert refused.status_code == 409 and refused.json()["rule"] == "move.motion"
    http.put("/api/program/editing", json={"strict": False})
    http.post("/api/program/undo")  # the move
    body = http.post("/api/program/undo").json()  # the load
    assert [e["text"] for e in body["entries"][:-1]] == [UP]
