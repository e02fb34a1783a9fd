"""Mechanical interference zones (seed 001): feasibility tests, detours, generated zones."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.collision.interference import (
    InterferenceZones,
    PathDetour,
    PathOk,
    PathRefused,
    PolygonZone,
    PolyhedronZone,
    distance_to_boundary,
    points_in_polygon,
    sample_self_collision,
    wrap_polygons,
    zones_from_toml,
)
from shared.errors import FileFormatError, InputError

# A non-convex zone in the (J1, J2) plane: a "U" opening upwards (pocket between x=2 and x=3).
U_SHAPE = np.array([[1, 1], [4, 1], [4, 4], [3, 4], [3, 2], [2, 2], [2, 4], [1, 4]], dtype=float)


def _u_zones(lower=(0.0, 0.0), upper=(5.0, 5.0)) -> InterferenceZones:
    return InterferenceZones(lower, upper, [PolygonZone((1, 2), U_SHAPE, "U")])


def _path(a, b, result) -> list[np.ndarray]:
    return [np.asarray(a, float)] + [np.asarray(w) for w in getattr(result, "waypoints", ())] + [np.asarray(b, float)]


def _enters(zone: PolygonZone, pts: list[np.ndarray], axes=(0, 1)) -> bool:
    """Dense sampling of the polyline: any sample strictly inside the zone (beyond 1e-7)?"""
    ax = list(axes)
    for p, q in zip(pts[:-1], pts[1:]):
        s = np.linspace(0.0, 1.0, 2001)[:, None]
        xy = (p + s * (q - p))[:, ax]
        inside = points_in_polygon(xy, zone.vertices) & (distance_to_boundary(xy, zone.vertices) > 1e-7)
        if inside.any():
            return True
    return False


def _length(pts: list[np.ndarray]) -> float:
    return float(sum(np.linalg.norm(q - p) for p, q in zip(pts[:-1], pts[1:])))


def test_point_inside_by_parity_and_boundary_is_outside() -> None:
    pts = np.array([[1.5, 3.0], [2.5, 3.0], [2.5, 1.5], [0.5, 0.5], [1.0, 2.0], [4.0, 4.0], [3.5, 1.0]])
    assert points_in_polygon(pts, U_SHAPE).tolist() == [True, False, True, False, False, False, False]


def test_goal_inside_is_refused_with_the_reason() -> None:
    res = _u_zones().check_path(np.array([0.5, 0.5]), np.array([1.5, 3.0]))
    assert isinstance(res, PathRefused)
    assert "goal lies inside" in res.reason and res.zone == "U" and "J1=" in res.reason


def test_straight_paths_that_miss_or_graze_the_zone_are_ok() -> None:
    iz = _u_zones()
    assert isinstance(iz.check_path(np.array([0.5, 0.5]), np.array([4.5, 0.5])), PathOk)  # below
    assert isinstance(iz.check_path(np.array([2.5, 4.5]), np.array([2.5, 2.5])), PathOk)  # into the pocket
    assert isinstance(iz.check_path(np.array([0.5, 1.0]), np.array([4.5, 1.0])), PathOk)  # along the bottom edge
    assert isinstance(iz.check_path(np.array([0.0, 2.0]), np.array([2.0, 0.0])), PathOk)  # through vertex (1, 1)
    assert iz.crossed_zone(np.array([0.5, 3.0]), np.array([4.5, 3.0])).name == "U"  # through both arms


def test_start_inside_may_leave_but_not_cross_again() -> None:
    iz = _u_zones()
    assert isinstance(iz.check_path(np.array([1.5, 3.0]), np.array([0.5, 3.0])), PathOk)
    res = iz.check_path(np.array([1.5, 3.0]), np.array([4.5, 3.0]))  # leaves, then enters the right arm
    assert isinstance(res, PathDetour)
    assert not _enters(PolygonZone((1, 2), U_SHAPE), _path([1.5, 3.0], [4.5, 3.0], res)[1:])


def _shortest_vertex_path(a: np.ndarray, b: np.ndarray, zone: PolygonZone, lower, upper, max_len: int = 4) -> float:
    """Brute force over every sequence of up to ``max_len`` distinct vertices within the ranges."""
    verts = [v for v in zone.vertices if np.all(v >= lower) and np.all(v <= upper)]
    best = np.inf
    for k in range(1, max_len + 1):
        for seq in itertools.permutations(range(len(verts)), k):
            pts = [a] + [verts[i] for i in seq] + [b]
            length = _length(pts)
            if length < best and not _enters(zone, pts):
                best = length
    return best


@pytest.mark.parametrize(
    "a, b",
    [((0.5, 3.0), (4.5, 3.0)), ((2.5, 3.5), (4.5, 2.5)), ((2.5, 3.0), (2.5, 0.5)), ((0.5, 2.5), (4.5, 3.5))],
)
def test_detour_avoids_the_zone_and_is_the_shortest_vertex_path(a, b) -> None:
    a, b = np.array(a), np.array(b)
    zone = PolygonZone((1, 2), U_SHAPE, "U")
    res = _u_zones().check_path(a, b)
    assert isinstance(res, PathDetour) and res.zones == ("U",)
    pts = _path(a, b, res)
    assert not _enters(zone, pts)
    assert _length(pts) == pytest.approx(_shortest_vertex_path(a, b, zone, np.zeros(2), np.full(2, 5.0)), abs=1e-9)


def test_detour_stays_within_joint_ranges_or_is_refused() -> None:
    # J2 may not go below 1.5: the way under the U is closed, so the detour goes over the top
    iz = _u_zones(lower=(0.0, 1.5), upper=(5.0, 5.0))
    res = iz.check_path(np.array([2.5, 3.5]), np.array([4.5, 2.5]))
    assert isinstance(res, PathDetour)
    assert all(w[1] >= 1.5 for w in res.waypoints)
    # and with the top closed too there is no way out of the pocket
    boxed = _u_zones(lower=(0.0, 1.5), upper=(5.0, 3.9))
    res = boxed.check_path(np.array([2.5, 3.5]), np.array([4.5, 2.5]))
    assert isinstance(res, PathRefused) and "joint ranges" in res.reason


def test_other_joints_move_in_proportion_along_the_detour() -> None:
    iz = InterferenceZones([0, 0, -1, -1], [5, 5, 1, 1], [PolygonZone((2, 3), U_SHAPE[:, ::-1] * [1, 0.4] - [0, 1.2], "U23")])
    zone = iz.zones[0]
    # zone in (J2, J3); J1 and J4 move from 0 to 1 / 0 to -1
    a = np.array([0.0, 3.0, -1.0, 0.0])
    b = np.array([1.0, 3.0, 1.0, -1.0])
    assert iz.crossed_zone(a, b) is zone
    res = iz.check_path(a, b)
    assert isinstance(res, PathDetour)
    pts = _path(a, b, res)
    assert not _enters(zone, pts, axes=(1, 2))
    j1 = [p[0] for p in pts]
    assert j1 == sorted(j1) and all(p[3] == pytest.approx(-p[0]) for p in pts)


def _reenters(zone: PolygonZone, pts: list[np.ndarray]) -> bool:
    """Along the polyline: is any sample strictly inside the zone after one outside it?"""
    xy = np.vstack([p + np.linspace(0.0, 1.0, 2001)[:, None] * (q - p) for p, q in zip(pts[:-1], pts[1:])])
    inside = points_in_polygon(xy, zone.vertices) & (distance_to_boundary(xy, zone.vertices) > 1e-7)
    outside = np.flatnonzero(~inside)
    return bool(len(outside) and inside[outside[0] :].any())


@settings(max_examples=60, deadline=None)
@given(
    st.tuples(st.floats(0.0, 5.0), st.floats(0.0, 5.0)),
    st.tuples(st.floats(0.0, 5.0), st.floats(0.0, 5.0)),
)
def test_any_move_is_ok_detoured_or_refused_consistently(a, b) -> None:
    a, b = np.array(a), np.array(b)
    zone = PolygonZone((1, 2), U_SHAPE, "U")
    res = _u_zones().check_path(a, b)
    if zone.contains(b):
        assert isinstance(res, PathRefused)
        return
    assert isinstance(res, (PathOk, PathDetour))
    pts = _path(a, b, res)
    assert not _reenters(zone, pts)
    if not zone.contains(a):
        assert not _enters(zone, pts)


def test_polyhedron_inside_crossing_and_detour() -> None:
    cube = np.array(list(itertools.product([1.0, 2.0], repeat=3)))
    zone = PolyhedronZone((1, 2, 3), cube, "box")
    iz = InterferenceZones([0, 0, 0], [3, 3, 3], [zone])
    assert zone.contains(np.array([1.5, 1.5, 1.5])) and not zone.contains(np.array([1.0, 1.5, 1.5]))
    assert isinstance(iz.check_path(np.zeros(3), np.array([1.5, 1.5, 1.5])), PathRefused)
    assert isinstance(iz.check_path(np.array([0.5, 0.5, 1.5]), np.array([2.5, 0.5, 1.5])), PathOk)
    a, b = np.array([0.5, 1.4, 1.3]), np.array([2.5, 1.6, 1.45])
    res = iz.check_path(a, b)
    assert isinstance(res, PathDetour)
    pts = _path(a, b, res)
    for p, q in zip(pts[:-1], pts[1:]):
        for s in np.linspace(0, 1, 501):
            x = p + s * (q - p)
            assert not np.all(zone.normals @ x + zone.offsets < -1e-7)
    # no shorter path over two cube vertices exists
    best = min(
        _length([a, cube[i], cube[j], b])
        for i in range(8)
        for j in range(8)
        if not zone.inside_intervals(a, cube[i]) and not zone.inside_intervals(cube[i], cube[j]) and not zone.inside_intervals(cube[j], b)
    )
    assert _length(pts) <= best + 1e-9


def test_bad_zones_are_refused() -> None:
    with pytest.raises(InputError, match="at least 3"):
        PolygonZone((1, 2), np.array([[0.0, 0.0], [1.0, 1.0]]))
    with pytest.raises(InputError, match="zero area"):
        PolygonZone((1, 2), np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]))
    with pytest.raises(InputError, match="cross"):
        PolygonZone((1, 2), np.array([[0.0, 0.0], [2.0, 2.0], [2.0, 0.0], [0.0, 1.0]]))  # a bow tie
    with pytest.raises(InputError, match="flat"):
        PolyhedronZone((1, 2, 3), np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float))
    with pytest.raises(InputError, match="joints 1..2"):
        InterferenceZones([0, 0], [1, 1], [PolygonZone((2, 3), U_SHAPE)])
    with pytest.raises(InputError, match="2 finite"):
        _u_zones().check_path(np.zeros(3), np.zeros(2))


def test_zones_from_a_toml_file(tmp_path: Path) -> None:
    path = tmp_path / "zones.toml"
    path.write_text(
        '[[interference_zones]]\nname = "elbow"\njoints = [2, 3]\nunit = "deg"\n'
        "vertices = [[0, 0], [10, 0], [10, 10], [0, 10]]\n"
    )
    (z,) = zones_from_toml(path)
    assert z.joints == (2, 3) and z.name == "elbow" and z.origin == "file"
    assert z.contains(np.radians([5.0, 5.0]))
    path.write_text('[[interference_zones]]\njoints = [2, 3]\nvertices = [[0, 0], [1, 1]]\n')
    with pytest.raises(FileFormatError) as err:
        zones_from_toml(path)
    assert str(path) in str(err.value) and "interference_zones.0" in str(err.value)
    path.write_text('[[interference_zones]]\njoints = [2, 3]\n')
    with pytest.raises(FileFormatError, match="vertices"):
        zones_from_toml(path)


# --- zones generated from the PUMA's self-collision ----------------------------------------------
STEP_DEG = 4.0


@pytest.fixture(scope="module")
def puma():
    from shared.robots.loader import load_robot

    return load_robot("puma562")


@pytest.fixture(scope="module")
def self_model(puma):
    from shared.collision.interference import self_collision_model

    model, excluded = self_collision_model(puma)
    return model, excluded


@pytest.fixture(scope="module")
def grid23(puma, self_model):
    return sample_self_collision(puma, (2, 3), step_deg=STEP_DEG, model=self_model[0])


def test_always_overlapping_wrist_pairs_are_declared_and_not_sampled(puma, self_model) -> None:
    model, excluded = self_model
    assert excluded == ()  # the robot file already lists them
    assert {(3, 6), (4, 6)} <= set(puma.description.always_in_contact)
    assert ("link3", "link6") not in model.pair_names and ("link4", "link6") not in model.pair_names
    assert ("link0", "link2") in model.pair_names


def test_generated_zone_wraps_the_colliding_samples(grid23) -> None:
    zones = wrap_polygons(grid23)
    assert zones and all(z.origin == "generated" and z.joints == (2, 3) for z in zones)
    pts = grid23.points()
    coll = grid23.colliding.ravel()
    inside = np.zeros(len(pts), dtype=bool)
    for z in zones:
        inside |= points_in_polygon(pts, z.vertices)
    assert inside[coll].all()  # every colliding sample is in a zone
    # a free sample may be inside only next to a colliding one (the boundary is known to a step)
    h = grid23.steps
    coll_pts = pts[coll]
    for p in pts[inside & ~coll]:
        assert np.min(np.max(np.abs(coll_pts - p) / h, axis=1)) <= 1.0 + 1e-9


def test_generated_zone_agrees_with_the_collision_core_off_the_grid(puma, self_model, grid23) -> None:
    """Fresh configurations between the grid points: colliding ones are in a zone and free
    ones outside, except within the tolerance (one step) of a zone's boundary."""
    model = self_model[0]
    zones = wrap_polygons(grid23)
    rng = np.random.default_rng(7)
    tol = float(np.hypot(*grid23.steps))
    # half the samples near the boundaries, half anywhere in the ranges
    near = []
    for z in zones:
        v = z.vertices
        k = rng.integers(0, len(v), 100)
        s = rng.uniform(0, 1, (100, 1))
        edge_pts = v[k] + s * (np.roll(v, -1, axis=0)[k] - v[k])
        near.append(edge_pts + rng.normal(0, tol, edge_pts.shape))
    lo, hi = puma.lower[[1, 2]], puma.upper[[1, 2]]
    cand = np.clip(np.vstack(near + [rng.uniform(lo, hi, (200, 2))]), lo, hi)
    data = model.new_data()
    n_coll = 0
    for p in cand:
        q = grid23.q_ref.copy()
        q[[1, 2]] = p
        hit = bool(model.pair_hits(q, data=data).any())
        n_coll += hit
        in_zone = any(z.contains(p) for z in zones)
        if hit != in_zone:
            d = min(distance_to_boundary(p[None, :], z.vertices)[0] for z in zones)
            assert d <= tol, f"{np.degrees(p)} deg: colliding={hit}, in zone={in_zone}, {d:.4f} rad from a boundary"
    assert n_coll > 20  # the test saw colliding configurations


