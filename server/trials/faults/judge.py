"""The judge of a campaign run: what really happened, from the physics and the link, never from
the robot's own reports (a :class:`TickObserver` of the virtual session, after every servo period).

Each period it reads:

- **harm**: the force the robot exerts on the world, through its tool (the wrist's true force
  while the tool or what it holds touches something) or a link of the arm (MuJoCo's contact
  solution; ``robot_sim.physics.faults.contact_load``); past the cell's ``damage_force_n`` the run
  is harmed;
- **the stop**: the first period the executor holds (FAULT or STOPPED), and from then on for
  ``SETTLE_S`` how far the tool still travels (the stopping distance) and how long until it rests;
- **the physical onset** of the fault: for a sensor that drops out, the first period the robot
  moves without it (or has stopped); for the link, the first heartbeat overdue at a robot with
  work to do; for a change of the world or a dragging joint, the first period the robot's own
  bands are crossed in the physics: the arm more than ``OFF_PATH_M`` off its commanded path, the
  robot pushing harder than its force band for the motion it runs (the unmodelled box: whatever
  it does), or its fingers closed on nothing where its fault-free twin (the group's clean run on
  the same world, tick for tick) held the object; a stop before any of these has latency 0;
- **running off the path**: the flange more than ``OFF_PATH_M`` from where the joint servo is
  commanded to hold it for more than ``OFF_PATH_S`` while a statement runs, with no stop;
- **running on through silence**: the robot with work to do and nothing heard from the console
  for longer than its silence threshold and ``SILENCE_MARGIN_S``, with no stop.

The verdict (:meth:`Judge.verdict`): **missed** (harm, running off the path or through silence, or
the program ended done with the world not as the console's model of it says), **caught** (the
robot stopped after the fault struck, before any harm), **absorbed** (a fault struck, nothing
needed a stop, and the world ended right), **false_stop** (a stop with no fault yet), **clean**
(no fault, no stop, the world right), **hung** (the session could not go on: a wait ran out).
"""

from __future__ import annotations

import numpy as np

from robot_sim.physics import faults as world_faults
from server.trials.faults.catalogue import BLINDING_KINDS, LINK_KINDS, CleanTrace, Fault
from server.trials.faults.inject import Injector
from server.trials.faults.results import FaultRun
from shared.cells.object_world import seated_feature
from shared.wire.messages import RobotState

SETTLE_S = 0.5
"""How long the judge watches after a stop (stopping distance, harm while braking) before the run ends."""
BANDS = {"finger_m": 0.002}
"""The grip's band: the fingers closed this far past the object's width hold nothing (counted
where the fault-free twin held the object at the same moment). The force band is the robot's own
for what it is doing (``_force_band``: its unplanned-contact limit, or its safety limit in a
guarded motion or a task), applied to the force it really exerts."""
OFF_PATH_M = 0.005
OFF_PATH_S = 0.1
SILENCE_MARGIN_S = 0.1
REST_M_PER_TICK = 1e-5
"""Tool travel per servo period under which the stopped arm is at rest (m)."""
_STOPPED = (RobotState.FAULT, RobotState.STOPPED)


class RunOver(Exception):
    """The judge has seen enough (a stop and its settling): the run ends here."""


