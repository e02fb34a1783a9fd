"""``shared.collision.cell_check.CellCollision``: one collision answer for a cell.

The oracles: the collision scene asked directly (``SceneModel.check`` with every distance), the
zone boundaries of the cell file applied here by hand, and, in the rover cell, the ground's own
checker (``GroundChecker``, the terrain's exact distance)."""

from __future__ import annotations

import numpy as np
import pytest

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision import SceneModel
from shared.collision.cell_check import CellCollision
from shared.language.parser import parse_program
from shared.motion.interpreter import plan_program
from shared.paths import ASSETS_DIR
from shared.robots.jog import JogFrames, world_T_tcp
from shared.terrain.ground import GroundChecker

ROVER_TERRAIN = ASSETS_DIR / "cells" / "rover_terrain.toml"
# tests/server/test_terrain_session.py: the instrument arm's last link lies on the ground
Q_ON_GROUND = np.radians([-40.0, -40.0, -200.0])
_RANK = {"free": 0, "quasi": 1, "operation": 2}


@pytest.fixture(scope="module")
def peg_cell():
    return load_cell(DEFAULT_CELL)


@pytest.fixture(scope="module")
def cc(peg_cell) -> CellCollision:
    # a coarser hierarchy than the console's: built in a fraction of the time, the same answers
    return CellCollision(peg_cell, scene=SceneModel.from_cell(peg_cell, leaf_size=8))


@pytest.fixture(scope="module")
def q_in_table(peg_cell) -> np.ndarray:
    """Where a straight line 60 cm below the base ends: the arm is down in the table."""
    statements = parse_program("DRAW TO (550, 0, -600) mm IN BASE", "t.tp").statements
    plan = plan_program(statements, peg_cell.robot, peg_cell, start_q=peg_cell.q_home)
    assert plan.refusal is None
    return plan.q_final


@pytest.fixture(scope="module")
def rover():
    cell = load_cell(ROVER_TERRAIN)
    ground = GroundChecker(cell)
    scene = SceneModel.from_cell(cell, leaf_size=8, exclude=(ground.NAME,))
    return cell, ground, CellCollision(cell, scene=scene, ground=ground)


def _pairs(report) -> set[tuple[str, str]]:
    return {(p.a, p.b) for p in report.pairs}


def _peg_at_tool(cell) -> np.ndarray:
    """The peg where the gripper's centre is at the home pose (between the fingers)."""
    frames = JogFrames(cell.world_T_base, cell.frame("work"), cell.flange_T_tcp)
    return world_T_tcp(cell.robot, cell.q_home, frames)


def _expected(cell, scene, q, tool: str):
    """From every distance the scene gives at ``q``: the tool's smallest distance to an object
    and its pair (the arm's own links are no object), and the zone with the cell file's
    boundaries applied here (the most restrictive object, the nearest first), the object that
    sets it and its distance."""
    full = scene.check(q, distances="all")
    links = {f"link{i}" for i in range(cell.robot.dof + 1)}
    from_tool = {pair: d.distance for pair, d in full.distances.items() if tool in pair and not set(pair) <= links}
    nearest = min(from_tool, key=from_tool.get)
    zones = []
    for obj in cell.object_names:
        d = max(min(v for pair, v in from_tool.items() if obj in pair), 0.0)
        limits = cell.zone_distances(obj)
        z = "operation" if d <= limits.operation else "quasi" if d <= limits.quasi else "free"
        zones.append((-_RANK[z], d, obj, z))
    _, d, obj, z = min(zones)
    return from_tool[nearest], nearest, z, obj, d


def test_home_is_clear_and_the_nearest_is_the_tools_nearest(peg_cell, cc) -> None:
    q = peg_cell.q_home
    report = cc.check(q)
    assert not report.colliding and report.pairs == () and report.triangles == {}
    assert report.ground is None  # no terrain in this cell
    tool = f"link{peg_cell.robot.dof}"
    d_min, nearest, zone, obj, d_zone = _expected(peg_cell, cc.scene, q, tool)
    assert report.min_distance == pytest.approx(d_min, abs=1e-9)
    assert set(report.nearest) == set(nearest)
    assert (report.zone, report.zone_object) == (zone, obj) == ("quasi", "peg")
    assert report.zone_distance == pytest.approx(d_zone, abs=1e-9)