def test_generated_zone_refuses_and_detours_real_moves(puma, grid23) -> None:
    zones = wrap_polygons(grid23)
    iz = InterferenceZones.for_robot(puma, zones)
    # the upper arm meets the pedestal near the top of J2's range, whatever J3 is
    res = iz.check_path(np.radians([0, 0, 90, 0, 0, 0]), np.radians([0, 44.5, 90, 0, 0, 0]))
    assert isinstance(res, PathRefused) and "goal lies inside" in res.reason
    # moves between free configurations whose straight path crosses the elbow-fold zone's
    # staircase are detoured round it
    rng = np.random.default_rng(11)
    lo, hi = np.radians([0.0, 150.0]), puma.upper[[1, 2]]
    detours = 0
    for _ in range(3000):
        a, b = grid23.q_ref.copy(), grid23.q_ref.copy()
        a[[1, 2]] = rng.uniform(lo, hi)
        b[[1, 2]] = rng.uniform(lo, hi)
        if iz.goal_zone(a) is not None or iz.goal_zone(b) is not None or iz.crossed_zone(a, b) is None:
            continue
        res = iz.check_path(a, b)
        assert isinstance(res, PathDetour)
        pts = _path(a, b, res)
        for z in zones:
            assert not _enters(z, pts, axes=(1, 2))
        assert all(puma.within_limits(w) for w in res.waypoints)
        detours += 1
        if detours >= 3:
            break
    assert detours >= 3


