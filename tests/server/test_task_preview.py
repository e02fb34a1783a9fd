"""The task panel follows a preview: the actions a previewed range makes appear as the player
passes them, and the marking is where the player stands (thesis 3.5, issue 18 point 5)."""

from __future__ import annotations

from pathlib import Path

import pytest

from server.console import Session
from server.console.events import TaskChanged

ROOT = Path(__file__).resolve().parents[2]
PROGRAM = (ROOT / "assets" / "programs" / "peg_transfer.tp").read_text()
ALL = ["grasp(PEG)", "part(PEG,HOLE1)", "mate(PEG,HOLE2)", "release(PEG)"]


def actions(session: Session) -> list[str]:
    return [a.action for a in session.task.view().preview_actions]


def test_the_preview_shows_each_action_as_the_player_passes_it(session: Session) -> None:
    events: list = []
    session.subscribe_events(events.append)
    session.program.load(PROGRAM, "peg_transfer.tp")
    n = session.program.view().empty_index
    view = session.preview.begin(0, n)
    assert session.task.settled()  # the range is played off the caller's thread
    task = session.task.view()
    assert task.preview_active and actions(session) == []
    assert "PEGINHOLE(PEG,HOLE1)" in task.preview_marking and "HANDEEMPTY" in task.preview_marking

    seen: list[list[str]] = []
    for k in range(41):  # step the player through the range
        session.preview.seek(view.duration * k / 40)
        now = actions(session)
        if not seen or now != seen[-1]:
            seen.append(now)
    # each action appears once, in order, as the player passes it (a task call takes no plan
    # time, so grasp and the extraction after it appear together, as do insertion and release)
    assert all(s == ALL[:len(s)] for s in seen) and [len(s) for s in seen] == sorted({len(s) for s in seen})
    assert seen[0] == [] and seen[-1] == ALL and len(seen) >= 3
    task = session.task.view()
    assert "PEGINHOLE(PEG,HOLE2)" in task.preview_marking and "HOLEEMPTY(HOLE1)" in task.preview_marking
    assert "HANDEEMPTY" in task.preview_marking
    assert [a.statement for a in task.preview_actions] == sorted(a.statement for a in task.preview_actions)
    assert any(isinstance(e, TaskChanged) and e.task.preview_actions for e in events)
    # the virtual cell itself did not move: its marking is the loaded cell's
    assert "PEGINHOLE(PEG,HOLE1)" in task.virtual_marking and task.virtual_actions == []

    session.preview.end()
    task = session.task.view()
    assert not task.preview_active and task.preview_actions == [] and task.preview_marking == []


def test_a_preview_of_a_later_range_lists_only_that_range(session: Session) -> None:
    session.program.load(PROGRAM, "peg_transfer.tp")
    statements = session.program.view().entries
    first_draw = next(i for i, s in enumerate(statements) if "DRAW TO (0, -80, 160)" in s.text)
    view = session.preview.begin(first_draw, session.program.view().empty_index)
    session.preview.seek(view.duration)
    assert session.task.settled()
    # grasp and part happened before the range: the marking has them, the list does not
    assert actions(session) == ["mate(PEG,HOLE2)", "release(PEG)"]
    assert all(a.statement > first_draw for a in session.task.view().preview_actions)


def test_the_space_net_is_the_grounded_task_space_marked_as_loaded(session: Session) -> None:
    net = session.task.view().space_net
    assert net is not None
    predicates = {p.id: p.predicate for p in net.places}
    assert sorted(predicates.values()) == sorted(session.task.view().atoms)
    assert {predicates[p] for p in net.initial_marking} == set(session.task.view().virtual_marking)
    grasp = next(t for t in net.transitions if t.action == "grasp(PEG)")
    assert {predicates[p] for p in grasp.pre} == {"HANDEEMPTY", "PEGFREE(PEG)"}
    assert {predicates[p] for p in grasp.post} == {"HOLDING(PEG)"}


def test_a_preview_and_a_submit_never_wait_for_the_task_panels_play(session: Session, monkeypatch) -> None:
    """The play of a range (seconds at 1,000 statements) runs on the task panel's own thread: the
    preview answers while it is still playing, the panel follows once it is done."""
    import threading

    gate = threading.Event()
    real = session.task._play

    def slow_play(*args):
        assert gate.wait(30), "the test never let the play finish"
        return real(*args)

    monkeypatch.setattr(session.task, "_play", slow_play)
    session.program.load(PROGRAM, "peg_transfer.tp")
    n = session.program.view().empty_index
    view = session.preview.begin(0, n)  # answers although the play is held
    assert view.active and not session.task.settled(0.2)
    assert not session.task.view().preview_active  # nothing shown before the play is done
    gate.set()
    assert session.task.settled()
    session.preview.seek(view.duration)
    assert actions(session) == ALL


def test_a_range_previewed_again_after_an_edit_at_its_end_plays_only_what_changed(session: Session) -> None:
    """Recognition is kept per statement (issue 35): previewing the program again after a
    statement is added at its end plays that statement alone, and shows what a whole play shows."""
    session.program.load(PROGRAM, "peg_transfer.tp")
    n = session.program.view().empty_index
    session.preview.begin(0, n)
    assert session.task.settled()
    session.preview.end()
    session.program.insert("SPEED 20 %")  # at the end: the selection is the empty statement
    session.preview.begin(0, n + 1)
    view = session.preview.view()
    session.preview.seek(view.duration)
    assert session.task.settled()
    kept = session.task._recognition._kept[1]  # noqa: SLF001 - what the last play had to play
    assert kept.replayed == 1
    assert actions(session) == ALL
    session.preview.end()
