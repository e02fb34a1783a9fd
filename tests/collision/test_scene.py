"""Scene model API: pairs, resting contacts, skips, reported triangles, errors, zones."""

from __future__ import annotations

import numpy as np
import pytest

from shared.cells.cell import ZoneDistances
from shared.collision import classify, zone
from shared.collision.tri_tri import tri_tri_intersect_np
from shared.errors import InputError, UnknownNameError
from shared.spatial import make_transform


def test_pairs_skip_adjacent_links_and_static_object_pairs(model) -> None:
    names = set(model.pair_names)
    for i in range(6):
        assert (f"link{i}", f"link{i + 1}") not in names
    assert ("link0", "link2") in names and ("link6", "peg") in names
    assert ("table", "plate") not in names  # neither moves
    assert ("table", "peg") in names and ("plate", "peg") in names
    assert model.resting_pairs == {frozenset(("plate", "peg"))}  # the peg stands on its hole's floor


def test_resting_contact_is_skipped_until_the_peg_moves(cell, model) -> None:
    far = {"peg": make_transform(translation=np.array([0.55, -0.08, 0.6]))}
    assert ("plate", "peg") not in model.check(cell.q_home).distances
    assert model.check(cell.q_home, object_poses=far).distance("peg", "plate").distance > 0.1
    at_rest = model.check(cell.q_home, object_poses={"peg": cell.object("peg").world_T_object})
    assert ("plate", "peg") in at_rest.triangle_pairs  # put back on the floor: touching


# the gripper lowered into the plate beside the holes (the only interfering pair)
Q_INTO_PLATE = np.radians([0.0, -30.0, 180.0, 0.0, 45.0, 0.0])


def test_wrist_pairs_declared_in_the_robot_file_are_never_checked(cell, model) -> None:
    names = set(model.pair_names)
    for pair in (("link3", "link6"), ("link4", "link6"), ("link3", "link5")):
        assert pair not in names
    assert not model.check(cell.q_home).colliding  # the ready pose touches nothing


def test_compiled_link_poses_match_the_robot_model(cell, model) -> None:
    assert model._chain is not None  # the PUMA is a DH chain: the compiled path is taken
    rng = np.random.default_rng(5)
    links = list(model.link_bodies)
    for q in rng.uniform(cell.robot.lower, cell.robot.upper, size=(50, cell.robot.dof)):
        ours = model._world_poses(q, None)[links]
        ref = cell.world_T_base @ cell.robot.link_poses(q)[model.link_indices]
        np.testing.assert_allclose(ours, ref, atol=1e-12)


def test_reported_triangles_really_interfere(cell, model) -> None:
    report = model.check(Q_INTO_PLATE)
    assert report.colliding and report.pairs
    poses = model.body_poses(Q_INTO_PLATE)
    for a, b in report.triangle_pairs:
        ma, mb = model.mesh(a), model.mesh(b)
        for ta, tb in report.triangle_pairs[(a, b)][:50]:
            pa = ma.vertices[ma.faces[ta]] @ poses[a][:3, :3].T + poses[a][:3, 3]
            pb = mb.vertices[mb.faces[tb]] @ poses[b][:3, :3].T + poses[b][:3, 3]
            assert tri_tri_intersect_np(pa, pb)
    for pair in report.pairs:
        assert set(pair.tris_a) == set(report.triangle_pairs[(pair.a, pair.b)][:, 0])
    assert set(report.interfering_triangles("link6")) >= set(report.pairs[0].tris_a)


def test_skip_and_first_hit_and_no_distances(cell, model) -> None:
    touching = (("link6", "plate"),)
    full = model.check(Q_INTO_PLATE)
    assert {(p.a, p.b) for p in full.pairs} == set(touching)
    assert len(full.pairs[0].tris_a) > 1 and full.min_distance == 0.0
    clean = model.check(Q_INTO_PLATE, skip=touching)
    assert not clean.colliding and clean.min_distance > 0
    quick = model.check(Q_INTO_PLATE, triangles=False, distances="none")
    assert quick.colliding and {(p.a, p.b) for p in quick.pairs} == set(touching)
    assert all(len(p.tris_a) == 1 for p in quick.pairs)
    assert quick.min_distance is None and quick.distances == {}
    some = model.check(cell.q_home, distances=["peg", ("link6", "table")])
    assert set(some.distances) == {("link6", "table")} | {k for k in model.pair_names if "peg" in k and k != ("plate", "peg")}


def test_distances_witness_points_and_lookup(cell, model) -> None:
    report = model.check(cell.q_home)
    d = report.distance("peg", "link6")
    assert d.a == "peg" and d.distance == pytest.approx(np.linalg.norm(d.point_a - d.point_b))
    assert report.nearest.distance == report.min_distance == min(v.distance for v in report.distances.values())


def test_bad_input_is_refused_with_the_choices(cell, model) -> None:
    with pytest.raises(UnknownNameError, match="peg"):
        model.check(cell.q_home, object_poses={"pge": np.eye(4)})
    with pytest.raises(UnknownNameError):
        model.check(cell.q_home, skip=[("link1", "link2")])  # adjacent: never checked
    with pytest.raises(InputError):
        model.check(cell.q_home, distances="some")
    with pytest.raises(InputError):
        model.check(np.zeros(5))
    with pytest.raises(InputError):
        model.check(cell.q_home, object_poses={"peg": np.full((4, 4), np.nan)})


def test_model_is_shared_data_is_per_caller(cell, model) -> None:
    d1, d2 = model.new_data(), model.new_data()
    rng = np.random.default_rng(3)
    for q in rng.uniform(cell.robot.lower, cell.robot.upper, size=(20, 6)):
        r1 = model.check(q, data=d1)
        r2 = model.check(q, data=d2)
        assert r1.triangle_pairs.keys() == r2.triangle_pairs.keys()
        assert r1.min_distance == pytest.approx(r2.min_distance, abs=1e-12)


def test_check_world_with_given_poses(cell, model) -> None:
    poses = model.body_poses(cell.q_home)
    by_name = model.check_world(poses)
    by_q = model.check(cell.q_home)
    assert by_name.triangle_pairs.keys() == by_q.triangle_pairs.keys() | {("plate", "peg")}  # all objects given: moved
    arr = model.check_world(np.array([poses[n] for n in model.body_names]))
    assert arr.triangle_pairs.keys() == by_name.triangle_pairs.keys()


def test_zone_classification(cell, model) -> None:
    limits = ZoneDistances(quasi=0.1, operation=0.02)
    assert classify(0.2, limits) == "free" and classify(0.1, limits) == "quasi" and classify(0.02, limits) == "operation"
    state = zone(model, cell, cell.q_home)
    assert state.nearest == "peg" and state.zone == "quasi"
    assert set(state.distances) == {"table", "plate", "peg"}
    assert state.zones["table"] == classify(state.distances["table"], cell.zone_distances("table"))
    # lower the arm towards the peg: the zone tightens to operation
    q = cell.q_home.copy()
    for _ in range(60):
        q[1] += 0.01
        s = zone(model, cell, q)
        if s.zone == "operation":
            break
    assert s.zone == "operation" and s.distance <= cell.zone_distances(s.object).operation
    # holding the peg: it is tool, not an obstacle
    held = zone(model, cell, cell.q_home, held=["peg"])
    assert "peg" not in held.distances
