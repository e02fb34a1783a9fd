"""The program editor in its strict mode (thesis §4.3.6): rules, invariants under random use,
exact undo/redo. Free editing, the default, is tested in ``test_free_editing.py``.

The state machine below keeps its own record of what must hold and re-derives, from the thesis's
wording, which rule should refuse each operation; so it catches both an editor that allows too
much (an invariant breaks) and one that refuses too much (an expected success is refused).
"""

from __future__ import annotations

from collections.abc import Callable

import pytest
from hypothesis import HealthCheck, event, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

from shared.errors import InputError
from shared.language.statements import (
    Draw,
    Drive,
    Event,
    Mode,
    Move,
    Moves,
    Rotate,
    SetMode,
    SetSpeed,
    Speed,
    SpeedUnit,
    TaskCall,
    UntilContact,
    UntilForce,
    UntilTime,
    is_action,
    is_parameter,
    is_task,
)
from shared.program.editor import EMPTY, Editor, EmptyStatement, PreviewStarted, ProgramState, Submission
from shared.program.rules import Refusal, RefusedError, Rule, program_violations, unwrap

# ------------------------------------------------------------------ strategies

_num = st.floats(-3.0, 3.0, allow_nan=False, allow_infinity=False)
_vec3 = st.tuples(_num, _num, _num)
_speed = st.builds(Speed, value=st.floats(0.01, 1.0), unit=st.sampled_from(list(SpeedUnit)))
_speeds = st.none() | _speed
_untils = st.none() | st.builds(UntilForce, newtons=st.floats(0.1, 50.0)) | st.builds(UntilContact) | st.builds(
    UntilTime, seconds=st.floats(0.1, 10.0)
)
_names = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,6}", fullmatch=True)

BY_KIND: dict[str, st.SearchStrategy] = {
    "MOVE": st.builds(Move, joints=st.tuples(*[_num] * 6), speed=_speeds, until=_untils),
    "DRIVE": st.builds(Drive, joint=st.integers(1, 6), target=_num, speed=_speeds, until=_untils),
    "DRAW": st.builds(Draw, position=_vec3, speed=_speeds, until=_untils),
    "ROTATE": st.builds(Rotate, rpy=_vec3, speed=_speeds, until=_untils),
    "MOVES": st.builds(Moves, position=_vec3, rpy=_vec3, speed=_speeds, until=_untils),
    "SPEED": st.builds(SetSpeed, speed=_speed),
    "MODE": st.builds(SetMode, mode=st.sampled_from(list(Mode))),
    "EVENT": st.builds(Event, name=_names),
    "TASK": st.builds(
        TaskCall, name=st.sampled_from(["insert_peg", "extract_peg", "grasp", "release", "fly"]),
        args=st.lists(_names, max_size=2).map(tuple),
    ),
}
actions = st.one_of(*(BY_KIND[k] for k in ("MOVE", "DRIVE", "DRAW", "ROTATE", "MOVES")))
parameters = st.one_of(BY_KIND["SPEED"], BY_KIND["MODE"], BY_KIND["EVENT"])
tasks = BY_KIND["TASK"]
statements = st.one_of(actions, parameters, tasks)


# the task registry's end-state contracts, restated: grasp and release keep the arm still,
# extract_peg ends where its contract says; insert_peg (and a task nobody knows) ends where only
# the robot can tell
STILL_TASKS = {"grasp", "release"}
KNOWN_END_TASKS = STILL_TASKS | {"extract_peg"}


def is_motion(statement: object) -> bool:
    """Moves the arm: an action, or a task that does not keep the arm still."""
    return is_action(statement) or (is_task(statement) and statement.name not in STILL_TASKS)


def ends_unknown(statement: object) -> bool:
    return is_task(statement) and statement.name not in KNOWN_END_TASKS


def end_key(statement: object) -> object:
    """Where a motion leaves the robot: an action's own parameters (conditions aside); a task's call."""
    if is_action(statement):
        return statement.model_copy(update={"speed": None, "until": None})
    return ("after task", statement)


# ------------------------------------------------------------------ the rules, restated for the oracle


