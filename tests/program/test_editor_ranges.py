"""Ranges in the program editor: select a range, delete it under the thesis's continuity rule
(strict mode), one undo step; refusals name the statement they concern (``Refusal.index``)."""

from __future__ import annotations

import pytest

from shared.language.statements import Draw, SetSpeed, Speed, SpeedUnit
from shared.program.editor import Editor, ProgramState
from shared.program.rules import Refusal, Rule

D1 = Draw(position=(0.1, 0.0, 0.2))
D2 = Draw(position=(0.2, 0.0, 0.2))
D3 = Draw(position=(0.3, 0.0, 0.2))
SPD = SetSpeed(speed=Speed(value=0.5, unit=SpeedUnit.FRACTION))
SLOW = SetSpeed(speed=Speed(value=0.2, unit=SpeedUnit.FRACTION))


def editor(*statements, selected: int | None = None) -> Editor:
    return Editor(ProgramState.of(statements, selected), strict=True)


def test_shift_select_makes_a_range_and_a_plain_select_collapses_it() -> None:
    e = editor(D1, SPD, D2, D3)
    e.select(1)
    e.select(3, extend=True)
    assert e.state.selected_range == (1, 3)
    assert e.state.selected_index == 3  # the cursor is where the range was extended to
    e.select_previous(extend=True)
    assert e.state.selected_range == (1, 2)
    e.select_previous(extend=True)
    e.select_previous(extend=True)
    assert e.state.selected_range == (0, 1)  # past the anchor: the range turns round it
    e.select_next()
    assert e.state.selected_range == (1, 1)


def test_select_range_checks_both_ends() -> None:
    e = editor(D1, D2)
    refusal = e.select_range(0, 7)
    assert isinstance(refusal, Refusal) and refusal.rule is Rule.SELECT_RANGE
    assert e.select_range(2, 0).selected_range == (0, 2)


def test_a_range_reaching_the_end_is_deleted_in_one_undo_step() -> None:
    e = editor(D1, SPD, D2, D3)
    e.select_range(1, 4)  # through the trailing empty statement, which stays
    state = e.delete()
    assert isinstance(state, ProgramState)
    assert state.statements == (D1,)
    assert state.selected_range == (1, 1)  # the statement after the range: here the empty one
    assert e.undo_label == "delete statements 2..4"
    back = e.undo()
    assert back.statements == (D1, SPD, D2, D3) and back.selected_range == (1, 4)
    assert e.redo().statements == (D1,)


def test_a_range_of_parameter_statements_may_go_from_the_middle_and_selection_goes_after_it() -> None:
    e = editor(D1, SPD, SLOW, D2, D3)
    state = e.delete(1, 2)
    assert isinstance(state, ProgramState)
    assert state.statements == (D1, D2, D3)
    assert state.selected_index == 1 and state.selected_statement == D2  # not the empty line


def test_a_range_with_an_action_in_the_middle_is_refused_on_that_action() -> None:
    e = editor(D1, SPD, D2, D3)
    e.select_range(1, 2)
    refusal = e.delete()
    assert isinstance(refusal, Refusal)
    assert refusal.rule is Rule.DELETE_ACTION_NOT_LAST
    assert refusal.index == 2  # the DRAW at statement 3
    assert "statements 2..3" in refusal.message and "statement 4 follows" in refusal.message
    assert e.state.statements == (D1, SPD, D2, D3)  # nothing changed
    assert not e.can_undo


def test_a_single_middle_action_is_refused_on_its_line() -> None:
    e = editor(D1, D2, selected=0)
    refusal = e.delete()
    assert isinstance(refusal, Refusal) and refusal.rule is Rule.DELETE_ACTION_NOT_LAST and refusal.index == 0


def test_deleting_only_the_empty_statement_is_refused_on_it() -> None:
    e = editor(D1)
    refusal = e.delete()
    assert isinstance(refusal, Refusal) and refusal.rule is Rule.DELETE_EMPTY and refusal.index == 1


def test_insert_collapses_a_range() -> None:
    e = editor(D1, D2)
    e.select_range(0, 2)
    state = e.insert(SPD)
    assert isinstance(state, ProgramState)
    assert state.statements == (D1, D2, SPD)
    assert state.selected_range == (3, 3)


@pytest.mark.parametrize(("start", "stop", "rule", "index"), [
    (1, 3, Rule.SUBMIT_PREFIX, 1),
    (0, 9, Rule.SUBMIT_RANGE, 0),
])
def test_submit_refusals_name_their_first_statement(start, stop, rule, index) -> None:
    refusal = ProgramState.of((D1, SPD, D2)).check_submit(start, stop)
    assert refusal is not None and refusal.rule is rule and refusal.index == index
    if rule is Rule.SUBMIT_PREFIX:
        assert "submit 1..3 instead" in refusal.message


def test_insert_and_modify_refusals_name_the_selected_line() -> None:
    state = ProgramState.of((D1, D2), selected=0)
    assert state.check_insert(D3, strict=True).index == 0
    assert state.check_modify(D3, strict=True).index == 0
