"""Backing the arm out of a contact (thesis §4.2.3: after a surprise the operator recovers): the
tool point moves a short distance straight back along the way the failed statement was pressing,
or straight up when that way is not known, at a slow speed, its orientation kept."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.errors import TeleprogError
from shared.language.statements import Draw, Frame, Speed, SpeedUnit, Statement
from shared.motion.interpreter import plan_program
from shared.robots.jog import JogFrames, world_T_tcp

UP = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class BackAway:
    """The motion, or (``motion`` None) why none can be planned from where the arm stopped."""

    motion: Draw | None
    refusal: str = ""


def approach_direction(statement: Statement, robot, cell, frames: JogFrames, q: np.ndarray) -> np.ndarray | None:
    """Unit vector (world) along which the tool point moves when ``statement`` goes on from
    ``q``; None when it would not move the tool or cannot be planned."""
    try:
        plan = plan_program([statement], robot, cell, start_q=q)
    except TeleprogError:
        return None
    if plan.refusal is not None or plan.duration <= 0:
        return None
    qs = plan.sample(np.array([0.0, min(0.1, plan.duration)])).q
    step = world_T_tcp(robot, qs[1], frames)[:3, 3] - world_T_tcp(robot, qs[0], frames)[:3, 3]
    norm = float(np.linalg.norm(step))
    return step / norm if norm > 1e-6 else None


def back_away_motion(robot, cell, frames: JogFrames, q: np.ndarray, failed: Statement | None, *,
                     distance: float, speed: float) -> BackAway:
    """The DRAW (world frame, ``speed`` m/s) that moves the tool point ``distance`` m back from
    where the arm stopped at ``q``: against ``failed``'s approach when known, else up; the first
    of those that plans."""
    world_p = world_T_tcp(robot, q, frames)[:3, 3]
    approach = approach_direction(failed, robot, cell, frames, q) if failed is not None else None
    ways = ([-approach] if approach is not None else []) + [UP]
    refusal = ""
    for way in ways:
        target = world_p + distance * way
        motion = Draw(position=tuple(float(v) for v in target), frame=Frame.WORLD,
                      speed=Speed(value=speed, unit=SpeedUnit.M_PER_S))
        plan = plan_program([motion], robot, cell, start_q=q)
        if plan.refusal is None:
            return BackAway(motion)
        refusal = str(plan.refusal)
    return BackAway(None, refusal)