def test_a_pose_in_the_table_reports_the_pairs_and_their_triangles(peg_cell, cc, q_in_table) -> None:
    report = cc.check(q_in_table)
    assert report.colliding
    direct = cc.scene.check(q_in_table, distances="none")
    assert set(report.pairs) == _pairs(direct)
    assert any("table" in p and any(b.startswith("link") for b in p) for p in report.pairs)
    bodies = {b for p in report.pairs for b in p}
    assert set(report.triangles) == bodies
    for body in bodies:
        assert len(report.triangles[body]) > 0
        np.testing.assert_array_equal(report.triangles[body], direct.interfering_triangles(body))
    # the zone is the tool's (the last link's): the elbow in the table does not set it
    tool = f"link{peg_cell.robot.dof}"
    _, _, zone, obj, d_zone = _expected(peg_cell, cc.scene, q_in_table, tool)
    assert (report.zone, report.zone_object) == (zone, obj)
    assert report.zone_distance == pytest.approx(d_zone, abs=1e-9)


def test_the_tool_touching_the_table_is_the_operation_zone(peg_cell, cc) -> None:
    statements = parse_program("DRAW TO (550, 0, -600) mm IN BASE", "t.tp").statements
    plan = plan_program(statements, peg_cell.robot, peg_cell, start_q=peg_cell.q_home)
    tool = f"link{peg_cell.robot.dof}"
    for q in plan.sample(np.linspace(0.0, plan.duration, 81)).q:
        touching = {p for p in _pairs(cc.scene.check(q, distances="none")) if tool in p}
        if touching:
            break
    else:
        pytest.fail("the tool never touches anything on the way into the table")
    report = cc.check(q)
    assert touching <= set(report.pairs)
    assert report.zone == "operation" and report.zone_distance == pytest.approx(0.0, abs=1e-9)
    assert report.zone_object in {b for p in touching for b in p}
    assert report.min_distance <= 0.0


def test_a_held_object_does_not_collide_with_the_gripper(peg_cell, cc) -> None:
    q = peg_cell.q_home
    poses = {"peg": _peg_at_tool(peg_cell)}
    tool = f"link{peg_cell.robot.dof}"
    loose = cc.check(q, object_poses=poses)
    assert (tool, "peg") in loose.pairs and loose.colliding  # a peg there, not held: a collision
    held = cc.check(q, object_poses=poses, held="peg")
    assert (tool, "peg") not in held.pairs and not held.colliding
    # held, the peg counts as tool: it is no obstacle setting the zone
    assert held.zone_object != "peg"
    assert cc.touching(q, object_poses=poses)[0] == ((tool, "peg"),)
    assert cc.touching(q, object_poses=poses, held="peg")[0] == ()


def test_involves_arm(cc) -> None:
    assert cc.involves_arm(("link3", "table"))
    assert cc.involves_arm(["plate", "link6"])
    assert not cc.involves_arm(("table", "peg"))  # two objects: not the motion's doing
    assert not cc.involves_arm(("link6", "peg"), held="peg")  # the held object rides with the gripper
    assert cc.involves_arm(("link6", "plate"), held="peg")
    assert not cc.involves_arm(None)
    assert not cc.involves_arm(())


def test_touching_agrees_with_check_on_pairs(peg_cell, cc, q_in_table) -> None:
    statements = parse_program("DRAW TO (550, 0, -600) mm IN BASE", "t.tp").statements
    plan = plan_program(statements, peg_cell.robot, peg_cell, start_q=peg_cell.q_home)
    qs = list(plan.sample(np.linspace(0.0, plan.duration, 9)).q) + [q_in_table]
    poses = {"peg": _peg_at_tool(peg_cell)}
    seen_touching = False
    for q in qs:
        for kwargs in ({}, {"object_poses": poses}, {"object_poses": poses, "held": "peg"}):
            pairs, scene_report = cc.touching(q, **kwargs)
            full = cc.check(q, **kwargs)
            assert set(pairs) == set(full.pairs), (q, kwargs)
            assert set(pairs) == _pairs(scene_report)
            seen_touching |= bool(pairs)
    assert seen_touching
    # the triangles of the cheap answer, when asked for, are the full answer's
    pairs, scene_report = cc.touching(q_in_table, triangles=True)
    full = cc.check(q_in_table)
    for body in full.triangles:
        np.testing.assert_array_equal(scene_report.interfering_triangles(body), full.triangles[body])