def test_robot_zones_for_the_planner_are_cached(puma) -> None:
    from shared.collision.interference import robot_zones

    iz = robot_zones(puma, step_deg=STEP_DEG)
    assert robot_zones(puma, step_deg=STEP_DEG) is iz
    assert {z.joints for z in iz.zones} == {(2, 3)}
    goal = np.radians([0, 44.5, 90, 0, 0, 0])
    assert isinstance(iz.check_path(np.radians([0, 0, 90, 0, 0, 0]), goal), PathRefused)
    extra = PolygonZone((1, 2), np.radians([[-10, -10], [10, -10], [10, 10], [-10, 10]]), "box")
    both = robot_zones(puma, step_deg=STEP_DEG, extra=[extra])
    assert len(both.zones) == len(iz.zones) + 1
    assert isinstance(both.check_path(np.radians([-20, 0, 90, 0, 0, 0]), np.radians([20, 0, 90, 0, 0, 0])), PathDetour)


def test_generated_polyhedra_wrap_the_colliding_samples(puma, self_model) -> None:
    from shared.collision.interference import wrap_polyhedra

    grid = sample_self_collision(puma, (2, 3, 5), step_deg=15.0, model=self_model[0])
    zones = wrap_polyhedra(grid)
    assert zones and all(z.joints == (2, 3, 5) and z.origin == "generated" for z in zones)
    pts = grid.points()
    for p in pts[grid.colliding.ravel()]:
        assert any(z.contains(p) for z in zones)
    # convex hulls are conservative, yet most free samples stay outside
    free = pts[~grid.colliding.ravel()]
    inside = np.array([any(z.contains(p) for z in zones) for p in free])
    assert inside.mean() < 0.5
