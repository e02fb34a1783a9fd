"""Interpreter and trajectory planner: the code both the preview and the telerobot execute.

``Interpreter.plan_next(statement) -> Segment`` plans one statement at a time;
``plan_program(program, robot, cell, start_q) -> Plan`` plans a whole program. A ``Segment`` is
sampled with ``sample(t)`` and played against a ``SensorModel`` with ``run`` or ``stepper``;
``simulate_program`` plays a whole program, each statement from where the previous one stopped.
"""

from shared.motion.frames import CellFrames
from shared.motion.interpreter import DEFAULT_SPEED, Interpreter, InterpreterState, Plan, plan_program
from shared.motion.limits import PUMA_LIMITS, MotionLimits, default_limits
from shared.motion.refusal import PlanRefused, RefusalReason
from shared.motion.segment import Outcome, Samples, Segment, SegmentKind, SegmentStepper, StepResult, StopReason
from shared.motion.sensors import FreeSpace, PlaneSurface, SensorModel
from shared.motion.simulate import ProgramRun, StatementRun, simulate_program

__all__ = [
    "DEFAULT_SPEED",
    "PUMA_LIMITS",
    "CellFrames",
    "FreeSpace",
    "Interpreter",
    "InterpreterState",
    "MotionLimits",
    "Outcome",
    "Plan",
    "PlanRefused",
    "PlaneSurface",
    "ProgramRun",
    "RefusalReason",
    "Samples",
    "Segment",
    "SegmentKind",
    "SegmentStepper",
    "SensorModel",
    "StatementRun",
    "StepResult",
    "StopReason",
    "default_limits",
    "plan_program",
    "simulate_program",
]
