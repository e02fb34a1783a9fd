"""Generation writes what the operator meant (issue 16, finding 5): a segment that goes on the
way the previous statement went continues it (one straight stroke is one DRAW, one slider drag
one DRIVE), and Cartesian targets are written in the frame the operator jogs in."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shared.errors import InputError
from shared.language.statements import Frame
from shared.program.generator import (
    Generated,
    GeneratorSettings,
    JogMode,
    ProgramGenerator,
    RobotSample,
    generate_program,
    merged,
)
from shared.spatial import (
    exp_so3,
    invert,
    make_transform,
    rotation_angle,
    rpy_to_matrix,
)

DT = 0.01
Q0 = np.radians([10.0, -40.0, 170.0, 5.0, 40.0, -10.0])
R0 = rpy_to_matrix([0.1, -0.2, 0.3])
P0 = np.array([0.45, -0.10, 0.30])
TEXT_MM = 0.5e-4 + 1e-12  # the text's 0.1 mm, half a step of rounding


def hold(value, n: int) -> np.ndarray:
    return np.repeat(np.asarray(value, dtype=float)[None], n, axis=0)


def ramp(a, b, n: int) -> np.ndarray:
    s = np.arange(1, n + 1)[:, None] / n
    return np.asarray(a, float)[None] + s * (np.asarray(b, float) - np.asarray(a, float))[None]


def tool_stream(ps, rs=None, t0: float = 0.0) -> list[RobotSample]:
    rs = hold(R0, len(ps)) if rs is None else rs
    return [RobotSample(t0 + i * DT, Q0, JogMode.TOOL, base_T_tool=make_transform(r, p)) for i, (p, r) in enumerate(zip(ps, rs))]


def joint_stream(qs, t0: float = 0.0) -> list[RobotSample]:
    return [RobotSample(t0 + i * DT, q, JogMode.JOINT) for i, q in enumerate(qs)]


def pushed(gen: ProgramGenerator, samples) -> list[Generated]:
    out = [g for s in samples for g in gen.push(s)]
    return out + gen.finish()


def test_a_straight_stroke_with_pauses_is_one_draw_to_its_end() -> None:
    a, b, c = P0 + [0.04, 0, 0], P0 + [0.07, 0, 0], P0 + [0.12, 0, 0]
    ps = np.concatenate([hold(P0, 20), ramp(P0, a, 80), hold(a, 40), ramp(a, b, 60), hold(b, 40), ramp(b, c, 100), hold(c, 20)])
    generated = pushed(ProgramGenerator(), tool_stream(ps))
    # segmentation alone cuts it at each pause; the later pieces continue the first
    assert [g.statement.kind for g in generated] == ["DRAW", "DRAW", "DRAW"]
    assert [g.continues for g in generated] == [False, True, True]
    program = merged(generated)
    assert len(program) == 1
    np.testing.assert_allclose(program[0].position, c, atol=TEXT_MM)


def test_speed_changes_cut_pieces_that_merge_back_into_one_draw() -> None:
    s = np.linspace(0.0, 1.0, 200)
    p1 = P0 + np.array([0.1, -0.05, 0.0])
    ps = np.concatenate([hold(P0, 20), P0 + (10 * s**3 - 15 * s**4 + 6 * s**5)[:, None] * (p1 - P0), hold(p1, 20)])
    literal = GeneratorSettings(split_on_speed_change=True)
    assert len(generate_program(tool_stream(ps), literal)) > 1  # the literal thesis test cuts it
    program = generate_program(tool_stream(ps), literal, merge=True)
    assert [st.kind for st in program] == ["DRAW"]
    np.testing.assert_allclose(program[0].position, p1, atol=0.0001)


def test_a_corner_or_a_reversal_is_not_merged() -> None:
    a, corner = P0 + [0.05, 0, 0], P0 + [0.05, 0.05, 0]
    ps = np.concatenate([hold(P0, 20), ramp(P0, a, 80), hold(a, 40), ramp(a, corner, 80), hold(corner, 20)])
    assert len(generate_program(tool_stream(ps), merge=True)) == 2
    back = P0 + [0.02, 0, 0]
    ps = np.concatenate([hold(P0, 20), ramp(P0, a, 80), hold(a, 40), ramp(a, back, 80), hold(back, 20)])
    program = generate_program(tool_stream(ps), merge=True)
    assert len(program) == 2
    np.testing.assert_allclose(program[1].position, back, atol=TEXT_MM)


def test_a_stroke_that_bends_beyond_the_tolerance_stays_two_draws() -> None:
    a = P0 + [0.05, 0, 0]
    end = P0 + [0.10, 0.006, 0]  # the first target is 3 mm off the line from the start to here
    ps = np.concatenate([hold(P0, 20), ramp(P0, a, 80), hold(a, 40), ramp(a, end, 80), hold(end, 20)])
    assert len(generate_program(tool_stream(ps), merge=True)) == 2
    assert len(generate_program(tool_stream(ps), GeneratorSettings(merge_tolerance=0.004), merge=True)) == 1


def test_a_joint_dragged_in_steps_is_one_drive_and_another_joint_is_not_merged() -> None:
    q1, q2 = Q0.copy(), Q0.copy()
    q1[5] += math.radians(8.0)
    q2[5] += math.radians(3.0)  # back a little: the joint's own target, still the same joint
    q3 = q2.copy()
    q3[4] += math.radians(6.0)
    qs = np.concatenate([hold(Q0, 10), ramp(Q0, q1, 50), hold(q1, 30), ramp(q1, q2, 40), hold(q2, 30), ramp(q2, q3, 40), hold(q3, 10)])
    generated = pushed(ProgramGenerator(), joint_stream(qs))
    assert [(g.statement.joint, g.continues) for g in generated] == [(6, False), (6, True), (5, False)]
    program = merged(generated)
    assert [(st.kind, st.joint) for st in program] == [("DRIVE", 6), ("DRIVE", 5)]
    assert program[0].target == pytest.approx(q2[5], abs=1e-5)


def test_a_turn_about_one_axis_in_steps_is_one_rotate() -> None:
    axis = np.array([0.0, 0.0, 1.0])
    angles = np.concatenate([np.zeros(10), np.linspace(0, 0.3, 60)[1:], np.full(30, 0.3), np.linspace(0.3, 0.6, 60)[1:], np.full(20, 0.6)])
    rs = np.stack([exp_so3(axis * a) @ R0 for a in angles])
    program = generate_program(tool_stream(hold(P0, len(rs)), rs), merge=True)
    assert [st.kind for st in program] == ["ROTATE"]
    assert rotation_angle(rpy_to_matrix(program[0].rpy) @ R0.T) == pytest.approx(0.6, abs=math.radians(0.1))  # three angles at 0.1 deg


def test_a_later_stroke_along_the_same_line_continues_the_earlier_one() -> None:
    gen = ProgramGenerator()
    a, b = P0 + [0, 0, 0.04], P0 + [0, 0, 0.09]
    first = pushed(gen, tool_stream(np.concatenate([hold(P0, 10), ramp(P0, a, 60), hold(a, 10)])))
    second = pushed(gen, tool_stream(np.concatenate([ramp(a, b, 60), hold(b, 10)]), t0=2.0))
    assert [g.continues for g in first + second] == [False, True]


W_T_BASE = make_transform(rpy_to_matrix([0.0, 0.0, math.pi / 2]), np.array([0.1, 0.2, 0.7]))
W_T_WORK = make_transform(rpy_to_matrix([0.0, 0.0, -0.3]), np.array([0.6, -0.1, 0.75]))


def test_targets_follow_the_frame_the_operator_chooses() -> None:
    gen = ProgramGenerator(world_T_base=W_T_BASE, world_T_work=W_T_WORK)
    a, b = P0 + [0.05, 0, 0], P0 + [0.10, 0, 0]
    first = pushed(gen, tool_stream(np.concatenate([hold(P0, 10), ramp(P0, a, 60), hold(a, 10)])))
    assert gen.set_frame("WORK") == []  # nothing open
    second = pushed(gen, tool_stream(np.concatenate([ramp(a, b, 60), hold(b, 10)]), t0=2.0))
    assert [(g.statement.frame, g.continues) for g in first + second] == [(Frame.BASE, False), (Frame.WORK, False)]
    work_p = (invert(W_T_WORK) @ W_T_BASE @ make_transform(R0, b))[:3, 3]
    np.testing.assert_allclose(second[0].statement.position, work_p, atol=TEXT_MM)
    # the program state moved with the frame: a rotation-free stroke writes no ROTATE
    assert [g.statement.kind for g in second] == ["DRAW"]
    gen.set_frame(Frame.WORLD)
    c = b + [0, 0.03, 0]
    third = pushed(gen, tool_stream(np.concatenate([ramp(b, c, 60), hold(c, 10)]), t0=4.0))
    np.testing.assert_allclose(third[0].statement.position, (W_T_BASE @ make_transform(R0, c))[:3, 3], atol=TEXT_MM)


def test_changing_frame_mid_stroke_closes_the_open_segment_in_the_old_frame() -> None:
    gen = ProgramGenerator(world_T_base=W_T_BASE, world_T_work=W_T_WORK)
    a = P0 + [0.05, 0, 0]
    for s in tool_stream(np.concatenate([hold(P0, 10), ramp(P0, a, 60)])):
        gen.push(s)
    closed = gen.set_frame(Frame.WORK)
    assert [(g.statement.kind, g.statement.frame) for g in closed] == [("DRAW", Frame.BASE)]


def test_a_frame_the_generator_cannot_write_is_refused_with_its_name() -> None:
    with pytest.raises(InputError, match="TOOL"):
        ProgramGenerator().set_frame(Frame.TOOL)
    gen = ProgramGenerator()  # no transforms: BASE only
    pushed(gen, tool_stream(np.concatenate([hold(P0, 10), ramp(P0, P0 + [0.05, 0, 0], 60)])))
    with pytest.raises(InputError, match="WORK"):
        gen.set_frame("WORK")
