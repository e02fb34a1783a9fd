"""The terrain tools of a rover cell (seed 004): the arm against the ground at the virtual arm's
pose, the virtual sensors on demand, and instrument placement at a picked terrain point.

All geometry is ``shared.terrain`` (``GroundChecker``); this part keeps the current placement and
the sensors switch and turns answers into views. In a cell without terrain the part is there but
``available`` is False, and every action says the cell has no terrain.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from server.console.context import ConsoleContext
from server.console.events import PlacementChanged, TerrainChanged
from server.console.views import (
    Caller,
    PlacementCandidateView,
    PlacementView,
    ProgramView,
    TerrainSensorsView,
    TerrainView,
    VirtualState,
)
from shared.errors import InputError
from shared.language.formatter import format_statement
from shared.language.statements import Statement
from shared.terrain.ground import GroundChecker, GroundContact
from shared.terrain.placement import PlacementResult

if TYPE_CHECKING:
    from server.console.arm import VirtualArm
    from server.console.control import ControlLock
    from server.console.program_desk import ProgramDesk

log = logging.getLogger(__name__)


def placement_view(result: PlacementResult) -> PlacementView:
    """The typed view of a placement result, with the program as statement text."""
    candidates = [
        PlacementCandidateView(
            q=c.q.tolist(), q_deg=np.degrees(c.q).tolist(), standoff=c.standoff, clearance=c.clearance,
            head_clearance=c.head_clearance, tilt_deg=float(np.degrees(c.tilt)), approach=c.q_approach is not None,
        )
        for c in result.candidates
    ]
    if candidates:
        best = candidates[0]
        message = (f"{len(candidates)} safe configuration(s); best: standoff {best.standoff * 1e3:.1f} mm, "
                   f"arm clearance {best.clearance * 1e3:.1f} mm, tilt {best.tilt_deg:.1f} deg")
    else:
        why = ", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in result.rejected.items() if v)
        message = f"no safe configuration ({why or 'no IK solution'})"
    return PlacementView(
        world_p_target=result.world_p_target.tolist(), world_n_surface=result.world_n_surface.tolist(),
        candidates=candidates, rejected=dict(result.rejected), program=[format_statement(s) for s in result.program],
        message=message,
    )


class TerrainTools:
    """Ground checks, sensors and placement of the session's cell (when it has a terrain)."""

    def __init__(self, ctx: ConsoleContext, ground: GroundChecker | None, control: ControlLock) -> None:
        self._ctx = ctx
        self.ground = ground
        self._control = control
        self.desk: ProgramDesk | None = None  # set by the session
        self.arm: VirtualArm | None = None  # set by the session
        self._lock = threading.Lock()
        self._show_sensors = False
        self._contact: GroundContact | None = None
        self._view: TerrainView | None = None
        self._placement: tuple[PlacementResult, PlacementView] | None = None

    @property
    def available(self) -> bool:
        """Whether the cell has a terrain."""
        return self.ground is not None

    def _need(self) -> GroundChecker:
        if self.ground is None:
            raise InputError(f"cell {self._ctx.cell.name!r} has no terrain (open a rover terrain cell)")
        return self.ground

    # -- the arm against the ground ----------------------------------------------------------
    def take_contact(self, contact: GroundContact) -> TerrainView:
        """The view of the virtual arm's newest ground contact (kept as the current one)."""
        with self._lock:
            self._contact = contact
            self._view = self._make_view(contact, self._show_sensors)
            return self._view

    @staticmethod
    def _make_view(c: GroundContact, show_sensors: bool) -> TerrainView:
        sensors = c.sensors
        return TerrainView(
            distance=c.distance, in_collision=c.in_collision, shape=c.shape,
            world_p_arm=c.world_p_arm.tolist(), world_p_terrain=c.world_p_terrain.tolist(), head_distance=c.head_distance,
            sensor_distance=sensors.distance if np.isfinite(sensors.distance) else None,
            sensor_collision=sensors.in_collision, contact_corners=c.contact_corners.tolist(),
            sensors=TerrainSensorsView(starts=sensors.starts.tolist(), ends=sensors.ends.tolist(), collides=sensors.collides.tolist())
            if show_sensors else None,
        )

    def view(self) -> TerrainView:
        """The arm against the ground at the virtual arm's pose."""
        self._need()
        with self._lock:
            assert self._view is not None
            return self._view

    def set_sensors(self, on: bool, *, client: Caller | str | None = None) -> TerrainView:
        """Show or hide the virtual sensors (their segments come with every terrain view)."""
        self._need()
        self._control.check(client)
        with self._lock:
            self._show_sensors = bool(on)
            assert self._contact is not None
            self._view = view = self._make_view(self._contact, self._show_sensors)
        self._ctx.bus.emit([TerrainChanged(terrain=view)])
        return view

    # -- picking and placement -----------------------------------------------------------------
    def pick(self, world_p_origin: np.ndarray, world_d: np.ndarray) -> np.ndarray:
        """The first terrain point along a ray; ``InputError`` if it misses the ground."""
        return self._need().pick(world_p_origin, world_d)

    def ground_point(self, x: float, y: float) -> np.ndarray:
        """The terrain point at ground position (x, y) (world, m)."""
        return self._need().ground_point(x, y)

    def place_instrument(
        self, *, world_p: Sequence[float] | None = None, ground_xy: Sequence[float] | None = None,
        ray: tuple[Sequence[float], Sequence[float]] | None = None, client: Caller | str | None = None,
    ) -> PlacementView:
        """Instrument placement at a terrain point given as a world point, a ground position
        (x, y) or a picking ray (origin, direction), all in metres."""
        ground = self._need()
        if sum(v is not None for v in (world_p, ground_xy, ray)) != 1:
            raise InputError("give exactly one of a target point, a ground position or a picking ray")
        self._control.check(client)
        if ray is not None:
            target = ground.pick(np.asarray(ray[0], dtype=float), np.asarray(ray[1], dtype=float))
        elif ground_xy is not None:
            xy = np.asarray(ground_xy, dtype=float).reshape(-1)
            if xy.shape != (2,):
                raise InputError(f"a ground position has 2 coordinates (x, y), got {xy.size}")
            target = ground.ground_point(xy[0], xy[1])
        else:
            target = np.asarray(world_p, dtype=float).reshape(-1)
            if target.shape != (3,):
                raise InputError(f"a target point has 3 coordinates (x, y, z), got {target.size}")
        result = ground.place(target)
        view = placement_view(result)
        with self._lock:
            self._placement = (result, view)
        log.info("placement at %s mm: %d configurations", np.round(result.world_p_target * 1e3, 1).tolist(), len(result.candidates))
        self._ctx.bus.emit([PlacementChanged(placement=view)])
        return view

    def placement_view(self) -> PlacementView | None:
        self._need()
        with self._lock:
            return self._placement[1] if self._placement is not None else None

    def _current(self) -> tuple[PlacementResult, PlacementView]:
        with self._lock:
            current = self._placement
        if current is None:
            raise InputError("no placement yet: pick a target on the terrain first")
        return current

    def placement_program(self) -> tuple[Statement, ...]:
        """The statements of the current placement; ``InputError`` when there is none."""
        self._need()
        result, view = self._current()
        if not result.program:
            raise InputError(f"the placement at the picked target has no safe configuration ({view.message})")
        return tuple(result.program)

    def insert_placement(self, *, client: Caller | str | None = None) -> ProgramView:
        """Insert the current placement's statements at the selection, one undoable step each."""
        for statement in self.placement_program():
            self.desk.insert(statement, client=client)
        return self.desk.view()

    def candidate_q(self, index: int) -> np.ndarray:
        """Joint vector of candidate ``index`` (0 = the best) of the current placement."""
        self._need()
        candidates = self._current()[0].candidates
        if not 0 <= index < len(candidates):
            raise InputError(f"placement candidate {index + 1} does not exist: there are {len(candidates)}")
        return candidates[index].q.copy()

    def goto_placement(self, index: int = 0, *, client: Caller | str | None = None) -> VirtualState:
        """Put the virtual arm at placement candidate ``index`` (0: the best) to look at it."""
        return self.arm.set_q(self.candidate_q(index), client=client)
