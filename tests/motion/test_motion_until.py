"""UNTIL FORCE / CONTACT / TIME: a motion stops early against a sensor model, with the reason."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shared.errors import InputError
from shared.language.statements import Draw, UntilContact, UntilForce, UntilTime
from shared.motion import FreeSpace, Interpreter, PlaneSurface, SensorModel, StopReason

WALL = 0.42  # m, world height: 70 mm below the peg cell's home tool point, above the plate


def down_to(cell, z: float, until) -> tuple[Interpreter, object]:
    interp = Interpreter.for_cell(cell)
    p = interp.state.world_T_tcp[:3, 3]
    return interp, interp.plan_next(Draw(position=(p[0], p[1], z), until=until))


def tcp_z(interp: Interpreter, q: np.ndarray) -> float:
    return float(interp.frames.world_T_tcp(interp.robot, q)[2, 3])


def test_the_wall_is_a_sensor_model(make_wall) -> None:
    assert isinstance(make_wall(WALL), SensorModel)


def test_until_contact_stops_at_the_wall(cell, make_wall) -> None:
    interp, seg = down_to(cell, 0.40, UntilContact())
    wall = make_wall(WALL)
    out = seg.run(wall, dt=0.01)
    assert out.reason is StopReason.CONTACT and out.stopped_early
    assert 0.0 < out.t_stop < seg.duration
    assert abs(tcp_z(interp, out.q_stop) - WALL) < 1e-6
    assert out.samples.t[-1] == out.t_stop and np.all(np.diff(out.samples.t) > 0)
    # every sample before the stop is above the wall
    assert all(tcp_z(interp, q) > WALL for q in out.samples.q[:-1])
    assert wall.calls > 0


def test_until_force_stops_where_the_force_passes_the_threshold(cell, make_wall) -> None:
    interp, seg = down_to(cell, 0.40, UntilForce(newtons=5.0))
    out = seg.run(make_wall(WALL, stiffness=1000.0), dt=0.01)
    assert out.reason is StopReason.FORCE
    assert abs(out.force - 5.0) < 1e-3
    assert abs(tcp_z(interp, out.q_stop) - (WALL - 0.005)) < 1e-6  # 5 N into a 1000 N/m wall


def test_until_time_stops_after_the_time(cell) -> None:
    _, seg = down_to(cell, 0.40, UntilTime(seconds=0.3))
    assert seg.duration > 0.3
    out = seg.run(None, dt=0.01)
    assert out.reason is StopReason.TIME and out.t_stop == 0.3
    np.testing.assert_array_equal(out.q_stop, seg.sample(0.3).q[0])


def test_a_condition_that_never_holds_lets_the_motion_complete(cell, make_wall) -> None:
    _, seg = down_to(cell, 0.45, UntilContact())  # ends above the wall
    out = seg.run(make_wall(WALL), dt=0.01)
    assert out.reason is StopReason.COMPLETED and not out.stopped_early
    np.testing.assert_array_equal(out.q_stop, seg.q_end)
    assert seg.run(FreeSpace(), dt=0.01).reason is StopReason.COMPLETED


def test_already_in_contact_stops_at_once(cell, make_wall) -> None:
    _, seg = down_to(cell, 0.40, UntilContact())
    out = seg.run(make_wall(0.6), dt=0.01)  # the wall is above the start
    assert out.reason is StopReason.CONTACT and out.t_stop == 0.0
    np.testing.assert_array_equal(out.q_stop, seg.q_start)


@pytest.mark.parametrize("until", [UntilContact(), UntilForce(newtons=5.0), UntilTime(seconds=0.3), None])
def test_stepping_sample_by_sample_stops_like_run(cell, make_wall, until) -> None:
    _, seg = down_to(cell, 0.40, until)
    dt = 0.02
    out = seg.run(make_wall(WALL), dt=dt)
    stepper = seg.stepper(make_wall(WALL), dt=dt)
    steps = []
    while not stepper.done:
        steps.append(stepper.step())
        assert len(steps) < 10_000
    last = steps[-1]
    assert last.reason is out.reason
    assert last.t == pytest.approx(out.t_stop, abs=1e-12)
    np.testing.assert_allclose(last.q, out.q_stop, atol=1e-12)
    assert len(steps) == len(out.samples.t)
    assert stepper.step() is last  # a finished stepper stays finished


def test_a_stepper_samples_in_batches_what_sample_gives_one_at_a_time(cell) -> None:
    from shared.motion.segment import STEP_CHUNK

    _, seg = down_to(cell, 0.40, None)
    dt = seg.duration / (2.5 * STEP_CHUNK)  # three batches, the last one short
    stepper = seg.stepper(FreeSpace(), dt=dt)
    steps = []
    while not stepper.done:
        steps.append(stepper.step())
        assert len(steps) < 10_000  # a stepper that never finishes fails here, not by eating memory
    assert len(steps) > 2 * STEP_CHUNK
    for step in steps[:-1]:
        one = seg.sample(step.t)
        np.testing.assert_allclose(step.q, one.q[0], atol=1e-12)
        np.testing.assert_allclose(step.qd, one.qd[0], atol=1e-12)
    assert steps[-1].t == seg.duration and not np.any(steps[-1].qd)
    np.testing.assert_array_equal(steps[-1].q, seg.q_end)


def test_sensor_time_is_on_the_callers_clock(cell) -> None:
    seen: list[float] = []

    class Clock:
        def force(self, t: float, q: np.ndarray) -> float:
            seen.append(t)
            return 0.0

        def contact(self, t: float, q: np.ndarray) -> bool:
            seen.append(t)
            return t >= 100.25

    _, seg = down_to(cell, 0.40, UntilContact())
    out = seg.run(Clock(), dt=0.1, t0=100.0)
    assert seen[0] == 100.0
    assert out.reason is StopReason.CONTACT and math.isclose(out.t_stop, 0.25, abs_tol=1e-6)


def test_a_guarded_motion_needs_a_sensor_model(cell) -> None:
    _, seg = down_to(cell, 0.40, UntilContact())
    with pytest.raises(InputError, match="sensor model"):
        seg.run(None)


def test_planning_goes_on_from_where_the_arm_stopped(cell, make_wall) -> None:
    interp, seg = down_to(cell, 0.40, UntilContact())
    out = seg.run(make_wall(WALL), dt=0.01)
    interp.resume_at(out.q_stop)
    assert abs(interp.state.world_T_tcp[2, 3] - WALL) < 1e-6
    up = interp.plan_next(Draw(position=(0.0, 0.0, -0.02), frame="TOOL"))  # back up 20 mm (tool z is down)
    np.testing.assert_array_equal(up.q_start, out.q_stop)
    assert abs(tcp_z(interp, up.q_end) - (WALL + 0.02)) < 1e-6


def test_the_plane_surface_model_stops_a_guarded_move(cell) -> None:
    interp, seg = down_to(cell, 0.40, UntilForce(newtons=20.0))
    surface = PlaneSurface(cell.robot, interp.frames, height=WALL, stiffness=2.0e4)
    out = seg.run(surface, dt=0.01)
    assert out.reason is StopReason.FORCE
    assert abs(tcp_z(interp, out.q_stop) - (WALL - 20.0 / 2.0e4)) < 1e-6


def test_a_simulated_program_goes_on_from_where_a_guarded_move_stopped(cell, make_wall) -> None:
    from shared.language.statements import Event, TaskCall
    from shared.motion import simulate_program

    interp = Interpreter.for_cell(cell)
    p = interp.state.world_T_tcp[:3, 3]
    program = [
        Draw(position=(p[0], p[1], 0.40), until=UntilContact()),  # stops on the wall at 0.42
        TaskCall(name="grasp", args=("peg",)),
        Draw(position=(0.0, 0.0, -0.03), frame="TOOL"),  # 30 mm back up from the contact
        Event(name="done"),
    ]
    run = simulate_program(program, interp, make_wall(WALL), dt=0.01)
    assert run.refusal is None and len(run.runs) == 4
    first, task, back, event = run.runs
    assert first.outcome.reason is StopReason.CONTACT
    assert task.outcome is None and task.t_start == first.t_end
    np.testing.assert_array_equal(back.segment.q_start, first.outcome.q_stop)
    assert abs(tcp_z(interp, run.q_final) - (WALL + 0.03)) < 1e-6
    assert event.t_start == pytest.approx(first.outcome.t_stop + back.outcome.t_stop)
    assert run.duration == pytest.approx(event.t_start)
