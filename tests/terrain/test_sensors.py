"""The paper's virtual-sensor check (a) beside the exact distance (b): where it agrees, and the
cases where it over- or under-states the clearance."""

from __future__ import annotations

import numpy as np
import pytest

from shared.terrain.arm import arm_model
from shared.terrain.checks import TerrainChecker
from shared.terrain.tree import build_tree
from shared.terrain.triangulate import TerrainMesh


def _plane(point, normal, half=3.0):
    """Two triangles of a big plane through ``point`` with upward ``normal``."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    c = np.asarray(point, float)
    v = np.array([c - half * u - half * w, c + half * u - half * w, c + half * u + half * w, c - half * u + half * w])
    return TerrainMesh(v, np.array([[0, 1, 2], [0, 2, 3]], np.int32))


def _checker(cell, mesh, n_sensors=36):
    return TerrainChecker(build_tree(mesh, 4, 2), arm_model(cell.robot, n_sensors), cell.world_T_base)


def _head_part(checker):
    arm = checker.arm
    return next(i for i, p in enumerate(arm.parts) if arm.tool_shape in p.shape_indices)


def test_paper_parts_and_sensor_layout(cell):
    arm = arm_model(cell.robot, 36)
    head = arm.parts[next(i for i, p in enumerate(arm.parts) if arm.tool_shape in p.shape_indices)]
    # the forearm and the spectrometer head are one coaxial part, wrapped at the head's radius
    assert len(head.shape_indices) == 2 and head.radius == pytest.approx(0.038)
    assert len(head.link_A) == 36
    radial = head.link_A - head.link_A.mean(axis=0)
    assert np.allclose(np.linalg.norm(radial, axis=1), 0.038)


def test_sensor_distance_overstates_on_tilted_part(cell):
    """Flat ground, forearm pointing down at an angle: the sensors measure along the axis, which
    is longer than the shortest way, so the sensor distance exceeds the exact one."""
    probe = _checker(cell, _plane([0, 0, -5.0], [0, 0, 1]))
    for q3 in range(-20, -200, -5):  # a pose whose forearm points 25-50 deg below horizontal
        q = np.radians([-30.0, -20.0, float(q3)])
        A, B, _ = probe.arm.sensors(probe.world_T_base, q, (_head_part(probe),))
        axis = (B - A).mean(axis=0)
        axis /= np.linalg.norm(axis)
        if -0.75 < axis[2] < -0.4:
            break
    else:
        pytest.fail("no tilted forearm pose found")
    ground_z = float(min(A[:, 2].min(), B[:, 2].min())) - 0.05
    checker = _checker(cell, _plane([0.7, -0.1, ground_z], [0, 0, 1]))
    exact = checker.exact_check(q)
    sensors = checker.sensor_check(q, parts=(_head_part(checker),))
    assert not exact.in_collision and not sensors.in_collision
    assert sensors.distance > exact.distance + 0.005
    # the smallest sensor reading is the axial distance from that sensor's end to the plane
    i = int(np.argmin(sensors.d_RS))
    assert sensors.d_RS[i] == pytest.approx((sensors.B[i, 2] - ground_z) / -axis[2], rel=1e-6)


def test_sensors_blind_when_parallel_to_ground(cell):
    """Rays parallel to the ground never hit it: no reading however close the ground is."""
    q = np.radians([-30.0, -20.0, -60.0])
    checker = _checker(cell, _plane([0, 0, -5.0], [0, 0, 1]))
    part = _head_part(checker)
    A, B, _ = checker.arm.sensors(checker.world_T_base, q, (part,))
    axis = (B - A).mean(axis=0)
    axis /= np.linalg.norm(axis)
    # a plane containing the part's axis direction, 10 mm below the lowest sensor
    side = np.cross(axis, [0, 0, 1.0])
    normal = np.cross(side, axis)
    normal = normal if normal[2] > 0 else -normal
    low = A[np.argmin(A @ normal)]
    checker = _checker(cell, _plane(low - 0.01 * normal, normal))
    sensors = checker.sensor_check(q, parts=(part,))
    exact = checker.exact_check(q)
    assert np.isinf(sensors.distance) and not sensors.in_collision
    assert exact.distance < 0.011


def test_spike_between_sensors_is_missed(cell):
    """A rock tip poking into the head between two of 4 sensors: the exact check reports contact,
    the sensor scheme reports clearance (it only sees the sensor lines)."""
    q = np.radians([-30.0, -20.0, -60.0])
    probe = _checker(cell, _plane([0, 0, -5.0], [0, 0, 1]), n_sensors=4)
    part = _head_part(probe)
    A, B, _ = probe.arm.sensors(probe.world_T_base, q, (part,))
    axis = B.mean(axis=0) - A.mean(axis=0)
    axis /= np.linalg.norm(axis)
    centre = B.mean(axis=0) - 0.03 * axis  # on the axis, inside the spectrometer head
    mid_ab = (A[0] + B[0]) / 2 - centre
    mid_ab2 = (A[1] + B[1]) / 2 - centre
    between = mid_ab + mid_ab2
    between /= np.linalg.norm(between)
    tip = centre + between * 0.030  # inside the 38 mm head cylinder, far from the sensor lines
    far = tip + between * 0.5
    side = np.cross(between, (B[0] - A[0]) / np.linalg.norm(B[0] - A[0]))
    spike = TerrainMesh(np.array([tip, far + 0.02 * side, far - 0.02 * side]), np.array([[0, 1, 2]], np.int32))
    checker = _checker(cell, spike, n_sensors=4)
    assert checker.exact_check(q).in_collision
    assert not checker.sensor_check(q, parts=(part,)).in_collision


def test_box_sensors_understate(cell):
    """Sensors on the circle around the base bracket's cross-section stand outside the box: a
    slightly tilted plane 3 mm from the box's face cuts sensors while the box stays clear."""
    checker0 = _checker(cell, _plane([0, 0, -5.0], [0, 0, 1]))
    arm = checker0.arm
    base_part = next(i for i, p in enumerate(arm.parts) if p.link == 0)
    box = arm.shapes[arm.parts[base_part].shape_indices[0]]
    world_T_box = cell.world_T_base @ box.link_T_shape
    hy = box.par[3]  # the box's half width across its long (x) axis
    # plane 3 mm beyond the +y face, tilted 2 degrees about z so it crosses sensor lines
    tilt = np.radians(2.0)
    n_local = np.array([-np.sin(tilt), -np.cos(tilt), 0.0])  # faces the box
    p_local = np.array([0.0, hy + 0.003, 0.0])
    normal = world_T_box[:3, :3] @ (-n_local)
    point = world_T_box[:3, :3] @ p_local + world_T_box[:3, 3]
    checker = _checker(cell, _plane(point, normal, half=0.3))
    q = np.zeros(3)
    exact_per = checker.exact_check(q, per_shape=True).per_shape[box.name]
    sensors = checker.sensor_check(q, parts=(base_part,))
    assert exact_per > 0.001
    assert sensors.in_collision
