"""Automatic generation (thesis 4.2.2, 4.3.5): synthetic motions give the statements the rules
call for, jitter gives none, and a motion recorded by jogging the real PUMA 562 gives statements
whose targets are where the arm went.

Re-record the PUMA stream with ``.venv/bin/python tests/program/test_generator.py``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.errors import InputError
from shared.language.statements import Draw, Drive, Frame, Move, Moves, Rotate
from shared.language.formatter import format_statement
from shared.program.generator import (
    GeneratorSettings,
    JogMode,
    ProgramGenerator,
    RobotSample,
    generate_program,
)
from shared.spatial import exp_so3, make_transform, pose_to_transform, rotation_angle, rpy_to_matrix

RATE = 100.0
DT = 1.0 / RATE
DATA = Path(__file__).parent / "data" / "puma_jog_100hz.npz"
# generated statements hold what their text shows: 0.1 mm and 0.1 deg, the resolution the operator
# controls (half a step of rounding)
POSITION_TEXT = 0.5e-4 + 1e-12
ANGLE_TEXT = math.radians(0.05) + 1e-12
Q0 = np.radians([10.0, -40.0, 170.0, 5.0, 40.0, -10.0])
R0 = rpy_to_matrix([0.1, -0.2, 0.3])
P0 = np.array([0.45, -0.10, 0.30])


# -- synthetic streams ------------------------------------------------------------------------
def times(duration: float, start: float = 0.0) -> np.ndarray:
    return start + np.arange(int(round(duration * RATE))) * DT


def joint_stream(qs: np.ndarray, t0: float = 0.0) -> list[RobotSample]:
    return [RobotSample(t0 + i * DT, q, JogMode.JOINT) for i, q in enumerate(qs)]


def tool_stream(ps: np.ndarray, rs: np.ndarray, t0: float = 0.0, q: np.ndarray = Q0) -> list[RobotSample]:
    return [RobotSample(t0 + i * DT, q, JogMode.TOOL, base_T_tool=make_transform(r, p)) for i, (p, r) in enumerate(zip(ps, rs))]


def hold(value: np.ndarray, n: int) -> np.ndarray:
    return np.repeat(np.asarray(value, dtype=float)[None], n, axis=0)


def ramp(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """``n`` samples moving at constant velocity from just after ``a`` to ``b``."""
    s = np.arange(1, n + 1)[:, None] / n
    return np.asarray(a, float)[None] + s * (np.asarray(b, float) - np.asarray(a, float))[None]


def path(*pieces: np.ndarray) -> np.ndarray:
    return np.concatenate(pieces, axis=0)


def rotations_about(axis: np.ndarray, angles: np.ndarray, start: np.ndarray = R0) -> np.ndarray:
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.stack([exp_so3(axis * a) @ start for a in angles])


def kinds(statements) -> list[str]:
    return [s.kind for s in statements]


# -- joint mode -------------------------------------------------------------------------------
def test_single_joint_sweep_is_one_drive() -> None:
    q1 = Q0.copy()
    q1[2] += math.radians(30.0)
    qs = path(hold(Q0, 50), ramp(Q0, q1, 200), hold(q1, 50))
    out = generate_program(joint_stream(qs))
    assert kinds(out) == ["DRIVE"]
    assert isinstance(out[0], Drive) and out[0].joint == 3
    assert out[0].target == pytest.approx(q1[2], abs=ANGLE_TEXT)


def test_multi_joint_motion_is_one_move_keeping_untouched_joints() -> None:
    rng = np.random.default_rng(3)
    q1 = Q0 + np.radians([20.0, -15.0, 0.0, 0.0, 10.0, 0.0])
    qs = path(hold(Q0, 30), ramp(Q0, q1, 150), hold(q1, 30))
    qs = qs + rng.normal(0.0, math.radians(0.02), qs.shape)  # encoder-level jitter on every joint
    out = generate_program(joint_stream(qs))
    assert kinds(out) == ["MOVE"] and isinstance(out[0], Move)
    joints = np.array(out[0].joints)
    np.testing.assert_allclose(joints[[0, 1, 4]], q1[[0, 1, 4]], atol=math.radians(0.1))
    # joints that did not change keep the program's starting values: no jitter leaks in
    np.testing.assert_allclose(joints[[2, 3, 5]], qs[0][[2, 3, 5]], atol=ANGLE_TEXT)


def test_one_joint_then_another_without_stopping_gives_two_drives() -> None:
    q1 = Q0.copy()
    q1[0] += math.radians(20.0)
    q2 = q1.copy()
    q2[1] -= math.radians(15.0)
    qs = path(hold(Q0, 20), ramp(Q0, q1, 100), ramp(q1, q2, 100), hold(q2, 20))
    out = generate_program(joint_stream(qs))
    assert kinds(out) == ["DRIVE", "DRIVE"]
    assert (out[0].joint, out[1].joint) == (1, 2)
    assert out[0].target == pytest.approx(q1[0], abs=math.radians(0.3))
    assert out[1].target == pytest.approx(q2[1], abs=ANGLE_TEXT)


# -- tool mode --------------------------------------------------------------------------------
def test_straight_tool_line_is_one_draw() -> None:
    p1 = P0 + np.array([0.08, 0.03, -0.02])
    ps = path(hold(P0, 30), ramp(P0, p1, 180), hold(p1, 30))
    out = generate_program(tool_stream(ps, hold(R0, len(ps)).reshape(-1, 3, 3)))
    assert kinds(out) == ["DRAW"]
    assert out[0].frame is Frame.BASE
    np.testing.assert_allclose(out[0].position, p1, atol=POSITION_TEXT)


def test_a_pure_x_drag_writes_round_numbers_without_the_iks_hundredths() -> None:
    """The tool's y and z wobble by a few hundredths of a millimetre (the IK's noise) during a
    pure-x drag: the text holds the 0.1 mm the operator controls, so y and z read as they started."""
    start = np.array([0.6535, 0.0, 0.49])
    end = start + np.array([0.05, 0.0, 0.0])
    ps = path(hold(start, 30), ramp(start, end, 180), hold(end, 30))
    wobble = np.zeros_like(ps)
    wobble[:, 1] = 0.04e-3 * np.sin(np.arange(len(ps)))
    wobble[:, 2] = -0.03e-3 * np.cos(np.arange(len(ps)))
    out = generate_program(tool_stream(ps + wobble, hold(R0, len(ps)).reshape(-1, 3, 3)))
    assert kinds(out) == ["DRAW"]
    assert format_statement(out[0]) == "DRAW TO (703.5, 0, 490) mm IN BASE"


def test_pure_rotation_is_one_rotate() -> None:
    angles = np.concatenate([np.zeros(30), np.linspace(0.0, math.radians(45.0), 200)[1:], np.full(30, math.radians(45.0))])
    rs = rotations_about([0.3, -0.5, 0.8], angles)
    out = generate_program(tool_stream(hold(P0, len(rs)), rs))
    assert kinds(out) == ["ROTATE"]
    assert rotation_angle(rpy_to_matrix(out[0].rpy).T @ rs[-1]) < 3 * ANGLE_TEXT


def test_a_long_turn_is_cut_so_each_rotate_is_less_than_half_a_turn() -> None:
    angles = np.concatenate([np.zeros(20), np.linspace(0.0, math.radians(320.0), 641)[1:], np.full(20, math.radians(320.0))])
    rs = rotations_about([0.0, 0.0, 1.0], angles)
    out = generate_program(tool_stream(hold(P0, len(rs)), rs))
    assert kinds(out) == ["ROTATE", "ROTATE", "ROTATE"]
    previous = rs[0]
    for statement in out:
        target = rpy_to_matrix(statement.rpy)
        assert 0.0 < rotation_angle(previous.T @ target) <= math.radians(150.5) + 3 * ANGLE_TEXT  # cut within a sample
        previous = target
    assert rotation_angle(previous.T @ rs[-1]) < 3 * ANGLE_TEXT


def test_position_and_orientation_together_is_one_moves() -> None:
    n = 150
    p1 = P0 + np.array([0.0, 0.06, 0.04])
    angles = np.linspace(0.0, math.radians(30.0), n + 1)[1:]
    ps = path(hold(P0, 20), ramp(P0, p1, n), hold(p1, 20))
    rs = np.concatenate([hold(R0, 20).reshape(-1, 3, 3), rotations_about([1, 0, 0], angles), hold(rotations_about([1, 0, 0], angles[-1:])[0], 20).reshape(-1, 3, 3)])
    out = generate_program(tool_stream(ps, rs))
    assert kinds(out) == ["MOVES"] and isinstance(out[0], Moves)
    np.testing.assert_allclose(out[0].position, p1, atol=POSITION_TEXT)
    assert rotation_angle(rpy_to_matrix(out[0].rpy).T @ rs[-1]) < 3 * ANGLE_TEXT


def test_line_then_turn_splits_at_the_corner_while_streaming() -> None:
    corner = P0 + np.array([0.10, 0.0, 0.0])
    end = corner + np.array([0.0, 0.08, 0.0])
    ps = path(hold(P0, 20), ramp(P0, corner, 200), ramp(corner, end, 160), hold(end, 30))  # 50 mm/s, no stop
    samples = tool_stream(ps, hold(R0, len(ps)).reshape(-1, 3, 3))
    gen = ProgramGenerator()
    emitted: list[tuple[float, object]] = []
    for s in samples:
        emitted.extend((s.t, st_) for st_ in gen.feed(s))
    emitted.extend((math.inf, st_) for st_ in gen.flush())
    assert [e[1].kind for e in emitted] == ["DRAW", "DRAW"]
    np.testing.assert_allclose(emitted[0][1].position, corner, atol=0.0015)
    np.testing.assert_allclose(emitted[1][1].position, end, atol=POSITION_TEXT)
    t_corner = (20 + 200 - 1) * DT
    assert emitted[0][0] < t_corner + 0.3  # handed out online, shortly after the corner
    assert gen.segments[0].reason == "departure"
    assert gen.segments[0].t_end == pytest.approx(t_corner, abs=0.03)


def test_line_then_rotation_gives_draw_then_rotate() -> None:
    p1 = P0 + np.array([0.0, 0.0, 0.07])
    angles = np.linspace(0.0, math.radians(40.0), 161)[1:]
    ps = path(hold(P0, 20), ramp(P0, p1, 140), hold(p1, 160 + 20))
    rs = np.concatenate([hold(R0, 160).reshape(-1, 3, 3), rotations_about([0, 0, 1], angles), hold(rotations_about([0, 0, 1], angles[-1:])[0], 20).reshape(-1, 3, 3)])
    out = generate_program(tool_stream(ps, rs))
    assert kinds(out) == ["DRAW", "ROTATE"]
    np.testing.assert_allclose(out[0].position, p1, atol=0.0015)
    assert rotation_angle(rpy_to_matrix(out[1].rpy).T @ rs[-1]) < 3 * ANGLE_TEXT


def test_a_stop_closes_a_segment() -> None:
    mid = P0 + np.array([0.05, 0.0, 0.0])
    end = mid + np.array([0.05, 0.0, 0.0])
    ps = path(hold(P0, 20), ramp(P0, mid, 100), hold(mid, 40), ramp(mid, end, 100), hold(end, 20))
    gen = ProgramGenerator()
    out = gen.generate(tool_stream(ps, hold(R0, len(ps)).reshape(-1, 3, 3)))
    assert kinds(out) == ["DRAW", "DRAW"]
    np.testing.assert_allclose(out[0].position, mid, atol=POSITION_TEXT)
    first = gen.segments[0]
    assert first.reason == "stop"
    assert first.t_start == pytest.approx(19 * DT, abs=0.025)  # motion starts after sample 19
    assert first.t_end == pytest.approx(119 * DT, abs=0.025)  # and reaches ``mid`` at sample 119


def test_smooth_acceleration_along_a_line_stays_one_draw() -> None:
    """An operator does not move at constant speed: a minimum-jerk stroke (speed rising from 0
    and falling back) is one straight line, so one DRAW; the literal thesis test cuts it."""
    s = np.linspace(0.0, 1.0, 200)
    p1 = P0 + np.array([0.1, -0.05, 0.0])
    ps = path(hold(P0, 20), P0 + (10 * s**3 - 15 * s**4 + 6 * s**5)[:, None] * (p1 - P0), hold(p1, 20))
    samples = tool_stream(ps, hold(R0, len(ps)))
    out = generate_program(samples)
    assert kinds(out) == ["DRAW"]
    np.testing.assert_allclose(out[0].position, p1, atol=0.0001)  # the stop is seen in the creeping tail
    assert len(generate_program(samples, GeneratorSettings(split_on_speed_change=True))) > 1


def test_reversing_along_the_same_line_gives_two_draws() -> None:
    far = P0 + np.array([0.08, 0.0, 0.0])
    back = P0 + np.array([0.03, 0.0, 0.0])
    ps = path(hold(P0, 20), ramp(P0, far, 160), ramp(far, back, 100), hold(back, 20))
    out = generate_program(tool_stream(ps, hold(R0, len(ps))))
    assert kinds(out) == ["DRAW", "DRAW"]
    np.testing.assert_allclose(out[0].position, far, atol=0.0015)
    np.testing.assert_allclose(out[1].position, back, atol=POSITION_TEXT)


def test_flush_keeps_the_program_state_and_feeding_goes_on() -> None:
    q1 = Q0.copy()
    q1[4] += math.radians(10.0)
    q2 = q1.copy()
    q2[5] += math.radians(10.0)
    gen = ProgramGenerator()
    first = [s for x in joint_stream(path(hold(Q0, 10), ramp(Q0, q1, 60))) for s in gen.feed(x)] + gen.flush()
    assert kinds(first) == ["DRIVE"] and first[0].joint == 5
    assert gen.flush() == []  # nothing left
    second = [s for x in joint_stream(ramp(q1, q2, 60), t0=1.0) for s in gen.feed(x)] + gen.flush()
    assert kinds(second) == ["DRIVE"] and second[0].joint == 6  # J5 is not re-reported
    gen.reset(RobotSample(3.0, Q0, "joint"))  # re-synced to another state: that is the new start
    third = [s for x in joint_stream(ramp(Q0, q1, 60), t0=3.01) for s in gen.feed(x)] + gen.flush()
    assert kinds(third) == ["DRIVE"] and third[0].joint == 5


# -- jitter -------------------------------------------------------------------------------------
def test_jittery_stationary_stream_gives_nothing() -> None:
    rng = np.random.default_rng(11)
    n = int(20 * RATE)
    qs = Q0 + rng.normal(0.0, math.radians(0.02), (n, 6))
    ps = P0 + rng.normal(0.0, 0.00005, (n, 3))
    rs = np.stack([exp_so3(w) @ R0 for w in rng.normal(0.0, math.radians(0.02), (n, 3))])
    gen = ProgramGenerator()
    out = [s for x in joint_stream(qs) for s in gen.feed(x)] + gen.flush()
    out += [s for x in tool_stream(ps, rs, t0=n * DT) for s in gen.feed(x)] + gen.flush()
    assert out == []
    assert all(seg.statement is None for seg in gen.segments)


def test_noise_on_a_line_still_gives_one_draw() -> None:
    rng = np.random.default_rng(5)
    p1 = P0 + np.array([-0.06, 0.09, 0.0])
    ps = path(hold(P0, 40), ramp(P0, p1, 300), hold(p1, 40))
    clean_end = ps[-1].copy()
    ps = ps + rng.normal(0.0, 0.00005, ps.shape)
    rs = np.stack([exp_so3(w) @ R0 for w in rng.normal(0.0, math.radians(0.02), (len(ps), 3))])
    out = generate_program(tool_stream(ps, rs))
    assert kinds(out) == ["DRAW"]
    np.testing.assert_allclose(out[0].position, clean_end, atol=0.0003)


def test_thresholds_decide_what_counts_as_a_change() -> None:
    """A 0.8 mm nudge is below the default 1 mm minimum translation, above a 0.5 mm one."""
    p1 = P0 + np.array([0.0008, 0.0, 0.0])
    ps = path(hold(P0, 20), ramp(P0, p1, 10), hold(p1, 20))
    samples = tool_stream(ps, hold(R0, len(ps)).reshape(-1, 3, 3))
    assert generate_program(samples) == []
    fine = GeneratorSettings(min_translation=0.0005, linear_noise_floor=0.002)
    assert kinds(generate_program(samples, fine)) == ["DRAW"]


# -- modes and frames -----------------------------------------------------------------------------
def test_mode_change_closes_the_segment() -> None:
    q1 = Q0.copy()
    q1[3] += math.radians(25.0)
    p1 = P0 + np.array([0.05, 0.0, 0.0])
    joint = joint_stream(path(hold(Q0, 10), ramp(Q0, q1, 100)))
    tool = tool_stream(path(ramp(P0, p1, 100), hold(p1, 10)), hold(R0, 110).reshape(-1, 3, 3), t0=110 * DT, q=q1)
    gen = ProgramGenerator()
    out = [s for x in joint + tool for s in gen.feed(x)] + gen.flush()
    assert kinds(out) == ["DRIVE", "DRAW"]
    assert gen.segments[0].reason == "mode"
    assert out[0].target == pytest.approx(q1[3], abs=ANGLE_TEXT)


def test_targets_in_world_and_work_frames() -> None:
    world_T_base = pose_to_transform([1.0, 0.5, 0.66], [0.0, 0.0, math.radians(90.0)])
    world_T_work = pose_to_transform([1.5, 0.2, 0.8], [0.0, 0.0, math.radians(-30.0)])
    p1 = P0 + np.array([0.0, 0.1, 0.0])
    samples = tool_stream(path(hold(P0, 20), ramp(P0, p1, 150), hold(p1, 20)), hold(R0, 190).reshape(-1, 3, 3))
    world = generate_program(samples, GeneratorSettings(frame=Frame.WORLD), world_T_base=world_T_base)
    assert world[0].frame is Frame.WORLD
    np.testing.assert_allclose(world[0].position, (world_T_base @ np.append(p1, 1.0))[:3], atol=POSITION_TEXT)
    work = generate_program(samples, GeneratorSettings(frame=Frame.WORK), world_T_base=world_T_base, world_T_work=world_T_work)
    expected = (np.linalg.inv(world_T_work) @ world_T_base @ np.append(p1, 1.0))[:3]
    np.testing.assert_allclose(work[0].position, expected, atol=POSITION_TEXT)
    with pytest.raises(InputError, match="world_T_base"):
        generate_program(samples, GeneratorSettings(frame=Frame.WORLD))


def test_bad_input_is_refused_with_a_clear_message() -> None:
    gen = ProgramGenerator()
    gen.feed(RobotSample(1.0, Q0, "joint"))
    with pytest.raises(InputError, match="does not follow"):
        gen.feed(RobotSample(1.0, Q0, "joint"))
    with pytest.raises(InputError, match="5 joints"):
        gen.feed(RobotSample(2.0, Q0[:5], "joint"))
    with pytest.raises(InputError, match="no tool pose"):
        RobotSample(3.0, Q0, "tool")
    with pytest.raises(InputError, match="control mode"):
        RobotSample(3.0, Q0, "wrist")
    with pytest.raises(InputError, match="4x4"):
        RobotSample(3.0, Q0, "tool", base_T_tool=np.eye(3))
    with pytest.raises(InputError, match="TOOL"):
        GeneratorSettings(frame=Frame.TOOL)
    with pytest.raises(InputError, match="min_translation"):
        GeneratorSettings(min_translation=0.0)


# -- properties: strokes and sweeps with jitter give one statement each, ending where they ended -
@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    strokes=st.integers(1, 4),
    speed=st.floats(0.02, 0.12),
    stop_between=st.booleans(),
)
def test_polyline_strokes_give_one_draw_each(seed: int, strokes: int, speed: float, stop_between: bool) -> None:
    rng = np.random.default_rng(seed)
    vertices = [P0]
    direction = None
    while len(vertices) <= strokes:
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        if direction is not None and np.dot(d, direction) > math.cos(math.radians(50.0)):
            continue  # turns sharper than 50 deg, so the velocity change is well above the threshold
        direction = d
        vertices.append(vertices[-1] + d * rng.uniform(0.03, 0.10))
    pieces = [hold(P0, 20)]
    for a, b in zip(vertices[:-1], vertices[1:]):
        n = max(int(np.linalg.norm(b - a) / speed * RATE), 2)
        pieces.append(ramp(a, b, n))
        if stop_between:
            pieces.append(hold(b, 30))
    pieces.append(hold(vertices[-1], 20))
    ps = path(*pieces)
    ps = ps + rng.normal(0.0, 0.00005, ps.shape)  # sensor jitter: 0.05 mm, 0.02 deg
    rs = np.stack([exp_so3(w) @ R0 for w in rng.normal(0.0, math.radians(0.02), (len(ps), 3))])
    out = generate_program(tool_stream(ps, rs))
    assert kinds(out) == ["DRAW"] * strokes
    for statement, vertex in zip(out, vertices[1:]):
        np.testing.assert_allclose(statement.position, vertex, atol=0.001)


@settings(max_examples=25, deadline=None)
@given(
    sweeps=st.lists(
        st.tuples(st.integers(1, 6), st.floats(5.0, 40.0), st.booleans(), st.floats(8.0, 40.0)),
        min_size=1, max_size=4,
    ),
    stop_between=st.booleans(),
    seed=st.integers(0, 2**31 - 1),
)
def test_joint_sweeps_give_one_drive_each(sweeps, stop_between: bool, seed: int) -> None:
    """Sweeps of one joint after another (each a different joint from the one before, or the
    same joint stopping first), with encoder jitter: one DRIVE each, on that joint, ending where
    the sweep ended."""
    rng = np.random.default_rng(seed)
    q = Q0.copy()
    pieces, expected = [hold(q, 20)], []
    previous = None
    for joint, degrees, negative, speed in sweeps:
        if joint == previous and not stop_between:
            joint = joint % 6 + 1
        target = q.copy()
        target[joint - 1] += math.radians(-degrees if negative else degrees)
        pieces.append(ramp(q, target, max(int(degrees / speed * RATE), 2)))
        if stop_between:
            pieces.append(hold(target, 30))
        expected.append((joint, target[joint - 1]))
        q, previous = target, joint
    pieces.append(hold(q, 20))
    qs = path(*pieces)
    qs = qs + rng.normal(0.0, math.radians(0.02), qs.shape)
    out = generate_program(joint_stream(qs))
    assert kinds(out) == ["DRIVE"] * len(expected)
    for statement, (joint, target) in zip(out, expected):
        assert statement.joint == joint
        assert statement.target == pytest.approx(target, abs=math.radians(0.6))


# -- a motion recorded by jogging the real PUMA 562 ---------------------------------------------
RECORD_WORLD_T_BASE = pose_to_transform([0.0, 0.0, 0.66], [0.0, 0.0, 0.0])
RECORD_Q_START = np.radians([0.0, -45.0, 180.0, 0.0, 45.0, 0.0])


def record_puma_jog() -> dict[str, np.ndarray]:
    """Jog the PUMA 562 at 100 Hz through a few operator steps (shared.robots.jog), returning
    the stream as arrays plus the index of the last sample of each motion phase."""
    from shared.robots.jog import JogFrames, jog_joint, jog_tool, world_T_tcp
    from shared.robots.loader import load_robot

    robot = load_robot("puma562")
    frames = JogFrames(RECORD_WORLD_T_BASE, np.eye(4), np.eye(4))
    q = RECORD_Q_START.copy()
    rows: list[tuple[np.ndarray, np.ndarray, int]] = []
    phase_ends: list[int] = []

    def tick(mode: int) -> None:
        rows.append((q.copy(), world_T_tcp(robot, q, frames), mode))

    def still(n: int, mode: int) -> None:
        for _ in range(n):
            tick(mode)

    def tool(n: int, frame: str, constraint: str, motion: str, step: list[float]) -> None:
        nonlocal q
        for _ in range(n):
            result = jog_tool(robot, q, frames=frames, frame=frame, constraint=constraint, motion=motion, displacement=np.array(step))
            assert result.moved and result.blocked is None, result.message
            q = result.q
            tick(1)
        phase_ends.append(len(rows) - 1)

    def joint(n: int, j: int, step: float) -> None:
        nonlocal q
        for _ in range(n):
            result = jog_joint(robot, q, j, step)
            assert result.moved and result.blocked is None, result.message
            q = result.q
            tick(0)
        phase_ends.append(len(rows) - 1)

    still(30, 1)
    tool(100, "world", "x", "translate", [0.0006, 0.0, 0.0])  # 60 mm at 60 mm/s
    still(30, 1)
    tool(100, "tool", "z", "rotate", [0.0, 0.0, math.radians(0.3)])  # 30 deg at 30 deg/s
    still(30, 1)
    tool(80, "world", "y", "translate", [0.0, 0.0005, 0.0])  # 40 mm, then straight on down
    tool(60, "world", "z", "translate", [0.0, 0.0, -0.0005])  # 30 mm: a corner, no stop
    still(30, 1)
    still(20, 0)
    joint(80, 1, math.radians(0.25))  # J1 +20 deg at 25 deg/s
    still(30, 0)
    return {
        "t": np.arange(len(rows)) * DT,
        "q": np.stack([r[0] for r in rows]),
        "world_T_tool": np.stack([r[1] for r in rows]),
        "mode": np.array([r[2] for r in rows], dtype=np.int8),
        "phase_ends": np.array(phase_ends),
        "world_T_base": RECORD_WORLD_T_BASE,
    }


def load_recording() -> dict[str, np.ndarray]:
    with np.load(DATA) as f:
        return {k: f[k] for k in f.files}


def recorded_samples(rec: dict[str, np.ndarray]) -> list[RobotSample]:
    modes = (JogMode.JOINT, JogMode.TOOL)
    return [
        RobotSample(float(t), q, modes[int(m)], world_T_tool=pose)
        for t, q, pose, m in zip(rec["t"], rec["q"], rec["world_T_tool"], rec["mode"])
    ]


def test_recording_is_a_real_puma_jog() -> None:
    """The stored stream is what jogging the PUMA produces: FK of each stored joint vector is
    the stored pose, and jogging again reproduces it."""
    from shared.robots.loader import load_robot

    rec = load_recording()
    robot = load_robot("puma562")
    for q, pose in zip(rec["q"][::25], rec["world_T_tool"][::25]):
        np.testing.assert_allclose(rec["world_T_base"] @ robot.fk(q), pose, atol=1e-9)
    fresh = record_puma_jog()
    np.testing.assert_allclose(fresh["q"], rec["q"], atol=1e-6)
    np.testing.assert_array_equal(fresh["phase_ends"], rec["phase_ends"])


@pytest.mark.parametrize("frame", [Frame.WORLD, Frame.BASE])
def test_recorded_puma_jog_gives_statements_where_the_arm_went(frame: Frame) -> None:
    rec = load_recording()
    out = generate_program(recorded_samples(rec), GeneratorSettings(frame=frame), world_T_base=rec["world_T_base"])
    assert kinds(out) == ["DRAW", "ROTATE", "DRAW", "DRAW", "DRIVE"]
    out_T_world = np.eye(4) if frame is Frame.WORLD else np.linalg.inv(rec["world_T_base"])
    reached = [out_T_world @ rec["world_T_tool"][i] for i in rec["phase_ends"]]
    for statement, pose in zip(out[:4], reached[:4]):
        assert statement.frame is frame
        if isinstance(statement, Draw):
            np.testing.assert_allclose(statement.position, pose[:3, 3], atol=0.0015)
        else:
            assert isinstance(statement, Rotate)
            assert math.degrees(rotation_angle(rpy_to_matrix(statement.rpy).T @ pose[:3, :3])) < 0.5
    # the first DRAW and the ROTATE end where the arm stopped, exactly
    np.testing.assert_allclose(out[0].position, reached[0][:3, 3], atol=POSITION_TEXT)
    # the corner DRAW leaves the orientation alone, so its target is on the way down, not past it
    assert out[2].position[2] == pytest.approx(reached[2][2, 3], abs=0.0015)
    drive = out[4]
    assert isinstance(drive, Drive) and drive.joint == 1
    assert drive.target == pytest.approx(rec["q"][rec["phase_ends"][4], 0], abs=ANGLE_TEXT)
    j1_before = rec["q"][rec["phase_ends"][3], 0]  # tool jogging moved J1 too
    assert drive.target - j1_before == pytest.approx(math.radians(20.0), abs=2 * ANGLE_TEXT)


def test_recorded_program_checks_clean_and_replays_the_arm_s_joints() -> None:
    """The generated program passes the language checks (shared.language.checks) for the PUMA
    from the recording's start, and the joint vector the checks track after each statement is
    the one the arm had at the end of that motion (same IK branch: continuity holds)."""
    from shared.language.checks import check_program
    from shared.robots.loader import load_robot

    rec = load_recording()
    out = generate_program(recorded_samples(rec), GeneratorSettings(frame=Frame.BASE), world_T_base=rec["world_T_base"])
    result = check_program(out, load_robot("puma562"), q_start=rec["q"][0])
    assert result.ok, [str(p) for p in result.problems]
    for q_after, i in zip(result.q_after, rec["phase_ends"]):
        np.testing.assert_allclose(q_after, rec["q"][i], atol=math.radians(0.05))


def test_recorded_stream_with_sensor_noise_gives_the_same_statements() -> None:
    rng = np.random.default_rng(7)
    rec = load_recording()
    noisy = dict(rec)
    noisy["q"] = rec["q"] + rng.normal(0.0, math.radians(0.02), rec["q"].shape)
    poses = rec["world_T_tool"].copy()
    poses[:, :3, 3] += rng.normal(0.0, 0.00005, (len(poses), 3))
    poses[:, :3, :3] = np.stack([exp_so3(w) @ r for w, r in zip(rng.normal(0.0, math.radians(0.02), (len(poses), 3)), poses[:, :3, :3])])
    noisy["world_T_tool"] = poses
    out = generate_program(recorded_samples(noisy), GeneratorSettings(frame=Frame.WORLD))
    assert kinds(out) == ["DRAW", "ROTATE", "DRAW", "DRAW", "DRIVE"]
    for statement, i in zip(out, rec["phase_ends"]):
        if isinstance(statement, Draw):
            np.testing.assert_allclose(statement.position, rec["world_T_tool"][i][:3, 3], atol=0.002)


if __name__ == "__main__":
    DATA.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(DATA, **record_puma_jog())
    print(f"wrote {DATA} ({DATA.stat().st_size} bytes)")
