"""The tool point computed independently of ``shared.robots.jog``: pinocchio's frame placement
and the default cell's frames written out (checked against the cell file), for the tests of
``shared.motion.expectation`` and ``shared.motion.back_away``."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from shared.robots.jog import JogFrames

WORLD_T_BASE = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0.66], [0, 0, 0, 1.0]])
FLANGE_T_TCP = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0.11], [0, 0, 0, 1.0]])


def checked_frames(cell) -> JogFrames:
    """The cell's jog frames, after checking its base and tool point are the ones written here."""
    np.testing.assert_allclose(cell.world_T_base, WORLD_T_BASE, atol=1e-12)
    np.testing.assert_allclose(cell.flange_T_tcp, FLANGE_T_TCP, atol=1e-12)
    return JogFrames(cell.world_T_base, cell.frame("work"), cell.flange_T_tcp)


def tcp_point(cell, q) -> np.ndarray:
    """The tool point in the world at ``q``: pinocchio's frame placement, then the cell's frames."""
    model = cell.robot.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    base_T_flange = data.oMf[cell.robot.tool_frame_id].homogeneous
    return (WORLD_T_BASE @ base_T_flange @ FLANGE_T_TCP)[:3, 3]
