"""Put one run's fault into its session at its moment (a :class:`TickObserver` of the virtual
session): into the physics world (``robot_sim.physics.faults``), the robot's sensor or joint, or
the link (:class:`server.trials.faults.link.FaultyLink`).

A fault on an object waits, armed, until it can happen: a held object is not moved or taken away
(someone takes a peg from the table, not from the gripper), a slip needs a held object, a plate
does not move while the peg in it is held.
"""

from __future__ import annotations

import numpy as np

from robot_sim.physics import faults as world_faults
from server.trials.faults.catalogue import LINK_KINDS, CleanTrace, Fault

OBJECT_KINDS = frozenset(("object_moved", "object_missing", "hole_moved"))
from server.trials.faults.link import FaultyLink
from shared.link.core import Direction
from shared.wire.messages import encode_message

OBSTACLE_CLEAR_M = 0.04
"""An obstacle is never put within this of where the tool is when it appears (beyond its size)."""


class Injector:
    def __init__(self, fault: Fault, trace: CleanTrace | None, t0: float) -> None:
        self.fault = fault
        self.trace = trace
        self.t0 = t0
        self.at = t0 + fault.at_s
        # a fault on an object strikes before the program's last task starts, or never: after
        # it nothing the robot does can find it out, and the world is simply not the one it left
        self.deadline = t0 + (trace.last_task_start - trace.start) if trace is not None and fault.kind in OBJECT_KINDS else None
        self.applied_at: float | None = None
        self.note = ""
        self.link: FaultyLink | None = None

    # -- the link faults are in place from the start (they act at their moment) ----------------------
    def attach(self, driver) -> None:
        f = self.fault
        if f.kind not in LINK_KINDS:
            driver.observers.append(self)
            return
        start, duration = self.at, f.duration_s
        if f.kind == "link_cut":
            def cut() -> None:
                driver.robot.disconnect()

            def reconnect() -> None:
                driver.robot.connect()
                driver.link.send(driver.t, Direction.UP, encode_message(driver.sender.hello()))

            self.link = FaultyLink(driver.link, kind="cut", start=start, duration=duration, on_cut=cut, on_reconnect=reconnect)
        elif f.kind == "jitter_burst":
            self.link = FaultyLink(driver.link, kind="jitter", start=start, duration=duration, extra=f.magnitude,
                                   seed=int(f.at_s * 1e6))
        else:  # link_stall, console_frozen
            self.link = FaultyLink(driver.link, kind="stall", start=start, duration=duration)
            if f.kind == "console_frozen":
                driver.console_silent = (start, start + duration)
        driver.link = self.link
        self.applied_at = start
        driver.observers.append(self)

    def next_due(self) -> float | None:
        return self.at if self.applied_at is None else None

    def on_tick(self, driver) -> None:
        if self.applied_at is not None or driver.t + 1e-9 < self.at:
            return
        if self.deadline is not None and driver.t > self.deadline:
            if not self.note:
                self.note = "never struck: the object was held until the program's last task"
            return
        if self._apply(driver):
            self.applied_at = driver.t

    # -- the world and robot faults ---------------------------------------------------------------
    def _apply(self, driver) -> bool:
        f, world = self.fault, driver.world
        name = f.target
        peg = world.pegs.get(name) if name else None
        held = world.held_peg()
        held_name = held[0] if held else None
        if f.kind in ("object_moved", "object_missing"):
            if peg is None or held_name == name:
                return False
            if f.kind == "object_missing":
                world_faults.remove_object(world, name)
                self.note = f"{name} taken away"
                return True
            T = peg.world_T_peg.copy()
            free = [h for h in world.holes if h != peg.in_hole and not any(p.in_hole == h for p in world.pegs.values())]
            if peg.in_hole is not None and free:
                src, dst = world.holes[peg.in_hole].world_T_hole, world.holes[free[0]].world_T_hole
                T = dst @ np.linalg.inv(src) @ T
                self.note = f"{name} moved from {peg.in_hole} into {free[0]}"
            elif peg.in_hole is None:
                T[:3, 3] += np.asarray(f.direction) * f.magnitude / 1e3
                self.note = f"{name} moved {f.magnitude:.1f} mm"
            else:
                return False  # in a hole with none free: lifting it out is not moving it
            world_faults.move_object(world, name, T)
            return True
        if f.kind == "hole_moved":
            if held is not None and held[1].in_hole is not None:
                return False
            carriers = list(world._carrier_shift)
            if not carriers:
                return False
            moved = world_faults.shift_carrier(world, carriers[0], np.asarray(f.direction) * f.magnitude / 1e3)
            self.note = f"{carriers[0]} moved {f.magnitude:.1f} mm" + (f" with {', '.join(moved)}" if moved else "")
            return True
        if f.kind == "peg_slip":
            if held is None:
                return False
            world_faults.slip(world, held_name, f.magnitude)
            self.note = f"{held_name} slips in the fingers (friction {f.magnitude:.3f})"
            return True
        if f.kind == "obstacle":
            return self._place_obstacle(driver)
        if f.kind == "heavier":  # built into the world (campaign._session): nothing changes now
            self.note = f"the movable objects {f.magnitude:.2f} times as heavy as modelled"
            return True
        if f.kind == "friction":
            self.note = f"friction {world.params.friction:.2f} (x{f.magnitude:.2f} the model's)"
            return True
        if f.kind == "jam":
            return self._jam(driver)
        if f.kind == "joint_drag":
            world_faults.drag_joint(world, f.joint, f.magnitude)
            self.note = f"joint {f.joint + 1} dragged by {f.magnitude:.1f} N m"
            return True
        if f.kind == "sensor_bias":
            world_faults.sensor_bias(world, np.asarray(f.direction) * f.magnitude)
            self.note = f"wrist sensor biased {f.magnitude:.1f} N"
            return True
        if f.kind == "sensor_dropout":
            world_faults.sensor_dropout(world)
            self.note = "wrist sensor readings invalid"
            return True
        raise ValueError(f"unknown fault kind {f.kind!r}")

    def _place_obstacle(self, driver) -> bool:
        f, world = self.fault, driver.world
        half = f.magnitude / 1e3
        if self.trace is None:
            return True
        tcp_now = world.world_T_tcp()[:3, 3]
        tops = [float(p.world_T_peg[2, 3] + p.half_size[2]) for n, p in world.pegs.items() if not p.held]
        tops += [float(h.world_T_hole[2, 3]) for h in world.holes.values()]
        floor = max(tops, default=-np.inf) + half + 0.005
        t_from = driver.t + f.duration_s
        for _, p in self.trace.tool_path(t_from, self.trace.end):
            p = np.asarray(p)
            if p[2] >= floor and np.linalg.norm(p - tcp_now) > 2.0 * half + OBSTACLE_CLEAR_M:
                world_faults.place_unmodelled(world, p, np.full(3, half))
                if world_faults.unmodelled_touched(world):  # it would appear inside the arm: not there
                    world_faults.retract_unmodelled(world)
                    continue
                self.note = f"a {2 * f.magnitude:.0f} mm box at ({', '.join(f'{v * 1e3:.0f}' for v in p)}) mm"
                return True
        self.note = "no place on the coming path for the obstacle"
        return True

    def _jam(self, driver) -> bool:
        f, world = self.fault, driver.world
        if self.trace is None:
            return True
        holes = [h for h in self.trace.end_holes.values() if h is not None]
        if not holes:
            self.note = "no hole the program fills"
            return True
        hole = holes[0]
        if any(p.in_hole == hole for p in world.pegs.values()):
            return self._noted("the hole is filled already")
        geo = world.hole_geometry[hole]
        h = min(f.magnitude / 1e3, geo.depth - 0.001)
        half = np.array([geo.width[0] / 2.0 - 0.001, geo.width[1] / 2.0 - 0.001, h / 2.0])
        T = geo.world_T_hole
        centre = T[:3, 3] + T[:3, :3] @ np.array([0.0, 0.0, -(geo.depth - h / 2.0)])
        world_faults.place_unmodelled(world, centre, half)
        self.note = f"a {h * 1e3:.1f} mm block at the bottom of {hole}"
        return True

    def _noted(self, note: str) -> bool:
        self.note = note
        return True