class Judge:
    def __init__(self, driver, fault: Fault, injector: Injector | None, twin: CleanTrace | None, t0: float,
                 record: CleanTrace | None = None) -> None:
        self.fault = fault
        self.injector = injector
        self.twin = twin
        self.t0 = t0
        self.record = record
        world = driver.world
        self.damage = float(world.params.damage_force)
        self.peak = 0.0
        self.peak_what = ""
        self.harm_at: float | None = None
        self.onset: float | None = None
        self.onset_how = ""
        self.stop_at: float | None = None
        self.stop_state = ""
        self.halted: str | None = None
        self.silent_for: float | None = None
        self._stop_tcp: np.ndarray | None = None
        self._last_tcp: np.ndarray | None = None
        self.stop_distance = 0.0
        self.rest_at: float | None = None
        self.missed_how = ""
        self._off_since: float | None = None
        self.max_off_path = 0.0
        self.off_path_now = 0.0
        halves = [h for h in world.object_half.values() if h is not None] if hasattr(world, "object_half") else []
        self._width = 2.0 * float(min(min(h[:2]) for h in halves)) if halves else 0.0
        self.last_task_start = t0
        self._task_number: int | None = None
        self.last_busy = t0
        self._robot = driver.cell.robot

    def next_due(self) -> float | None:
        return None

    # -- every servo period -----------------------------------------------------------------------
    def on_tick(self, driver) -> None:
        t = driver.t
        world = driver.world
        ex = driver.robot.executor
        load, what = world_faults.contact_load(world)
        if load > self.peak:
            self.peak, self.peak_what = load, what
        if load > self.damage and self.harm_at is None:
            self.harm_at = t
        tcp = np.array(world.data.site_xpos[world._tcp_site])
        if ex.busy:
            self.last_busy = t
        if ex.current is not None and ex.current[0] != self._task_number and _is_task(ex.current[1]):
            self._task_number, self.last_task_start = ex.current[0], t
        if self.record is not None:
            self.record.add(t, tcp, world.finger_opening())
        if self.stop_at is None and ex.state not in _STOPPED:
            self._watch_path(world, ex, t)
        self._watch_onset(driver, t, load)
        if self.stop_at is None:
            if ex.state in _STOPPED:
                self.stop_at, self.stop_state = t, ex.state.name.lower()
                self.halted = ex.halted  # a halt's reason (silence, own faults), even with no console to send it to
                heard = driver.last_up_delivery
                self.silent_for = None if heard is None else t - heard
                self._stop_tcp = self._last_tcp if self._last_tcp is not None else tcp
            else:
                self._watch_silence(driver, ex, t)
        else:
            moved = float(np.linalg.norm(tcp - self._stop_tcp))
            self.stop_distance = max(self.stop_distance, moved)
            if self.rest_at is None and self._last_tcp is not None and np.linalg.norm(tcp - self._last_tcp) < REST_M_PER_TICK:
                self.rest_at = t
            if t >= self.stop_at + SETTLE_S:
                self._last_tcp = tcp
                raise RunOver()
        self._last_tcp = tcp

    def _watch_onset(self, driver, t: float, load: float) -> None:
        inj = self.injector
        if self.onset is not None or inj is None or inj.applied_at is None:
            return
        ex = driver.robot.executor
        if self.fault.kind in LINK_KINDS:  # the silence shows once a heartbeat is overdue at a busy robot
            heard = driver.last_up_delivery
            if heard is not None and ex.busy and t - heard > driver.robot.heartbeat_s + driver.dt:
                self.onset, self.onset_how = t, "a heartbeat overdue at a busy robot"
            return
        if self.fault.kind in BLINDING_KINDS:  # a sensor matters once the robot moves by it
            if ex.state is RobotState.RUNNING or self.stop_at is not None or ex.state in _STOPPED:
                self.onset, self.onset_how = t, "the robot moves by the faulty sensor"
            return
        world = driver.world
        if world_faults.unmodelled_touched(world) and load > _force_band(ex):
            self.onset, self.onset_how = t, f"pushing the unmodelled box with {load:.0f} N, past the robot's band"
            return
        if self.off_path_now > OFF_PATH_M:
            self.onset, self.onset_how = t, "the arm off its commanded path"
            return
        row = None if self.twin is None else self.twin.row(t)
        if row is not None and world.gripper_closed and self._empty_grip(world) and self.twin.finger[row] >= self._width - BANDS["finger_m"]:
            self.onset, self.onset_how = t, "the fingers closed on nothing where the fault-free run held the object"
        elif ex.state is RobotState.RUNNING and load > _force_band(ex):
            self.onset, self.onset_how = t, f"pushing with {load:.0f} N, past the robot's {_force_band(ex):g} N band"

    def _empty_grip(self, world) -> bool:
        """The fingers closed past the object's width: nothing between them (the grip's band)."""
        return world.finger_opening() < self._width - BANDS["finger_m"]

    def _watch_path(self, world, ex, t: float) -> None:
        self.off_path_now = 0.0
        if ex.state is not RobotState.RUNNING:
            self._off_since = None
            return
        q, target = world.q, world.target
        if float(np.max(np.abs(q - target))) < 0.002:
            self._off_since = None
            return
        off = float(np.linalg.norm(self._robot.fk(q)[:3, 3] - self._robot.fk(target)[:3, 3]))
        self.off_path_now = off
        self.max_off_path = max(self.max_off_path, off)
        if off <= OFF_PATH_M:
            self._off_since = None
            return
        if self._off_since is None:
            self._off_since = t
        elif t - self._off_since > OFF_PATH_S and not self.missed_how:
            self.missed_how = (f"the arm ran {off * 1e3:.1f} mm off its commanded path for "
                               f"{t - self._off_since:.2f} s without stopping")

    def _watch_silence(self, driver, ex, t: float) -> None:
        inj = self.injector
        if inj is None or inj.link is None or self.missed_how:
            return
        heard = driver.last_up_delivery if driver.last_up_delivery is not None else self.t0
        if not ex.busy or ex.state not in (RobotState.IDLE, RobotState.RUNNING):
            return
        limit = driver.robot.watch.threshold + SILENCE_MARGIN_S
        if t - heard > limit:
            self.missed_how = f"the robot ran on through {t - heard:.2f} s of silence (threshold {driver.robot.watch.threshold:.2f} s)"

    # -- the verdict -------------------------------------------------------------------------------
    def world_wrong(self, driver) -> str:
        """Where the physical world differs from the console's model of it after the program, or ''."""
        world, expected = driver.world, driver.objects
        poses = expected.poses(driver._world_T_tcp())
        held = world.held_peg()
        held_name = held[0] if held else None
        if held_name != expected.held:
            return f"the gripper holds {held_name or 'nothing'}, the model says {expected.held or 'nothing'}"
        for name, peg in world.pegs.items():
            if name not in poses:
                continue
            want = seated_feature(driver.cell, name, poses[name])
            if want is not None and peg.in_hole != want:
                return f"{name} is {'in ' + peg.in_hole if peg.in_hole else 'in no hole'}, the model says in {want}"
            if want is None and peg.in_hole is None and not peg.held:
                off = float(np.linalg.norm(peg.world_T_peg[:2, 3] - poses[name][:2, 3]))
                if off > 0.01 + world.settings.object_offset * 1.5:
                    return f"{name} is {off * 1e3:.0f} mm from where the model has it"
        return ""

    def verdict(self, driver, *, finished: bool, error: str = "") -> FaultRun:
        f = self.fault
        inj = self.injector
        applied = inj.applied_at if inj is not None else None
        latency = None
        if self.stop_at is not None and applied is not None and self.stop_at >= applied:
            if self.onset is None or self.onset > self.stop_at:
                self.onset, self.onset_how = self.stop_at, "none before the stop (the stop came first)"
            latency = max(0.0, self.stop_at - self.onset)
        wrong = ""
        if self.harm_at is not None:
            outcome, why = "missed", f"contact load {self.peak:.0f} N on {self.peak_what or 'contact'} over the cell's {self.damage:g} N"
        elif self.missed_how:
            outcome, why = "missed", self.missed_how
        elif self.stop_at is not None:
            lost = [t for t in driver.link_losses if t <= self.stop_at]
            early = f.kind == "none" or applied is None or self.stop_at < applied
            silent = self.silent_for is not None and self.silent_for >= driver.robot.watch.threshold
            if early and lost:
                outcome, why = "caught", f"stopped after the lossy link cut the connection at {lost[0] - self.t0:.2f} s"
            elif early and silent:  # the link itself went silent past the limit (a jittery or stalled line)
                outcome, why = "caught", f"halted on {self.silent_for:.2f} s of real silence on the link"
            elif early:
                outcome, why = "false_stop", "the robot stopped with no fault in the world"
            else:
                outcome, why = "caught", ""
        elif error:
            outcome, why = "hung", error
        elif finished and (wrong := self.world_wrong(driver)):
            outcome, why = "missed", f"the program ended done with the world wrong: {wrong}"
        elif f.kind == "none":
            outcome, why = "clean", ""
        else:
            outcome, why = "absorbed", "" if applied is not None else "the fault never struck"
        return FaultRun(
            fault=f, outcome=outcome, why=why, injected_at_s=None if applied is None else round(applied - self.t0, 4),
            note=inj.note if inj is not None else "",
            onset_s=None if self.onset is None else round(self.onset - self.t0, 4), onset_how=self.onset_how,
            stop_s=None if self.stop_at is None else round(self.stop_at - self.t0, 4), stop_state=self.stop_state,
            latency_ms=None if latency is None else round(latency * 1e3, 1),
            stop_distance_mm=round(self.stop_distance * 1e3, 3) if self.stop_at is not None else None,
            stop_time_ms=None if self.rest_at is None or self.stop_at is None else round((self.rest_at - self.stop_at) * 1e3, 1),
            peak_load_n=round(self.peak, 2), peak_load_on=self.peak_what, max_off_path_mm=round(self.max_off_path * 1e3, 3),
        )


def _force_band(ex) -> float:
    """The force the robot's own rules allow now: the safety limit in a force-compliant task, in
    force mode or in a motion with an UNTIL; the unplanned-contact limit otherwise."""
    s = ex.settings
    current = ex.current[1] if ex.current is not None else None
    guarded = ex._in_task or ex.mode.name == "FORCE" or getattr(current, "until", None) is not None
    return s.max_force if guarded else s.contact_limit


def _is_task(statement) -> bool:
    from shared.language.statements import TaskCall

    return isinstance(statement, TaskCall)