def expected_insert(state: ProgramState, statement: object) -> Rule | None:
    if state.preview is not None:
        return Rule.PREVIEW_LOCKED
    before_empty = state.selected == len(state.statements)
    if is_action(statement) and not before_empty:
        return Rule.INSERT_ACTION_AT_END
    if is_task(statement) and not before_empty:
        return Rule.INSERT_TASK_AT_END
    if before_empty and is_motion(statement) and any(ends_unknown(s) for s in state.statements):
        return Rule.INSERT_AFTER_TASK
    return None


def expected_delete(state: ProgramState) -> Rule | None:
    if state.preview is not None:
        return Rule.PREVIEW_LOCKED
    if state.selected == len(state.statements):
        return Rule.DELETE_EMPTY
    selected = state.statements[state.selected]
    if is_action(selected) and state.selected != len(state.statements) - 1:
        return Rule.DELETE_ACTION_NOT_LAST
    if is_task(selected) and is_motion(selected) and any(is_motion(s) for s in state.statements[state.selected + 1 :]):
        return Rule.DELETE_ACTION_NOT_LAST  # a task that moves the arm is a motion too
    return None


def expected_modify(state: ProgramState, new: object) -> Rule | None:
    if state.preview is not None:
        return Rule.PREVIEW_LOCKED
    if state.selected == len(state.statements):
        return Rule.MODIFY_EMPTY
    old = state.statements[state.selected]
    if is_task(old):
        return Rule.MODIFY_TASK
    if new.kind != old.kind:
        return Rule.MODIFY_KIND
    last = state.selected == len(state.statements) - 1
    if is_action(old) and not last and end_key(new) != end_key(old):
        return Rule.MODIFY_ACTION_PARAMETERS
    return None


def expected_conditions(state: ProgramState) -> Rule | None:
    if state.preview is not None:
        return Rule.PREVIEW_LOCKED
    if state.selected == len(state.statements):
        return Rule.MODIFY_EMPTY
    if not is_action(state.statements[state.selected]):
        return Rule.MODIFY_CONDITIONS_NOT_ACTION
    return None


def expected_submit(state: ProgramState, start: int, stop: int) -> Rule | None:
    if state.preview is not None:
        return Rule.PREVIEW_LOCKED
    if not 0 <= start < stop <= len(state.statements):
        return Rule.SUBMIT_RANGE
    if start != 0:
        return Rule.SUBMIT_PREFIX
    return None


def assert_refused(result: object, rule: Rule) -> None:
    assert isinstance(result, Refusal), f"expected a refusal by {rule.value}, got {result!r}"
    assert result.rule is rule, f"expected rule {rule.value}, got {result}"
    assert result.message


# ------------------------------------------------------------------ random use


