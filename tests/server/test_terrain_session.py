"""The rover terrain cell in the console session: arm-ground contact merged into the collision
view and zone, the virtual sensors on demand, picking and instrument placement into the program,
the preview's ground warnings, and the HTTP endpoints (seed 004, issue 9 item 6)."""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from server.console import PlacementChanged, Regime, Session, TerrainChanged
from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision import SceneModel
from shared.errors import InputError
from shared.paths import ASSETS_DIR
from shared.terrain.cell import load_cell_terrain
from shared.terrain.ground import GroundChecker

ROVER_TERRAIN = ASSETS_DIR / "cells" / "rover_terrain.toml"
# found by sampling the joint ranges: the arm deployed, the instrument head 36 mm into the ground
Q_ON_GROUND = np.radians([-40.0, -40.0, -200.0])
TARGET_XY = (0.70, 0.0)  # m, reachable ground in front of the rover


@pytest.fixture(scope="module")
def rover_cell():
    cell = load_cell(ROVER_TERRAIN)
    return cell, SceneModel.from_cell(cell, exclude=("terrain",)), load_cell_terrain(cell)


@pytest.fixture
def session(rover_cell):
    cell, scene, _ = rover_cell
    s = Session(cell, scene=scene)
    yield s
    s.close()


def test_the_generic_scene_leaves_the_terrain_to_its_own_tree(session) -> None:
    assert session.terrain.available
    assert "terrain" not in {b.name for b in session.arm.collision.scene.bodies}
    with pytest.raises(InputError, match="unknown object to exclude .nonexistent."):
        SceneModel.from_cell(session.cell, exclude=("nonexistent",))


def test_arm_on_the_ground_is_a_collision_with_red_triangles(session, rover_cell) -> None:
    _, _, terrain = rover_cell
    clear = session.terrain.view()
    assert not clear.in_collision and clear.distance > 0 and not clear.contact_corners
    assert not session.arm.collision_view().colliding
    events = []
    session.subscribe_events(events.append)
    session.arm.set_q(Q_ON_GROUND)
    view = session.terrain.view()
    assert view.in_collision and view.distance <= 0
    expected = terrain.checker.contact_triangles(Q_ON_GROUND)
    assert len(view.contact_corners) == len(expected) > 0
    # the corners sent to the page are those triangles of the terrain mesh, in the world
    np.testing.assert_allclose(view.contact_corners, terrain.mesh.vertices[terrain.mesh.faces[expected]])
    collision = session.arm.collision_view()
    assert collision.colliding and ("link3", "terrain") in [tuple(p) for p in collision.pairs]
    assert collision.min_distance <= 0
    assert any(isinstance(e, TerrainChanged) and e.terrain.in_collision for e in events)


def test_the_witness_segment_is_the_exact_distance(session, rover_cell) -> None:
    _, _, terrain = rover_cell
    view = session.terrain.view()
    exact = terrain.checker.exact_check(session.arm.state.q)
    assert view.distance == pytest.approx(exact.distance)
    assert np.linalg.norm(np.subtract(view.world_p_arm, view.world_p_terrain)) == pytest.approx(view.distance, abs=1e-9)


def test_sensors_are_sent_only_while_shown(session) -> None:
    assert session.terrain.view().sensors is None
    shown = session.terrain.set_sensors(True)
    assert shown.sensors is not None
    n = len(shown.sensors.starts)
    assert n == len(shown.sensors.ends) == len(shown.sensors.collides) > 0
    session.arm.set_q(Q_ON_GROUND)  # the sensors follow the arm
    moved = session.terrain.view().sensors
    assert moved is not None and moved.starts != shown.sensors.starts
    assert session.terrain.set_sensors(False).sensors is None


