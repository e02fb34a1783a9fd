"""Where the program starts (the program desk keeps one; the parts downstream read it)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ProgramStart:
    """Where the program starts: a joint vector, where it came from, and whether it is known."""

    q: np.ndarray
    source: str = "model"  # model | predicted | telemetry
    unknown: bool = False
    """The predicted end lies after a task, a stop or a failure whose end only the robot knows."""