def test_the_ground_of_a_rover_cell_is_merged_into_the_pairs_and_zone(rover) -> None:
    _, ground, cc = rover
    assert ground.NAME not in {b.name for b in cc.scene.bodies}  # the ground has its own checker
    exact = ground.terrain.checker.exact_check(Q_ON_GROUND)
    assert exact.in_collision  # the oracle: the terrain's own exact check
    report = cc.check(Q_ON_GROUND)
    assert report.colliding
    assert ("link3", ground.NAME) in report.pairs
    assert report.ground is not None and report.ground.in_collision
    assert {p for p in report.pairs if ground.NAME in p} == {(link, ground.NAME) for link in report.ground.touching_links}
    assert report.zone == "operation" and report.zone_object == ground.NAME
    assert report.zone_distance == pytest.approx(0.0, abs=1e-12)
    assert report.min_distance == pytest.approx(float(exact.distance), abs=1e-9) and report.min_distance <= 0.0
    assert report.nearest == (cc.tool_body, ground.NAME)
    pairs, _ = cc.touching(Q_ON_GROUND)
    assert set(pairs) == set(report.pairs)
    assert cc.involves_arm(("link3", ground.NAME))


def test_a_rover_clear_of_the_ground_is_zoned_by_the_ground(rover) -> None:
    cell, ground, cc = rover
    q = cell.q_home
    assert not ground.terrain.checker.exact_check(q).in_collision
    report = cc.check(q)
    assert not report.colliding and not any(ground.NAME in p for p in report.pairs)
    assert cc.touching(q)[0] == ()
    # the only object is the ground: it sets the zone, by the head's distance and the cell's
    # boundaries for it
    contact = ground.contact(q)
    limits = cell.zone_distances(ground.NAME)
    head = contact.head_distance
    expected = "operation" if head <= limits.operation else "quasi" if head <= limits.quasi else "free"
    assert report.zone == expected and report.zone_object == ground.NAME
    assert report.zone_distance == pytest.approx(head, abs=1e-12)
    # the nearest is the ground: the scene holds nothing else but the arm, whose own links are
    # nearer to the tool here (a self-distance the operator does not ask about)
    self_distance = cc.scene.check(q, distances=[cc.tool_body]).min_distance
    assert self_distance is not None and self_distance < contact.distance
    assert report.min_distance == pytest.approx(contact.distance, abs=1e-12)
    assert report.nearest == (cc.tool_body, ground.NAME)


def test_nearest_is_never_the_arms_own_link_pair() -> None:
    """In every shipped cell, at home and at poses drawn over the joint ranges, "Nearest" names
    the tool (or what it holds) and an object or the ground, never two of the arm's links; in a
    cell with nothing but the arm it names nothing."""
    rng = np.random.default_rng(7)
    for path in sorted((ASSETS_DIR / "cells").glob("*.toml")):
        cell = load_cell(path)
        ground = GroundChecker(cell) if any(o.name == GroundChecker.NAME for o in cell.objects) else None
        scene = SceneModel.from_cell(cell, leaf_size=8, exclude=(ground.NAME,) if ground else ())
        cc = CellCollision(cell, scene=scene, ground=ground)
        links = {f"link{i}" for i in range(cell.robot.dof + 1)}
        objects = set(cell.object_names) | ({ground.NAME} if ground else set())
        qs = [cell.q_home] + list(rng.uniform(cell.robot.lower, cell.robot.upper, size=(12, cell.robot.dof)))
        for q in qs:
            report = cc.check(q)
            if not objects:
                assert report.nearest is None and report.min_distance is None, cell.name
                continue
            assert report.nearest is not None, (cell.name, q)
            tool, other = report.nearest
            assert tool == cc.tool_body and other in objects and other not in links, (cell.name, report.nearest)
            # and it is the nearest of the tool's distances to the objects
            full = scene.check(q, distances=[cc.tool_body])
            to_objects = [d.distance for pair, d in full.distances.items() if not set(pair) <= links]
            if ground is not None:
                to_objects.append(ground.contact(q).distance)
            assert report.min_distance == pytest.approx(min(to_objects), abs=1e-9), cell.name


def test_the_nearest_of_a_held_object_is_what_it_approaches(peg_cell, cc) -> None:
    """Holding the peg, the tool is the gripper and the peg: the nearest pair starts with one of them."""
    report = cc.check(peg_cell.q_home, object_poses={"peg": _peg_at_tool(peg_cell)}, held="peg")
    assert report.nearest is not None and report.nearest[0] in {cc.tool_body, "peg"}
    assert report.nearest[1] in {"table", "plate"}