class EditorMachine(RuleBasedStateMachine):
    """Random operation sequences against the editor, with an independent record of the truth."""

    def __init__(self) -> None:
        super().__init__()
        self.editor = Editor(strict=True)
        # (state before, state after) of each edit undo can take back, and of each undone edit
        self.undo_steps: list[tuple[ProgramState, ProgramState]] = []
        self.redo_steps: list[tuple[ProgramState, ProgramState]] = []
        self.submitted: list = []  # everything handed to the robot, in order
        # id(statement) -> (statement, where it must start); the statement is kept so ids stay unique
        self.starts: dict[int, tuple[object, object]] = {}

    # -------------------------------------------------------------- helpers

    def robot_end(self) -> object:
        motions = [s for s in self.submitted if is_motion(s)]
        return end_key(motions[-1]) if motions else "robot start"

    def start_at(self, state: ProgramState, index: int) -> object:
        """Where a motion placed at ``index`` of ``state`` starts: the end of the motion before it."""
        before = [s for s in state.statements[:index] if is_motion(s)]
        return end_key(before[-1]) if before else self.robot_end()

    def unchanged(self, before: ProgramState) -> None:
        assert self.editor.state is before

    def edited(self, before: ProgramState) -> None:
        self.undo_steps.append((before, self.editor.state))
        self.redo_steps.clear()

    # -------------------------------------------------------------- edits

    def _insert(self, statement: object) -> None:
        fresh = statement.model_copy()
        before = self.editor.state
        expected = expected_insert(before, fresh)
        result = self.editor.insert(fresh)
        if expected is not None:
            assert_refused(result, expected)
            self.unchanged(before)
            return
        assert isinstance(result, ProgramState), result
        i = before.selected
        assert result.statements == (*before.statements[:i], fresh, *before.statements[i:])
        assert result.statements[i] is fresh
        assert result.selected_statement is before.selected_statement  # selection stays put
        if is_motion(fresh):
            self.starts[id(fresh)] = (fresh, self.start_at(before, i))
        self.edited(before)

    @rule(statement=statements)
    def insert(self, statement):
        self._insert(statement)

    def _append(self, statement: object) -> None:
        if self.editor.state.preview is None:
            self.editor.select_empty()
        self._insert(statement)

    @rule(statement=statements)
    def append(self, statement):
        self._append(statement)

    @rule(statement=actions)
    def append_action(self, statement):
        # actions only ever go at the end, so chains of them need a rule of their own to grow
        self._append(statement)

    @rule(data=st.data())
    def select_a_statement(self, data):
        # uniform over the program, so statements in the middle get selected as often as the ends
        state = self.editor.state
        index = data.draw(st.integers(0, len(state.statements)))
        assert self.editor.select(index).selected == index

    @rule()
    def delete(self):
        before = self.editor.state
        event(f"delete: {expected_delete(before)}")
        expected = expected_delete(before)
        result = self.editor.delete()
        if expected is not None:
            assert_refused(result, expected)
            self.unchanged(before)
            return
        assert isinstance(result, ProgramState), result
        i = before.selected
        assert result.statements == before.statements[:i] + before.statements[i + 1 :]
        assert result.selected == i  # the selection moves on to the following statement
        assert result.selected_statement is before.entries[i + 1]
        self.edited(before)

    def _check_modify(self, before: ProgramState, new: object, expected: Rule | None, result: object) -> None:
        if expected is not None:
            assert_refused(result, expected)
            self.unchanged(before)
            return
        assert isinstance(result, ProgramState), result
        i = before.selected
        assert result.selected == i
        assert result.statements[:i] == before.statements[:i]
        assert result.statements[i + 1 :] == before.statements[i + 1 :]
        assert result.statements[i] == new
        old = before.statements[i]
        if is_motion(old):
            # a modified motion must start where the one it replaces started
            self.starts[id(result.statements[i])] = (result.statements[i], self.starts[id(old)][1])
        self.edited(before)

    @rule(data=st.data(), same_kind=st.booleans())
    def modify(self, data, same_kind):
        before = self.editor.state
        selected = before.selected_statement
        if same_kind and not isinstance(selected, EmptyStatement):
            new = data.draw(BY_KIND[selected.kind])
        else:
            new = data.draw(statements)
        new = new.model_copy()
        event(f"modify: {expected_modify(before, new)}")
        self._check_modify(before, new, expected_modify(before, new), self.editor.modify(new))

    @rule(speed=_speeds, until=_untils)
    def modify_conditions(self, speed, until):
        before = self.editor.state
        expected = expected_conditions(before)
        event(f"conditions: {expected}")
        result = self.editor.modify_conditions(speed=speed, until=until)
        new = None
        if expected is None:
            old = before.statements[before.selected]
            new = type(old)(**{**dict(old), "speed": speed, "until": until})
        self._check_modify(before, new, expected, result)

    @rule(data=st.data())
    def submit(self, data):
        before = self.editor.state
        n = len(before.statements)
        start = data.draw(st.sampled_from([0, 0, 0, 1]))
        stop = data.draw(st.integers(0, n + 1))
        expected = expected_submit(before, start, stop)
        event(f"submit: {expected}")
        result = self.editor.submit(start, stop)
        if expected is not None:
            assert_refused(result, expected)
            self.unchanged(before)
            return
        assert isinstance(result, Submission), result
        assert result.statements == before.statements[:stop]
        assert result.state.statements == before.statements[stop:]
        assert self.editor.state is result.state
        if before.selected >= stop:
            assert result.state.selected_statement is before.selected_statement
        else:
            assert result.state.selected == 0
        self.submitted.extend(result.statements)
        self.undo_steps.clear()
        self.redo_steps.clear()

    # -------------------------------------------------------------- not edits

    @rule(index=st.integers(-2, 12))
    def select(self, index):
        before = self.editor.state
        result = self.editor.select(index)
        if 0 <= index <= len(before.statements):
            assert isinstance(result, ProgramState)
            assert result.selected == index
            assert result.statements is before.statements
        else:
            assert_refused(result, Rule.SELECT_RANGE)
            self.unchanged(before)

    @rule(forward=st.booleans())
    def step_selection(self, forward):
        before = self.editor.state
        result = self.editor.select_next() if forward else self.editor.select_previous()
        target = before.selected + (1 if forward else -1)
        if 0 <= target <= len(before.statements):
            assert isinstance(result, ProgramState) and result.selected == target
        else:
            assert_refused(result, Rule.SELECT_RANGE)
            self.unchanged(before)

    @rule(data=st.data())
    def begin_preview(self, data):
        before = self.editor.state
        n = len(before.statements)
        start = data.draw(st.integers(0, n))
        stop = data.draw(st.integers(start, n + 1))
        result = self.editor.begin_preview(start, stop)
        if before.preview is not None:
            assert_refused(result, Rule.PREVIEW_LOCKED)
        elif not 0 <= start < stop <= n:
            assert_refused(result, Rule.PREVIEW_RANGE)
        else:
            assert isinstance(result, PreviewStarted)
            assert result.statements == before.statements[start:stop]
            assert result.state.statements is before.statements
            assert result.state.selected == before.selected
            return
        self.unchanged(before)

    @rule()
    def end_preview(self):
        before = self.editor.state
        result = self.editor.end_preview()
        if before.preview is None:
            assert_refused(result, Rule.PREVIEW_INACTIVE)
            self.unchanged(before)
        else:
            assert isinstance(result, ProgramState) and result.preview is None
            assert result.statements is before.statements and result.selected == before.selected

    # -------------------------------------------------------------- history

    @rule()
    def undo(self):
        before = self.editor.state
        result = self.editor.undo()
        if before.preview is not None:
            assert_refused(result, Rule.PREVIEW_LOCKED)
        elif not self.undo_steps:
            assert_refused(result, Rule.UNDO_SUBMITTED if self.submitted else Rule.UNDO_NOTHING)
        else:
            step = self.undo_steps.pop()
            assert result == step[0]  # exactly the state before the edit, selection included
            assert self.editor.state == step[0]
            self.redo_steps.append(step)
            return
        self.unchanged(before)

    @rule()
    def redo(self):
        before = self.editor.state
        result = self.editor.redo()
        if before.preview is not None:
            assert_refused(result, Rule.PREVIEW_LOCKED)
        elif not self.redo_steps:
            assert_refused(result, Rule.REDO_NOTHING)
        else:
            step = self.redo_steps.pop()
            assert result == step[1]  # exactly the state right after the edit
            assert self.editor.state == step[1]
            self.undo_steps.append(step)
            return
        self.unchanged(before)

    # -------------------------------------------------------------- invariants

    @invariant()
    def one_trailing_empty_statement(self):
        entries = self.editor.state.entries
        assert isinstance(entries[-1], EmptyStatement)
        assert sum(isinstance(e, EmptyStatement) for e in entries) == 1
        assert all(is_action(e) or is_parameter(e) or is_task(e) for e in entries[:-1])

    @invariant()
    def nothing_moves_after_a_task_with_an_unknown_end(self):
        statements = self.editor.state.statements
        for i, s in enumerate(statements):
            if ends_unknown(s):
                assert not any(is_motion(later) for later in statements[i + 1 :])

    @invariant()
    def selection_in_range(self):
        state = self.editor.state
        assert 0 <= state.selected <= len(state.statements)

    @invariant()
    def continuity(self):
        end = self.robot_end()
        for index, statement in enumerate(self.editor.state.statements):
            if not is_motion(statement):
                continue
            recorded = self.starts[id(statement)]
            assert recorded[0] is statement
            assert recorded[1] == end, f"statement {index + 1} no longer starts where it was made to start"
            end = end_key(statement)


