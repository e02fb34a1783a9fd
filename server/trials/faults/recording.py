"""A replayed campaign run as an MCAP file (``teleprog trial faults --replay SEED``): what the
judge saw every servo period, what the robot said, and the verdict, on the run's virtual clock
(``log_time`` is virtual time in ns), for Foxglove or any MCAP reader.

Topics (JSON):

* ``/fault/fault``: the run's fault, once, first;
* ``/fault/ground_truth``: every servo period: the robot's state and statement number, the force
  it exerts and on what, the tool point (m, world), the fingers' opening, what the wrist sensor
  reads (N, world; what the robot believes);
* ``/fault/robot``: each failure report and halt, as the robot sent it;
* ``/fault/run``: the verdict (``FaultRun``), once, last.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robot_sim.physics import faults as world_faults
from server.recording.writer import RecordingWriter
from server.trials.faults.catalogue import Fault
from server.trials.faults.results import FaultRun


class RunRecorder:
    def __init__(self, path: Path, fault: Fault) -> None:
        self.writer = RecordingWriter(path, queue_size=2_000_000)
        self.writer.start()
        self.writer.put("/fault/fault", 0, fault)
        self._said = 0

    def next_due(self) -> float | None:
        return None

    def on_tick(self, driver) -> None:
        t_ns = int(round(driver.t * 1e9))
        world, ex = driver.world, driver.robot.executor
        load, on = world_faults.contact_load(world)
        sensed = world.wrench[:3]
        self.writer.put("/fault/ground_truth", t_ns, {
            "t": driver.t, "state": ex.state.name.lower(), "statement": ex.current[0] if ex.current else None,
            "load_n": load, "load_on": on, "tcp_m": world.data.site_xpos[world._tcp_site].tolist(),
            "finger_opening_m": world.finger_opening(),
            "sensed_force_n": [float(v) if np.isfinite(v) else None for v in sensed],
        })
        for t, why in driver.robot_said[self._said:]:
            self.writer.put("/fault/robot", int(round(t * 1e9)), {"t": t, "said": why})
        self._said = len(driver.robot_said)

    def close(self, run: FaultRun, t: float) -> Path:
        self.writer.put("/fault/run", int(round(t * 1e9)), run)
        self.writer.close()
        return self.writer.path