def test_placement_from_a_ground_position_enters_the_program(session) -> None:
    events = []
    session.subscribe_events(events.append)
    placement = session.terrain.place_instrument(ground_xy=TARGET_XY)
    assert placement.candidates, placement.message
    assert placement.world_p_target[:2] == pytest.approx(list(TARGET_XY))
    assert any(isinstance(e, PlacementChanged) and e.placement == placement for e in events)
    assert session.terrain.placement_view() == placement
    program = session.terrain.insert_placement()
    texts = [e.text for e in program.entries if e.kind != "EMPTY"]
    assert texts == placement.program
    # the best configuration: C within 30 mm of the ground, the rest of the arm clear
    session.terrain.goto_placement(0)
    np.testing.assert_allclose(session.arm.state.q, placement.candidates[0].q, atol=1e-12)
    view = session.terrain.view()
    assert 0.0 < view.head_distance <= 0.030
    assert session.arm.collision_view().zone is Regime.OPERATION  # the head is within the operation boundary
    assert session.arm.collision_view().zone_object == "terrain"


def test_a_click_ray_picks_the_ground_point_below(session) -> None:
    below = session.terrain.ground_point(*TARGET_XY)
    picked = session.terrain.pick(np.array([TARGET_XY[0], TARGET_XY[1], 2.0]), np.array([0.0, 0.0, -3.0]))
    np.testing.assert_allclose(picked, below, atol=1e-9)
    via_ray = session.terrain.place_instrument(ray=((TARGET_XY[0], TARGET_XY[1], 2.0), (0.0, 0.0, -1.0)))
    np.testing.assert_allclose(via_ray.world_p_target, below, atol=1e-9)
    with pytest.raises(InputError, match="misses the ground"):
        session.terrain.place_instrument(ray=((0.0, 0.0, 2.0), (0.0, 0.0, 1.0)))  # up into the sky


def test_bad_targets_are_clear_errors(session) -> None:
    with pytest.raises(InputError, match="outside the terrain"):
        session.terrain.place_instrument(ground_xy=(5.0, 5.0))
    with pytest.raises(InputError, match="exactly one"):
        session.terrain.place_instrument(ground_xy=TARGET_XY, world_p=(0.7, -0.1, 0.0))
    with pytest.raises(InputError, match="pick a target"):
        session.terrain.insert_placement()


def test_preview_warns_when_a_statement_runs_the_arm_into_the_ground(session) -> None:
    q = np.degrees(Q_ON_GROUND)
    session.program.insert(f"MOVE ({q[0]:.1f}, {q[1]:.1f}, {q[2]:.1f}) deg")
    preview = session.preview.begin(0, 1)
    assert any(w.kind == "collision" and "terrain" in w.bodies for w in preview.warnings), preview.warnings
    session.preview.end()


def test_other_cells_have_no_terrain() -> None:
    cell = load_cell(DEFAULT_CELL)
    assert GroundChecker.for_cell(cell) is None


def test_terrain_endpoints(rover_cell, tmp_path) -> None:
    from server.app import create_app
    from server.settings import ConsoleSettings

    app = create_app(ConsoleSettings(cell=ROVER_TERRAIN, no_robot=True), build_page=False)
    with TestClient(app) as client:
        view = client.get("/api/terrain").json()
        assert view["distance"] > 0 and view["sensors"] is None
        assert client.put("/api/terrain/sensors", json={"show": True}).json()["sensors"]["starts"]
        bad = client.post("/api/terrain/placement", json={})
        assert bad.status_code == 422
        outside = client.post("/api/terrain/placement", json={"ground_mm": [5000, 5000]})
        assert outside.status_code == 400 and "outside the terrain" in outside.json()["detail"]
        placed = client.post("/api/terrain/placement", json={"ground_mm": [700, 0]}).json()
        assert placed["candidates"]
        program = client.post("/api/terrain/placement/insert").json()
        assert [e["text"] for e in program["entries"] if e["kind"] != "EMPTY"] == placed["program"]
        state = client.post("/api/terrain/placement/goto", json={"candidate": 1}).json()
        np.testing.assert_allclose(state["q_deg"], placed["candidates"][0]["q_deg"], atol=1e-9)
    default = create_app(ConsoleSettings(no_robot=True), build_page=False)
    with TestClient(default) as client:
        reply = client.get("/api/terrain")
        assert reply.status_code == 400 and "no terrain" in reply.json()["detail"]
