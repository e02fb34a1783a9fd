"""``shared.cells.framing``: the console's default camera and its presets, from the cell.

Oracles: the cell file's own numbers (the holes' and the peg's places, the plate's size, where the
robot stands) and a pinhole projection written out here, independent of ``ViewPose.project``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from shared.cells.framing import (
    FRONT_ELEVATION,
    PRESETS,
    cell_views,
    front_direction,
    work_focus,
)
from shared.cells.loader import load_cell
from shared.errors import UnknownNameError
from shared.paths import ASSETS_DIR
from shared.robots.shapes import link_meshes

SHIPPED = sorted((ASSETS_DIR / "cells").glob("*.toml"))
PEG = ASSETS_DIR / "cells" / "peg_in_hole.toml"


@pytest.fixture(scope="module", params=SHIPPED, ids=lambda p: p.stem)
def cell(request):
    return load_cell(request.param)


@pytest.fixture(scope="module")
def peg_cell():
    return load_cell(PEG)


def pinhole(view, points: np.ndarray, aspect: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Normalised coordinates (-1..1 across the view) and depth of world points: a camera at
    ``view.position`` looking at ``view.look_at`` with +z up on screen."""
    f = (view.look_at - view.position) / np.linalg.norm(view.look_at - view.position)
    r = np.cross(f, [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    d = np.atleast_2d(points) - view.position
    depth = d @ f
    t = math.tan(view.fov / 2.0)
    return np.column_stack([(d @ r) / depth / (t * aspect), (d @ u) / depth / t]), depth


def inside(view, points: np.ndarray, aspect: float = 1.0) -> np.ndarray:
    xy, depth = pinhole(view, points, aspect)
    return (depth > 0.05) & np.all(np.abs(xy) <= 1.0, axis=1)


def object_vertices(obj) -> np.ndarray:
    v = np.asarray(link_meshes(obj.shapes).vertices)
    return v @ obj.world_T_object[:3, :3].T + obj.world_T_object[:3, 3]


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(abs(float(a @ b)) / (np.linalg.norm(a) * np.linalg.norm(b))))


def test_peg_cell_looks_across_the_transfer_from_above(peg_cell) -> None:
    views = cell_views(peg_cell)
    front = views.front
    h1 = peg_cell.features["HOLE1"].world_T_feature[:3, 3]
    h2 = peg_cell.features["HOLE2"].world_T_feature[:3, 3]
    sight = front.look_at - front.position
    # the line of sight is far from the HOLE1-HOLE2 line: the holes stand apart on the screen
    assert angle_deg(sight, h2 - h1) > 45.0
    horizontal = np.array([sight[0], sight[1], 0.0])
    assert angle_deg(horizontal, h2 - h1) >= 40.0, "looks across the transfer axis, not along it"
    elevation = math.degrees(math.atan2(-sight[2], np.linalg.norm(sight[:2])))
    assert 35.0 <= elevation <= 50.0
    xy, _ = pinhole(front, np.array([h1, h2]))
    assert abs(xy[0, 0] - xy[1, 0]) > 0.2, "the two holes lie apart across the view"
    # the camera looks at the work: the plate's middle, between the holes, near the view's middle
    plate = peg_cell.object("plate")
    xy, _ = pinhole(front, plate.world_T_object[:3, 3][None])
    assert np.all(np.abs(xy) < 0.25)


def test_peg_cell_focus_is_the_task_not_the_table(peg_cell) -> None:
    focus = work_focus(peg_cell)
    assert {"plate", "peg", "HOLE1", "HOLE2", "tool"} <= set(focus.names)
    assert "table" not in focus.names
    # the plate (300 mm long) fills a good part of the view: at least a quarter of its width
    front = cell_views(peg_cell).front
    xy, _ = pinhole(front, object_vertices(peg_cell.object("plate")))
    assert np.ptp(xy[:, 0]) / 2.0 > 0.25
    # and the whole table does not: it is context, partly out of the picture
    assert not inside(front, object_vertices(peg_cell.object("table"))).all()


def test_every_shipped_cell_holds_its_objects_in_view(cell) -> None:
    views = cell_views(cell)
    focus = views.focus
    for name in ("front", "side", "top"):
        view = views.preset(name)
        assert inside(view, focus.points).all(), f"{cell.name}: the {name} view cuts off part of {focus.names}"
        xy, _ = pinhole(view, focus.points)
        span = max(np.ptp(xy[:, 0]), np.ptp(xy[:, 1])) / 2.0
        # the default fills a good part of the view; the others may stand back to keep out of the arm
        least = 0.4 if name == "front" else 0.2
        assert span > least, f"{cell.name}: the {name} view leaves the work small ({span:.2f} of the view)"
    # what the task is about is in the front view entirely: the features and the objects the arm
    # moves or that carry a feature; every other object shows at least in part
    front = views.front
    for feature in cell.features.values():
        assert inside(front, feature.world_T_feature[:3, 3][None]).all()
    for obj in cell.objects:
        v = object_vertices(obj)
        if obj.name in focus.names and cell.features:
            assert inside(front, v).all(), f"{cell.name}: {obj.name} is not wholly in view"
        else:
            assert inside(front, v).any() or inside(front, v.mean(axis=0)[None]).any(), f"{cell.name}: {obj.name} out of view"
    # the tool at home is in the view
    assert inside(front, focus.tool[None]).all()
    # seen from above, at the front elevation
    sight = front.look_at - front.position
    assert math.degrees(math.atan2(-sight[2], np.linalg.norm(sight[:2]))) == pytest.approx(math.degrees(FRONT_ELEVATION), abs=1e-6)


def test_the_default_is_computed_from_the_cell_not_written_in(peg_cell, tmp_path: Path) -> None:
    """Move the plate, its holes and the peg 300 mm along x and turn the transfer line to x:
    the view follows the work and still looks across its new line."""
    text = PEG.read_text()
    text = text.replace('[frames.work]\nxyz = [550.0, 0.0, 350.0]', '[frames.work]\nxyz = [550.0, 0.0, 350.0]\nrpy = [0.0, 0.0, 90.0]')
    moved = tmp_path / "turned.toml"
    moved.write_text(text)
    turned = load_cell(moved)
    h1 = turned.features["HOLE1"].world_T_feature[:3, 3]
    h2 = turned.features["HOLE2"].world_T_feature[:3, 3]
    assert abs((h2 - h1)[0]) > 0.15 and abs((h2 - h1)[1]) < 1e-6, "the holes now lie along x"
    sight = cell_views(turned).front.look_at - cell_views(turned).front.position
    assert angle_deg(np.array([sight[0], sight[1], 0.0]), h2 - h1) >= 40.0
    before = cell_views(peg_cell).front
    assert not np.allclose(before.position, cell_views(turned).front.position)


def test_front_direction_stays_off_the_arm(peg_cell) -> None:
    """The peg cell's arm comes down from behind the work: the camera turns off its links."""
    from shared.cells.framing import ARM_CLEARANCE, _direction, arm_clearance

    focus = work_focus(peg_cell)
    d = front_direction(focus)
    assert arm_clearance(focus, _direction(d, FRONT_ELEVATION)) >= ARM_CLEARANCE - 1e-9


def test_presets(peg_cell) -> None:
    views = cell_views(peg_cell)
    assert PRESETS == ("front", "side", "top", "follow")
    front, side, top = views.preset("front"), views.preset("side"), views.preset("top")
    assert front is views.front
    for a, b in ((front, side), (front, top), (side, top)):
        assert angle_deg(a.look_at - a.position, b.look_at - b.position) > 30.0
    sight = top.look_at - top.position
    assert math.degrees(math.atan2(-sight[2], np.linalg.norm(sight[:2]))) >= 75.0
    tool = np.array([0.4, 0.1, 0.5])
    follow = views.preset("follow", tool)
    np.testing.assert_allclose(follow.look_at, tool)
    np.testing.assert_allclose(follow.position - tool, views.follow_offset)
    assert 0.2 < np.linalg.norm(views.follow_offset) < np.linalg.norm(front.position - front.look_at)
    with pytest.raises(UnknownNameError):
        views.preset("bottom")


def test_project_matches_a_pinhole(peg_cell) -> None:
    front = cell_views(peg_cell).front
    pts = object_vertices(peg_cell.object("plate"))
    mine, depth = front.project(pts)
    theirs, depth2 = pinhole(front, pts)
    np.testing.assert_allclose(mine, theirs, atol=1e-12)
    np.testing.assert_allclose(depth, depth2, atol=1e-12)


def test_no_preset_stands_inside_the_arm_or_just_behind_a_link(cell) -> None:
    """The arm at home (link origins and the points between them): each is behind the camera or
    at least ``ARM_MARGIN`` in front of it wherever it is near the line of sight."""
    from shared.cells.framing import ARM_MARGIN

    views = cell_views(cell)
    arm = views.focus.arm
    for name in ("front", "side", "top", "follow"):
        view = views.preset(name)
        xy, depth = pinhole(view, arm)
        near_sight = np.all(np.abs(xy) < 1.5, axis=1) | (np.linalg.norm(arm - view.position, axis=1) < ARM_MARGIN)
        close = near_sight & (depth > -ARM_MARGIN) & (depth < ARM_MARGIN - 1e-9)
        assert not close.any(), f"{cell.name}: the {name} view has the arm at {arm[close]} right by the lens"