TestEditorMachine = EditorMachine.TestCase
TestEditorMachine.settings = settings(
    max_examples=150, stateful_step_count=40, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


# ------------------------------------------------------------------ one scenario per rule

D1 = Draw(position=(0.1, 0.0, 0.2))
D2 = Draw(position=(0.2, 0.0, 0.2))
R1 = Rotate(rpy=(0.0, 0.5, 0.0))
SPD = SetSpeed(speed=Speed(value=0.5, unit=SpeedUnit.FRACTION))
MODE = SetMode(mode=Mode.FORCE)
EV = Event(name="reached")
TASK = TaskCall(name="insert_peg", args=("PEG", "HOLE1"))


def editor_with(*statements, selected: int | None = None) -> Editor:
    return Editor(ProgramState.of(statements, selected), strict=True)


def _previewing(editor: Editor) -> Editor:
    assert isinstance(editor.begin_preview(0, 2), PreviewStarted)
    return editor


def _after_submit(editor: Editor) -> Editor:
    unwrap(editor.submit(0, 1))
    return editor


SCENARIOS: dict[Rule, Callable[[], object]] = {
    Rule.SELECT_RANGE: lambda: editor_with(D1).select(2),
    Rule.PREVIEW_LOCKED: lambda: _previewing(editor_with(D1, SPD, selected=1)).delete(),
    Rule.PREVIEW_RANGE: lambda: editor_with(D1).begin_preview(0, 2),
    Rule.PREVIEW_INACTIVE: lambda: editor_with(D1).end_preview(),
    Rule.INSERT_REAL: lambda: editor_with(D1).insert(EMPTY),
    Rule.INSERT_ACTION_AT_END: lambda: editor_with(D1, SPD, selected=1).insert(D2),
    Rule.INSERT_TASK_AT_END: lambda: editor_with(D1, SPD, selected=1).insert(TASK),
    Rule.INSERT_AFTER_TASK: lambda: editor_with(D1, TASK).insert(D2),
    Rule.DELETE_EMPTY: lambda: editor_with(D1).delete(),
    Rule.DELETE_ACTION_NOT_LAST: lambda: editor_with(D1, D2, selected=0).delete(),
    Rule.MODIFY_EMPTY: lambda: editor_with(D1).modify(D2),
    Rule.MODIFY_TASK: lambda: editor_with(D1, TASK, selected=1).modify(TaskCall(name="grasp")),
    Rule.MODIFY_KIND: lambda: editor_with(D1, selected=0).modify(R1),
    Rule.MODIFY_ACTION_PARAMETERS: lambda: editor_with(D1, D2, selected=0).modify(Draw(position=(0.3, 0.0, 0.2))),
    Rule.MODIFY_CONDITIONS_NOT_ACTION: lambda: editor_with(D1, SPD, selected=1).modify_conditions(until=UntilContact()),
    Rule.SUBMIT_RANGE: lambda: editor_with(D1, D2).submit(0, 3),
    Rule.SUBMIT_PREFIX: lambda: editor_with(D1, D2).submit(1, 2),
    Rule.UNDO_NOTHING: lambda: Editor().undo(),
    Rule.UNDO_SUBMITTED: lambda: _after_submit(editor_with(D1, D2)).undo(),
    Rule.REDO_NOTHING: lambda: editor_with(D1).redo(),
    Rule.MOVE_RANGE: lambda: editor_with(D1, D2, selected=0).move_statements(-1),
    Rule.MOVE_MOTION: lambda: editor_with(D1, D2, selected=0).move_statements(1),
    # free editing (the default): refused only where the result cannot run
    Rule.EDIT_AFTER_TASK: lambda: Editor(ProgramState.of((D1, TASK, SPD), selected=2)).modify(D2),
    Rule.EDIT_TASK_STATE: lambda: Editor(ProgramState.of((GRASP, D1, EXTRACT), selected=0)).delete(),
}
GRASP = TaskCall(name="grasp", args=("peg",))
EXTRACT = TaskCall(name="extract_peg", args=("peg", "HOLE1"))
CONSOLE_RULES = {Rule.PROGRAM_AFTER_TASK, Rule.EDIT_PATH}
"""Rules a whole program or the console's re-planning applies, not one editor operation alone."""


@pytest.mark.parametrize("rule_", [r for r in Rule if r not in CONSOLE_RULES], ids=lambda r: r.value)
def test_each_rule_refuses_with_its_id(rule_: Rule) -> None:
    assert rule_ in SCENARIOS, f"no scenario exercises rule {rule_.value}"
    assert_refused(SCENARIOS[rule_](), rule_)


def test_a_program_that_moves_the_arm_after_an_unknown_end_is_rejected() -> None:
    (violation,) = program_violations([D1, TASK, SPD, D2])
    assert violation.rule is Rule.PROGRAM_AFTER_TASK
    assert violation.index == 3  # the DRAW; the SPEED before it leaves the arm where it is
    assert "DRAW cannot follow TASK insert_peg (statement 2)" in violation.message
    assert program_violations([D1, SPD, TASK]) == []
    assert program_violations([TASK, EV, TaskCall(name="release"), MODE]) == []  # what keeps the arm still may follow
    with pytest.raises(InputError, match="cannot follow TASK insert_peg"):
        ProgramState.of([TASK, TaskCall(name="extract_peg", args=("peg", "HOLE2"))])


def test_after_a_task_with_a_known_end_anything_may_follow() -> None:
    grasp, extract = TaskCall(name="grasp", args=("peg",)), TaskCall(name="extract_peg", args=("peg", "HOLE1"))
    editor = Editor(strict=True)
    for statement in (D1, grasp, extract, D2, EV, TASK, TaskCall(name="release"), MODE):
        unwrap(editor.insert(statement))
    assert editor.state.unknown_pose is not None and editor.state.unknown_pose.task == "insert_peg"
    assert_refused(editor.insert(D1), Rule.INSERT_AFTER_TASK)
    assert_refused(editor.insert(extract), Rule.INSERT_AFTER_TASK)
    unwrap(editor.select(3))  # extract_peg moves the arm and the DRAW after it starts where it ends
    assert_refused(editor.delete(), Rule.DELETE_ACTION_NOT_LAST)


# ------------------------------------------------------------------ the rules, one behaviour at a time


def test_new_program_is_one_selected_empty_statement() -> None:
    state = ProgramState()
    assert state.entries == (EMPTY,)
    assert state.selected == 0 and state.selected_statement is EMPTY


def test_insert_goes_before_the_selection_and_keeps_it() -> None:
    editor = Editor(strict=True)
    unwrap(editor.insert(D1))
    unwrap(editor.insert(D2))
    assert editor.state.statements == (D1, D2)
    assert editor.state.selected_statement is EMPTY
    unwrap(editor.select(1))
    unwrap(editor.insert(SPD))  # parameter statements go anywhere
    assert editor.state.statements == (D1, SPD, D2)
    assert editor.state.selected_statement == D2


def test_parameters_may_go_anywhere_around_a_task_but_no_motion_after_an_unknown_end() -> None:
    editor = editor_with(D1, TASK)
    assert_refused(editor.insert(D2), Rule.INSERT_AFTER_TASK)
    unwrap(editor.insert(SPD))  # a parameter leaves the arm where the task left it
    unwrap(editor.select(1))
    unwrap(editor.insert(MODE))
    assert editor.state.statements == (D1, MODE, TASK, SPD)


def test_delete_moves_selection_to_the_next_statement() -> None:
    editor = editor_with(SPD, D1, EV, D2, selected=0)
    state = unwrap(editor.delete())
    assert state.statements == (D1, EV, D2) and state.selected_statement == D1
    unwrap(editor.select(1))
    state = unwrap(editor.delete())  # a parameter in the middle
    assert state.statements == (D1, D2) and state.selected_statement == D2
    state = unwrap(editor.delete())  # the last action
    assert state.statements == (D1,) and state.selected_statement is EMPTY


def test_last_action_behind_a_parameter_is_not_just_before_the_empty_statement() -> None:
    editor = editor_with(D1, SPD, selected=0)
    assert_refused(editor.delete(), Rule.DELETE_ACTION_NOT_LAST)
    assert_refused(editor.modify(D2), Rule.MODIFY_ACTION_PARAMETERS)


def test_task_call_before_the_empty_statement_can_be_deleted() -> None:
    editor = editor_with(D1, TASK, selected=1)
    assert unwrap(editor.delete()).statements == (D1,)


def test_conditions_change_anywhere_parameters_only_on_the_last_action() -> None:
    editor = editor_with(D1, D2, selected=0)
    speed = Speed(value=0.02, unit=SpeedUnit.M_PER_S)
    state = unwrap(editor.modify_conditions(speed=speed, until=UntilForce(newtons=5.0)))
    assert state.statements[0] == Draw(position=D1.position, speed=speed, until=UntilForce(newtons=5.0))
    state = unwrap(editor.modify_conditions(until=None))  # speed kept, condition cleared
    assert state.statements[0].speed == speed and state.statements[0].until is None
    assert state.selected == 0
    unwrap(editor.select(1))
    state = unwrap(editor.modify(Draw(position=(0.5, 0.5, 0.5))))
    assert state.statements[1].position == (0.5, 0.5, 0.5)


def test_parameter_statements_can_be_modified_anywhere() -> None:
    editor = editor_with(SPD, D1, D2, selected=0)
    new = SetSpeed(speed=Speed(value=0.1, unit=SpeedUnit.FRACTION))
    assert unwrap(editor.modify(new)).statements == (new, D1, D2)


def test_submission_takes_a_prefix_out_and_keeps_the_selection() -> None:
    editor = editor_with(D1, SPD, D2, EV, selected=3)
    submission = unwrap(editor.submit(0, 2))
    assert submission.statements == (D1, SPD)
    assert editor.state.statements == (D2, EV)
    assert editor.state.selected_statement == EV
    submission = unwrap(editor.submit_through(0))
    assert submission.statements == (D2,)
    assert editor.state.statements == (EV,) and editor.state.selected_statement == EV


def test_submitting_the_selected_statement_selects_the_first_left() -> None:
    editor = editor_with(D1, SPD, D2, selected=0)
    unwrap(editor.submit(0, 2))
    assert editor.state.selected == 0 and editor.state.selected_statement == D2


def test_preview_locks_everything_but_selection() -> None:
    editor = editor_with(D1, SPD, D2)
    started = unwrap(editor.begin_preview(1, 3))
    assert started.statements == (SPD, D2)
    attempts = (editor.insert(EV), editor.delete(), editor.modify(D2), editor.submit(0, 1), editor.undo(), editor.redo())
    for refused in attempts:
        assert_refused(refused, Rule.PREVIEW_LOCKED)
    assert unwrap(editor.select(0)).selected == 0
    assert unwrap(editor.end_preview()).statements == (D1, SPD, D2)
    unwrap(editor.insert(EV))


def test_undo_and_redo_walk_the_history_exactly() -> None:
    editor = Editor(strict=True)
    s1 = unwrap(editor.insert(D1))
    s2 = unwrap(editor.insert(SPD))
    unwrap(editor.select(0))  # not an edit: not recorded
    s3 = unwrap(editor.modify_conditions(until=UntilTime(seconds=2.0)))
    unwrap(editor.select(1))
    s4 = unwrap(editor.delete())
    assert editor.undo_label == "delete SPEED"
    before_delete = s3.select(1)
    assert unwrap(editor.undo()) == before_delete  # the selection as it was when the delete was done
    assert unwrap(editor.undo()) == s2.select(0)
    assert unwrap(editor.undo()) == s1
    assert unwrap(editor.undo()) == ProgramState()
    assert_refused(editor.undo(), Rule.UNDO_NOTHING)
    assert unwrap(editor.redo()) == s1
    assert unwrap(editor.redo()) == s2
    assert unwrap(editor.redo()) == s3
    assert unwrap(editor.redo()) == s4
    assert s4.statements == (D1.model_copy(update={"until": UntilTime(seconds=2.0)}),)
    assert not editor.can_redo


def test_a_new_edit_drops_the_redo_history() -> None:
    editor = Editor(strict=True)
    unwrap(editor.insert(D1))
    unwrap(editor.undo())
    unwrap(editor.insert(D2))
    assert_refused(editor.redo(), Rule.REDO_NOTHING)
    assert editor.state.statements == (D2,)


def test_unwrap_raises_an_input_error_naming_the_rule() -> None:
    with pytest.raises(RefusedError, match="delete.empty") as caught:
        unwrap(Editor().delete())
    assert isinstance(caught.value, InputError)
    assert caught.value.refusal.rule is Rule.DELETE_EMPTY


def test_state_is_immutable_and_operations_leave_it_alone() -> None:
    state = ProgramState.of([D1])
    new = state.insert(SPD)
    assert isinstance(new, ProgramState)
    assert state.statements == (D1,) and state.selected == 1
    with pytest.raises(AttributeError):
        state.selected = 0  # type: ignore[misc]


@pytest.mark.parametrize("bad", [[EMPTY], [D1, "MOVE"]])
def test_a_program_of_non_statements_is_rejected(bad) -> None:
    with pytest.raises(InputError):
        ProgramState.of(bad)


def test_selection_out_of_range_is_rejected_at_construction() -> None:
    with pytest.raises(InputError):
        ProgramState.of([D1], selected=2)
