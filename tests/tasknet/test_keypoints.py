"""Key points of sampled tool paths (thesis §3.3.3) on paths whose corners, rests and bends are
known, and on the recorded PUMA jog of the test data (five phases: x, a rotation in place, y, z,
then joint 1 sweeping an arc)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from shared.errors import InputError
from shared.tasknet.keypoints import KeyPointSettings, arc_radii, chord_error, key_points

JOG = Path(__file__).parents[1] / "program" / "data" / "puma_jog_100hz.npz"


def polyline(corners, step=0.001) -> np.ndarray:
    """Points every ``step`` m along straight pieces through ``corners``."""
    out = [np.asarray(corners[0], dtype=float)]
    for a, b in zip(corners, corners[1:]):
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        n = max(1, round(np.linalg.norm(b - a) / step))
        out += [a + (b - a) * s for s in np.linspace(0, 1, n + 1)[1:]]
    return np.array(out)


def test_the_radius_from_chord_and_height_is_the_circle_s() -> None:
    theta = np.linspace(0, np.pi, 181)
    circle = np.c_[0.05 * np.cos(theta), 0.05 * np.sin(theta), np.zeros_like(theta)]
    radii = arc_radii(circle, 7)
    np.testing.assert_allclose(radii[7:-7], 0.05, rtol=1e-9)
    assert np.isinf(radii[:7]).all() and np.isinf(radii[-7:]).all()  # no whole neighbourhood there
    assert np.isinf(arc_radii(polyline([(0, 0, 0), (0.1, 0, 0)]), 5)[5:-5]).all()  # straight


def test_the_chord_error_sums_each_point_s_distance_to_the_segment() -> None:
    points = np.array([[0, 0, 0], [0.25, 0.01, 0], [0.5, -0.02, 0], [0.75, 0, 0.03], [1, 0, 0]])
    error, far = chord_error(points)
    assert error == pytest.approx(0.01 + 0.02 + 0.03) and far == 3


@pytest.mark.parametrize("corners", [
    [(0, 0, 0), (0.1, 0, 0), (0.1, 0.1, 0)],                                     # an L
    [(0, 0, 0), (0.1, 0, 0), (0.1, 0.1, 0), (0, 0.1, 0.05), (0, 0, 0.05)],        # a square, one side rising
    [(0.3, 0.1, 0.4), (0.35, 0.1, 0.25), (0.5, 0.2, 0.25)],                     # down, then across
])
def test_the_corners_of_a_polyline_are_its_key_points(corners) -> None:
    path = polyline(corners)
    found = key_points(path)
    assert [k.kind for k in found] == ["start"] + ["corner"] * (len(corners) - 2) + ["end"]
    np.testing.assert_allclose([k.position for k in found], corners, atol=1.5e-3)  # within a sample or so
    # noise of 0.05 mm on every sample does not add or lose a key point
    noisy = path + np.random.default_rng(3).normal(0, 5e-5, path.shape)
    assert [k.kind for k in key_points(noisy)] == [k.kind for k in found]


def test_a_gentle_arc_is_linearised_within_the_error_bound() -> None:
    theta = np.linspace(0, np.pi / 2, 400)
    arc = np.c_[0.1 * np.cos(theta), 0.1 * np.sin(theta), np.zeros_like(theta)]
    settings = KeyPointSettings()
    found = key_points(arc, settings=settings)
    assert all(k.kind in ("start", "split", "end") for k in found) and len(found) > 3  # no corner, pieces
    spacing = float(np.linalg.norm(np.diff(arc, axis=0), axis=1).mean())
    for a, b in zip(found, found[1:]):
        error, _ = chord_error(arc[a.index: b.index + 1])
        assert error * spacing / settings.error_spacing <= settings.error_bound
    looser = key_points(arc, settings=KeyPointSettings(error_bound=0.5))
    assert len(looser) < len(found)  # a looser bound, fewer pieces


def test_a_rest_on_a_straight_line_splits_it_where_the_tool_stops_and_moves_again() -> None:
    line = polyline([(0, 0, 0), (0.2, 0, 0)])
    t = np.arange(len(line)) * 0.01  # 0.1 m/s
    rest = 80
    path = np.r_[line[: rest + 1], np.repeat(line[rest: rest + 1], 50, axis=0), line[rest + 1:]]
    times = np.r_[t[: rest + 1], t[rest] + 0.01 * np.arange(1, 51), t[rest + 1:] + 0.5]
    found = key_points(path, times)
    assert [k.kind for k in found] == ["start", "stop", "move", "end"]
    assert found[1].index == rest and found[2].index == rest + 50
    assert found[2].t - found[1].t == pytest.approx(0.5)
    assert [k.kind for k in key_points(path)] == ["start", "end"]  # without times there is no rest


def test_the_recorded_puma_jog_has_its_key_points_at_its_phase_ends() -> None:
    data = np.load(JOG)
    path = data["world_T_tool"][:, :3, 3]
    found = key_points(path, data["t"])
    x_end, rotation_end, y_end, z_end, arc_end = data["phase_ends"]
    at = {k.index: k.kind for k in found}
    near = lambda i, kinds, tol=3: any(abs(j - i) <= tol and at[j] in kinds for j in at)  # noqa: E731
    assert near(x_end, {"stop"})            # the x jog ends, the tool rests while it turns in place
    assert near(y_end, {"corner", "stop"})  # y then z: a corner
    assert near(z_end, {"stop"})
    assert near(arc_end, {"stop"})
    splits = [j for j, kind in at.items() if kind == "split"]
    assert splits and all(z_end < j < arc_end for j in splits)  # only the joint-1 arc needs pieces
    assert found[0].kind == "start" and found[-1].kind == "end"


def test_bad_paths_are_refused_with_what_is_wrong() -> None:
    with pytest.raises(InputError, match="3 coordinates"):
        key_points(np.zeros((5, 2)))
    with pytest.raises(InputError, match="point 2 is not finite"):
        key_points([[0, 0, 0], [1, 0, 0], [np.nan, 0, 0]])
    with pytest.raises(InputError, match="never decrease"):
        key_points(np.zeros((3, 3)), [0.0, 1.0, 0.5])
    assert key_points(np.zeros((0, 3))) == []
