"""Correcting the virtual world from a camera (thesis §4.2.3): an object's pose from its feature
points picked in a calibrated camera's image (``shared.vision.pose``), taken into the virtual
world when the points fit."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from server.console.context import ConsoleContext
from server.console.errors import ConflictError
from server.console.events import Notice
from server.console.views import Caller, LocatedView, matrix_list
from shared.errors import InputError, UnknownNameError
from shared.vision.pose import locate_object as locate_object_pose

if TYPE_CHECKING:
    from server.console.arm import VirtualArm
    from server.console.control import ControlLock
    from server.console.program_desk import ProgramDesk


def locate_or_refuse(camera, keypoints: np.ndarray, px: np.ndarray):
    """``shared.vision.pose.locate_object``, with pixels that cannot determine a pose refused as
    ``InputError`` instead of a numerical failure (SVD not converging, a NaN pose)."""
    if not np.all(np.isfinite(px)):
        raise InputError("pixels are degenerate: every u and v must be a finite number")
    distinct = len({(float(u), float(v)) for u, v in px})
    if distinct < len(px):
        raise InputError(f"pixels are degenerate: {len(px) - distinct + 1} of the {len(px)} points are at the same pixel")
    try:
        with np.errstate(all="ignore"):
            located = locate_object_pose(camera, keypoints, px)
    except (np.linalg.LinAlgError, ArithmeticError, ValueError) as exc:
        raise InputError(f"pixels are degenerate: no pose fits them ({exc})") from None
    if not (np.all(np.isfinite(located.world_T_object)) and np.isfinite(located.residual_px)):
        raise InputError("pixels are degenerate: no finite pose fits them")
    return located


class Locator:
    """Locate an object from a camera's pixels."""

    def __init__(self, ctx: ConsoleContext, control: ControlLock, desk: ProgramDesk, arm: VirtualArm) -> None:
        self._ctx = ctx
        self._control, self._desk, self._arm = control, desk, arm

    def locate_object(self, name: str, camera: str, pixels: Sequence[Sequence[float]], *, client: Caller | str | None = None) -> LocatedView:
        """Correct a virtual object's pose from its feature points seen in ``camera``'s image:
        ``pixels`` (u, v) in the order of the object's keypoints. Pixels that cannot determine a
        pose (repeated, collinear, not finite) are refused ("pixels are degenerate: ...")."""
        cell = self._ctx.cell
        self._control.check(client)  # before the solve: an observer's call does no work
        obj = self._arm.objects.resolve(name)
        if obj is None:
            raise UnknownNameError("object", name, cell.object_names)
        if camera not in cell.cameras:
            raise UnknownNameError("camera", camera, cell.cameras)
        keypoints = cell.object(obj).keypoints
        if len(keypoints) < 4:
            raise InputError(f"object {obj!r} has {len(keypoints)} feature points in the cell file; locating it needs 4")
        try:
            px = np.asarray(pixels, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"{obj!r} has {len(keypoints)} feature points: give one pixel (u, v) for each, as numbers") from None
        if px.ndim != 2 or px.shape[1] != 2 or px.shape[0] != len(keypoints):
            raise InputError(f"{obj!r} has {len(keypoints)} feature points: give one pixel (u, v) for each, in order")
        located = locate_or_refuse(cell.cameras[camera], keypoints, px)
        limit = self._ctx.settings.locate_max_residual_px
        if located.residual_px > limit:
            raise InputError(
                f"the picked pixels do not fit {obj!r}'s feature points (reprojection error {located.residual_px:.1f} px, "
                f"at most {limit:g}): check the order of the points"
            )
        with self._ctx.lock:
            self._control.check(client)
            self._desk.check_not_previewing("correct an object")
            objects = self._arm.objects
            if obj == objects.held:
                raise ConflictError(f"{obj!r} is in the virtual gripper; release it before correcting its pose")
            before = objects.world_T_object(obj).copy()
            objects.place(obj, located.world_T_object)
            moved = float(np.linalg.norm(located.world_T_object[:3, 3] - before[:3, 3]))
            events = self._arm.refresh()
        view = LocatedView(object=obj, camera=camera, world_T_object=matrix_list(located.world_T_object),
                           residual_px=located.residual_px, moved=moved)
        self._ctx.bus.emit([*events, Notice(level="info", message=f"{obj} located from camera {camera}: moved {moved * 1e3:.1f} mm "
                                                                    f"(reprojection {located.residual_px:.2f} px)")])
        return view
