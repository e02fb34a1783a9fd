"""``webui.notice_log.NoticeBoard``: when the notice line's notice ends, and what the log keeps.
The page's own checks are in ``tests/browser/test_truthful_model.py``; these are the rules."""

from __future__ import annotations

from shared.errors import InputError
from webui.actions import Actions
from webui.notice_log import LOG_SIZE, RECOVERY, NoticeBoard, action_kind, session_kind


def _board() -> NoticeBoard:
    return NoticeBoard(wall_clock=lambda: 0.0)


def _refuse():
    raise InputError("nope")


def test_a_refusal_stands_until_a_good_action_of_its_kind_that_began_after_it() -> None:
    board = _board()
    actions = Actions(lambda *a: None, board=board)
    actions.run("submit", _refuse)
    assert "submit refused: nope" in board.line_markdown()
    actions.run("regime override", lambda: None)  # another kind: it stands
    assert "submit refused" in board.line_markdown()
    actions.run("submit", lambda: None)
    assert board.line_markdown() == ""
    assert [n.message for n in board.entries()] == ["submit refused: nope"]  # the log keeps it


def test_a_notice_posted_during_a_good_action_is_not_ended_by_it() -> None:
    board = _board()
    actions = Actions(lambda *a: None, board=board)
    actions.run("release", lambda: board.post("warning", "held back, not sent", None, session_kind("warning", "held back, not sent")))
    assert "held back" in board.line_markdown()


def test_edits_share_a_kind_and_an_info_note_ends_at_any_good_action() -> None:
    assert action_kind("insert") == action_kind("delete") == action_kind("undo")
    board = _board()
    actions = Actions(lambda *a: None, board=board)
    actions.run("insert", _refuse)
    actions.run("delete", lambda: None)
    assert board.line_markdown() == ""
    board.post("info", "loaded 3 statement(s) from a.tp", None, session_kind("info", "loaded 3 statement(s) from a.tp"))
    actions.run("preview", lambda: None)
    assert board.line_markdown() == ""


def test_a_robot_answer_ends_when_the_robot_state_it_was_given_in_ends() -> None:
    board = _board()
    board.robot_state("idle")
    message = "robot did not apply stop: nothing to stop (robot idle)"
    assert session_kind("warning", message) == RECOVERY
    board.post("warning", message, None, session_kind("warning", message))
    board.robot_state("idle")
    assert "nothing to stop" in board.line_markdown()
    board.robot_state("running")
    assert board.line_markdown() == ""


def test_the_log_keeps_the_last_fifty_newest_first() -> None:
    board = _board()
    for i in range(LOG_SIZE + 5):
        board.post("info", f"note {i}", None, "note")
    entries = board.entries()
    assert len(entries) == LOG_SIZE
    assert entries[0].message == f"note {LOG_SIZE + 4}" and entries[-1].message == "note 5"
    assert board.log_html().count("data-notice-level") == LOG_SIZE
