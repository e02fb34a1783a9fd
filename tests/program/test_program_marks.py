"""The editor's incremental rule checks (issue 35): a program state keeps each statement's kind as
bits (``shared.program.marks``) and an edit splices them, so an edit reads what it changed. These
tests hold the spliced bits and every answer built on them to the whole-program readings they
replace: the task rule's breaks, the unknown pose, and free editing's refusal found by comparing
the two programs statement by statement."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.errors import InputError
from shared.language.statements import Draw, Move, SetSpeed, Speed, SpeedUnit, TaskCall
from shared.language.task_rule import pose_after, task_rule_breaks
from shared.program import marks as kinds
from shared.program.editor import Editor, ProgramState
from shared.program.free_rules import EditMap, free_edit_refusal
from shared.program.rules import Refusal


def _pool(draw_id: int) -> list:
    """Fresh statement objects (the identity-based reading needs each object once)."""
    return [
        Draw(position=(0.1 + draw_id * 1e-4, 0.0, 0.2)),
        Move(joints=(0.0, -0.8, 3.4, 0.0, 0.5, 2.9)),
        SetSpeed(speed=Speed(value=0.5, unit=SpeedUnit.FRACTION)),
        TaskCall(name="grasp", args=("peg",)),
        TaskCall(name="extract_peg", args=("peg", "HOLE1")),
        TaskCall(name="insert_peg", args=("peg", "HOLE2")),
        TaskCall(name="release"),
        TaskCall(name="polish"),  # not in the registry: its end is unknown
    ]


def _whole_unknown(statements):
    unknown = None
    for i, s in enumerate(statements):
        unknown = pose_after(s, i, unknown)
    return unknown


def _state_or_none(statements) -> ProgramState | None:
    try:
        return ProgramState(tuple(statements))
    except InputError:
        return None


EDITS = st.lists(
    st.tuples(st.sampled_from(["insert", "delete", "modify", "move", "select", "submit"]),
              st.integers(0, 40), st.integers(0, 7), st.integers(-3, 3)),
    min_size=1, max_size=40,
)


@settings(max_examples=150, deadline=None)
@given(start=st.lists(st.integers(0, 7), max_size=12), edits=EDITS)
def test_spliced_marks_and_rules_match_the_whole_program_readings(start, edits) -> None:
    counter = iter(range(10**6))
    program = [_pool(next(counter))[k] for k in start]
    # keep only a program the rules accept as the start
    while program and task_rule_breaks(program):
        program.pop()
    editor = Editor(ProgramState.of(program))
    for op, where, kind, by in edits:
        state = editor.state
        n = state.empty_index
        statement = _pool(next(counter))[kind]
        if op == "select":
            editor.select(where % (n + 1), extend=by > 0)
        elif op == "insert":
            editor.insert(statement)
        elif op == "delete":
            editor.delete()
        elif op == "modify":
            editor.modify(statement)
        elif op == "move" and by:
            editor.move_statements(by)
        elif op == "submit" and n:
            result = state.submit(0, 1 + where % n)
            if not isinstance(result, Refusal):
                editor.load(result.state)
        new = editor.state
        assert np.array_equal(new.marks, kinds.marks_of(new.statements))
        assert new.unknown_pose == _whole_unknown(new.statements)
        assert task_rule_breaks(new.statements) == []


@settings(max_examples=200, deadline=None)
@given(before=st.lists(st.integers(0, 7), max_size=10), first=st.integers(0, 12), size=st.integers(0, 3),
       inserted=st.lists(st.integers(0, 7), max_size=3), where=st.integers(0, 12))
def test_a_spliced_edit_is_refused_as_the_statement_by_statement_reading_refuses_it(before, first, size, inserted, where) -> None:
    counter = iter(range(10**6))
    old = tuple(_pool(next(counter))[k] for k in before)
    first = min(first, len(old))
    stop = min(first + size, len(old))
    put = tuple(_pool(next(counter))[k] for k in inserted)
    new = (*old[:first], *put, *old[stop:])
    edit = EditMap.splice(kinds.marks_of(old), kinds.marks_of(put), first, stop)
    assert np.array_equal(edit.after_marks, kinds.marks_of(new))
    assert [edit.old_of(i) for i in range(len(new))] == [next((j for j, s in enumerate(old) if s is t), None) for t in new]
    assert free_edit_refusal(old, new, where, edit) == free_edit_refusal(old, new, where)
    first_break = kinds.first_break(new, edit.after_marks)
    whole = task_rule_breaks(new)
    assert (first_break is None) == (not whole)
    if whole:
        assert first_break == whole[0]
        assert _state_or_none(new) is None
    else:
        assert _state_or_none(new) is not None


@settings(max_examples=150, deadline=None)
@given(before=st.lists(st.integers(0, 7), min_size=1, max_size=10), first=st.integers(0, 9), size=st.integers(1, 3),
       by=st.integers(-9, 9))
def test_a_moved_range_maps_back_to_where_it_was(before, first, size, by) -> None:
    counter = iter(range(10**6))
    old = tuple(_pool(next(counter))[k] for k in before)
    first = min(first, len(old) - 1)
    stop = min(first + size - 1, len(old) - 1)
    if by == 0 or not 0 <= first + by <= stop + by < len(old):
        return
    edit = EditMap.move(kinds.marks_of(old), first, stop, by)
    block, rest = old[first:stop + 1], old[:first] + old[stop + 1:]
    new = (*rest[:first + by], *block, *rest[first + by:])
    assert np.array_equal(edit.after_marks, kinds.marks_of(new))
    assert [old[edit.old_of(i)] for i in range(len(new))] == list(new)
    assert free_edit_refusal(old, new, first, edit) == free_edit_refusal(old, new, first)


def test_a_state_refuses_what_no_program_may_hold_and_a_motion_after_an_unknown_end() -> None:
    draw, _, speed, _, _, insert, _, _ = _pool(0)
    with pytest.raises(InputError, match="statement 2: a program holds real statements only"):
        ProgramState((draw, "DRAW"))
    with pytest.raises(InputError, match="statement 3: DRAW cannot follow TASK insert_peg"):
        ProgramState((draw, insert, _pool(1)[0]))
    # given marks that do not fit the statements are read again, never trusted
    state = ProgramState((insert, speed), marks=np.zeros(1, dtype=np.uint8))
    assert np.array_equal(state.marks, kinds.marks_of((insert, speed)))
