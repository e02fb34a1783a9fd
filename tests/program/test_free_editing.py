"""Free editing, the editor's default (issue 37): delete, replace, move and insert any statement or
range; refused only where the result cannot run (a motion after a task whose end only the robot
knows, a later task call's gripper state broken). The strict mode keeps the thesis's refusals
(§4.3.6, ``test_editor.py`` tests it at length). Undo covers every edit."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.language.statements import Draw, Move, SetSpeed, Speed, SpeedUnit, TaskCall, UntilContact
from shared.program.editor import Editor, ProgramState
from shared.program.free_rules import gripper_breaks
from shared.program.rules import Refusal, Rule, program_violations

D1 = Draw(position=(0.1, 0.0, 0.2))
D2 = Draw(position=(0.2, 0.0, 0.2))
D3 = Draw(position=(0.3, 0.0, 0.2))
HOME = Move(joints=(0.0, -0.8, 3.4, 0.0, 0.5, 2.9))
SPD = SetSpeed(speed=Speed(value=0.5, unit=SpeedUnit.FRACTION))
GRASP = TaskCall(name="grasp", args=("peg",))
EXTRACT = TaskCall(name="extract_peg", args=("peg", "HOLE1"))
INSERT = TaskCall(name="insert_peg", args=("peg", "HOLE2"))
RELEASE = TaskCall(name="release")


def editor(*statements, selected: int | None = None, strict: bool = False) -> Editor:
    return Editor(ProgramState.of(statements, selected), strict=strict)


def done(result: object) -> ProgramState:
    assert isinstance(result, ProgramState), f"expected a new program, got {result}"
    return result


def refused(result: object, rule: Rule) -> Refusal:
    assert isinstance(result, Refusal), f"expected a refusal by {rule.value}, got {result!r}"
    assert result.rule is rule, f"expected {rule.value}, got {result}"
    assert rule.value not in result.message and "rule" not in result.message  # plain words for the operator
    return result


def test_free_editing_is_the_default() -> None:
    assert Editor().strict is False
    assert Editor(strict=True).strict is True


# ------------------------------------------------------------------ delete


def test_deleting_a_motion_in_the_middle_leaves_the_rest_and_undo_brings_it_back() -> None:
    e = editor(D1, D2, D3, selected=1)
    state = done(e.delete())
    assert state.statements == (D1, D3)  # D3 now starts where D1 ends: its target is absolute
    assert state.selected_statement is D3
    assert e.undo_label == "delete DRAW"
    back = done(e.undo())
    assert back.statements == (D1, D2, D3) and back.selected_index == 1
    assert done(e.redo()).statements == (D1, D3)


def test_a_range_with_motions_goes_from_the_middle_in_one_step() -> None:
    e = editor(D1, SPD, D2, D3, HOME)
    e.select_range(1, 3)
    state = done(e.delete())
    assert state.statements == (D1, HOME) and state.selected_index == 1
    assert e.undo_label == "delete statements 2..4"
    assert done(e.undo()).statements == (D1, SPD, D2, D3, HOME)


def test_the_trailing_empty_statement_still_cannot_be_deleted() -> None:
    refused(editor(D1).delete(), Rule.DELETE_EMPTY)


# ------------------------------------------------------------------ replace


def test_a_motion_in_the_middle_can_be_replaced_by_a_new_target() -> None:
    e = editor(D1, D2, D3, selected=1)
    new = Draw(position=(0.25, 0.05, 0.2), speed=Speed(value=0.01, unit=SpeedUnit.M_PER_S), until=UntilContact())
    state = done(e.modify(new))
    assert state.statements == (D1, new, D3) and state.selected_index == 1
    assert done(e.undo()).statements == (D1, D2, D3)


def test_a_statement_can_be_replaced_by_one_of_another_kind() -> None:
    e = editor(D1, D2, SPD, D3, selected=1)
    assert done(e.modify(HOME)).statements == (D1, HOME, SPD, D3)  # a DRAW becomes a MOVE
    e.select(2)
    assert done(e.modify(D2)).statements == (D1, HOME, D2, D3)  # a SPEED becomes a DRAW


def test_a_task_call_can_be_replaced() -> None:
    e = editor(D1, GRASP, D2, selected=1)
    assert done(e.modify(SPD)).statements == (D1, SPD, D2)


def test_the_conditions_of_any_action_still_change() -> None:
    e = editor(D1, D2, selected=0)
    state = done(e.modify_conditions(until=UntilContact()))
    assert state.statements[0].until == UntilContact() and state.statements[1] is D2


# ------------------------------------------------------------------ move


def test_a_statement_moves_up_and_down_with_the_selection_and_undo_takes_it_back() -> None:
    e = editor(D1, D2, D3, selected=2)
    state = done(e.move_statements(-1))
    assert state.statements == (D1, D3, D2) and state.selected_statement is D3
    assert e.undo_label == "move statement 3 up"
    state = done(e.move_statements(-1))
    assert state.statements == (D3, D1, D2) and state.selected_index == 0
    assert done(e.undo()).statements == (D1, D3, D2)
    assert done(e.undo()).statements == (D1, D2, D3)


def test_a_range_moves_as_one_block() -> None:
    e = editor(D1, SPD, D2, D3)
    e.select_range(0, 1)
    state = done(e.move_statements(2))
    assert state.statements == (D2, D3, D1, SPD)
    assert state.selected_range == (2, 3)
    assert e.undo_label == "move statements 1..2 down"


def test_a_move_past_either_end_is_refused() -> None:
    e = editor(D1, D2, selected=0)
    assert refused(e.move_statements(-1), Rule.MOVE_RANGE).index == 0
    e.select(1)
    refused(e.move_statements(1), Rule.MOVE_RANGE)  # the empty statement stays last
    e.select(2)
    refused(e.move_statements(-1), Rule.MOVE_RANGE)  # the empty statement itself does not move


# ------------------------------------------------------------------ insert


def test_actions_and_tasks_go_in_anywhere() -> None:
    e = editor(D1, D3, selected=1)
    assert done(e.insert(D2)).statements == (D1, D2, D3)
    e.select(0)
    state = done(e.insert(HOME))
    assert state.statements == (HOME, D1, D2, D3) and state.selected_statement is D1
    e.select(2)
    assert done(e.insert(GRASP)).statements == (HOME, D1, GRASP, D2, D3)
    for _ in range(3):
        done(e.undo())
    assert e.state.statements == (D1, D3)


# ------------------------------------------------------------------ what free editing refuses


def test_deleting_the_grasp_a_later_extraction_needs_is_refused_on_the_extraction() -> None:
    e = editor(D1, GRASP, EXTRACT, D2, selected=1)
    refusal = refused(e.delete(), Rule.EDIT_TASK_STATE)
    assert refusal.index == 2  # the extract_peg's line, numbered as the operator sees it now
    assert "TASK extract_peg (statement 3)" in refusal.message and "hold nothing" in refusal.message
    assert e.state.statements == (D1, GRASP, EXTRACT, D2)  # nothing changed
    assert not e.can_undo


def test_moving_or_adding_a_task_that_breaks_a_later_one_is_refused() -> None:
    e = editor(GRASP, D1, EXTRACT, D2, RELEASE, selected=0)
    refused(e.move_statements(3), Rule.EDIT_TASK_STATE)  # the grasp after the extraction
    e.select(1)
    refusal = refused(e.insert(RELEASE), Rule.EDIT_TASK_STATE)  # let go before the extraction
    assert refusal.index == 2
    e.select(0)
    refused(e.insert(GRASP), Rule.EDIT_TASK_STATE)  # the old grasp would find the gripper full
    e.select(4)
    assert done(e.delete()).statements == (GRASP, D1, EXTRACT, D2)  # the release at the end: nothing after it needs it


def test_an_edit_is_not_refused_for_what_was_already_broken() -> None:
    # the program starts holding the peg (the robot grasped it before): nothing the editor can
    # know, so extract_peg first is fine, and so is an edit around it
    e = editor(EXTRACT, D1, D2, RELEASE, selected=1)
    assert done(e.delete()).statements == (EXTRACT, D2, RELEASE)


def test_a_motion_after_a_task_whose_end_only_the_robot_knows_is_refused() -> None:
    e = editor(D1, INSERT, SPD, selected=2)
    refusal = refused(e.modify(D2), Rule.EDIT_AFTER_TASK)  # the SPEED after insert_peg made a DRAW
    assert "TASK insert_peg" in refusal.message and refusal.index == 2
    e.select(0)
    refused(e.move_statements(2), Rule.EDIT_AFTER_TASK)  # the DRAW past the insertion
    e.select(3)
    refused(e.insert(D2), Rule.INSERT_AFTER_TASK)  # at the end, as in strict mode
    e.select(1)
    assert done(e.insert(D2)).statements == (D1, D2, INSERT, SPD)  # before the insertion: fine


def test_gripper_breaks_follow_the_tasks_contracts() -> None:
    assert gripper_breaks([GRASP, EXTRACT, INSERT, RELEASE]) == {}
    assert set(gripper_breaks([EXTRACT])) == {0}  # from an empty gripper
    assert gripper_breaks([EXTRACT, RELEASE, GRASP], start="peg") == {}
    assert "already hold" in gripper_breaks([GRASP, GRASP])[1]
    assert "not bolt" in gripper_breaks([GRASP, TaskCall(name="extract_peg", args=("bolt", "HOLE1"))])[1]
    assert gripper_breaks([TaskCall(name="grasp", args=("PEG",)), EXTRACT]) == {}  # names without case


# ------------------------------------------------------------------ strict mode keeps the thesis's refusals


@pytest.mark.parametrize(("edit", "rule"), [
    (lambda e: e.delete(), Rule.DELETE_ACTION_NOT_LAST),
    (lambda e: e.modify(Draw(position=(0.25, 0.0, 0.2))), Rule.MODIFY_ACTION_PARAMETERS),
    (lambda e: e.modify(HOME), Rule.MODIFY_KIND),
    (lambda e: e.insert(HOME), Rule.INSERT_ACTION_AT_END),
    (lambda e: e.insert(GRASP), Rule.INSERT_TASK_AT_END),
    (lambda e: e.move_statements(1), Rule.MOVE_MOTION),
], ids=["delete", "replace", "replace-kind", "insert-action", "insert-task", "move"])
def test_strict_mode_keeps_the_thesis_refusals(edit, rule: Rule) -> None:
    strict = editor(D1, D2, D3, selected=1, strict=True)
    result = edit(strict)
    assert isinstance(result, Refusal) and result.rule is rule, result
    assert strict.state.statements == (D1, D2, D3)
    free = editor(D1, D2, D3, selected=1)
    assert isinstance(edit(free), ProgramState)  # the same edit, free: done


def test_strict_mode_moves_parameter_statements_and_refuses_a_task_call_edit() -> None:
    e = editor(D1, SPD, D2, GRASP, selected=1, strict=True)
    assert done(e.move_statements(1)).statements == (D1, D2, SPD, GRASP)
    e.select(3)
    assert isinstance(e.modify(RELEASE), Refusal) and e.modify(RELEASE).rule is Rule.MODIFY_TASK


def test_switching_the_mode_is_not_an_edit() -> None:
    e = editor(D1, D2, D3, selected=1, strict=True)
    assert isinstance(e.delete(), Refusal)
    e.strict = False
    assert not e.can_undo
    assert done(e.delete()).statements == (D1, D3)
    e.strict = True
    assert done(e.undo()).statements == (D1, D2, D3)  # undo is undo in either mode


# ------------------------------------------------------------------ undo covers every edit


def test_a_loaded_program_is_an_edit_undo_takes_back() -> None:
    e = editor(D1, D2)
    done(e.insert(SPD))
    loaded = ProgramState.of((D3, GRASP))
    assert done(e.load(loaded, "load transfer.tp")) is loaded
    assert e.undo_label == "load transfer.tp"
    assert done(e.undo()).statements == (D1, D2, SPD)
    assert done(e.undo()).statements == (D1, D2)
    assert done(e.redo()).statements == (D1, D2, SPD)
    assert done(e.redo()).statements == (D3, GRASP)


def test_every_kind_of_edit_is_one_undo_step() -> None:
    e = editor(D1, D2, D3, selected=1)
    history = [e.state]
    for edit in (
        lambda: e.insert(SPD),
        lambda: e.modify_conditions(until=UntilContact()),
        lambda: e.modify(HOME),
        lambda: e.move_statements(-1),
        lambda: e.delete(),
        lambda: e.load(ProgramState.of((D3,))),
    ):
        history.append(done(edit()))
    for state in reversed(history[:-1]):
        assert done(e.undo()) == state  # exactly, selection included
    assert not e.can_undo


# ------------------------------------------------------------------ random use


_STATEMENTS = [D1, D2, D3, HOME, SPD, GRASP, EXTRACT, INSERT, RELEASE]
_ops = st.lists(
    st.tuples(
        st.sampled_from(["insert", "delete", "modify", "move", "select", "range"]),
        st.integers(0, 8),
        st.integers(-3, 3),
    ),
    max_size=30,
)


@settings(max_examples=200, deadline=None)
@given(_ops)
def test_random_free_edits_keep_the_program_valid_and_undo_walks_back_exactly(ops) -> None:
    e = Editor()
    steps: list[tuple[ProgramState, ProgramState]] = []  # (before, after) of each edit done
    for op, k, by in ops:
        n = e.state.empty_index
        if op == "select":
            e.select(k % (n + 1))
            continue
        if op == "range":
            e.select_range(k % (n + 1), (k + abs(by)) % (n + 1))
            continue
        before = e.state
        result = {
            "insert": lambda: e.insert(_STATEMENTS[k].model_copy()),
            "delete": lambda: e.delete(),
            "modify": lambda: e.modify(_STATEMENTS[k].model_copy()),
            "move": lambda: e.move_statements(by),
        }[op]()
        if isinstance(result, Refusal):
            assert e.state is before  # a refused edit changes nothing
            assert result.rule.value not in result.message
            continue
        assert e.state is result
        assert program_violations(result.statements) == []
        steps.append((before, result))
    for before, after in reversed(steps):
        assert e.state.statements == after.statements
        assert done(e.undo()) is before  # exactly the state before the edit, selection included
    assert not e.can_undo
