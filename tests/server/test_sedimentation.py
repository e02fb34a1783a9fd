"""The sedimentation view's simulation runner and its API (``teleprog up --sedimentation``)."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest
from fastapi.testclient import TestClient

from server.sedimentation.runner import (
    BRUTE_MAX_BODIES,
    SedimentationRunner,
    SedimentationSettings,
    SedimentationSnapshot,
)
from server.sedimentation.app import create_sedimentation_app
from server.settings import ConsoleSettings
from shared.errors import InputError, UnknownNameError


def brute_pairs(centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Every overlapping or touching pair, i < j, sorted: the plain O(N^2) answer."""
    d = centres[:, None, :] - centres[None, :, :]
    d2 = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]
    s = radii[:, None] + radii[None, :]
    i, j = np.nonzero(np.triu(d2 <= s * s, k=1))
    return np.stack([i, j], axis=1).astype(np.int64)


def check_snapshot(snap: SedimentationSnapshot) -> int:
    expected = brute_pairs(snap.centres, snap.radii)
    np.testing.assert_array_equal(snap.pairs, expected)
    colliding = np.zeros(snap.centres.shape[0], dtype=bool)
    colliding[expected.ravel()] = True
    np.testing.assert_array_equal(snap.colliding, colliding)
    return expected.shape[0]


# a dense clustered scene: many pairs per frame, so agreement is not vacuous
DENSE = dict(n=300, kind="gaussian", density=0.005, speed=0.8)


@pytest.mark.parametrize("method", ["usscd", "usscd_skin", "icollide"])
def test_runner_frames_match_brute_force(method: str) -> None:
    runner = SedimentationRunner(SedimentationSettings(method=method, **DENSE))
    total = check_snapshot(runner.latest())
    frames = [runner.step_once() for _ in range(25)]
    assert [f.frame for f in frames] == list(range(1, 26))
    total += sum(check_snapshot(f) for f in frames)
    assert total > 100
    # change the scene under the same runner: still exact
    runner.update(kind="sediment", n=400, speed=2.0)
    for _ in range(10):
        check_snapshot(runner.step_once())


def test_running_thread_publishes_exact_frames_and_measures_fps() -> None:
    runner = SedimentationRunner(SedimentationSettings(method="usscd", **DENSE), steps_hz=200.0, draw_hz=5.0)
    pictures: list[SedimentationSnapshot] = []
    got = threading.Event()

    def collect(snap: SedimentationSnapshot) -> None:
        pictures.append(snap)
        if len(pictures) >= 4:
            got.set()

    runner.subscribe(collect)
    t0 = time.monotonic()
    runner.start()
    try:
        assert got.wait(timeout=20.0), "the runner published no pictures"
    finally:
        runner.stop()
    elapsed = time.monotonic() - t0
    state = runner.state()
    assert state.frame > 0 and state.fps > 0 and state.steps_per_s > 0
    assert math.isfinite(state.fps)
    assert state.pairs == runner.latest().n_pairs or state.frame != runner.latest().frame
    for snap in pictures:
        check_snapshot(snap)
    assert [p.frame for p in pictures] == sorted(p.frame for p in pictures)
    # the drawing rate is capped independently of the simulation: never more than draw_hz
    assert len(pictures) <= 5.0 * elapsed + 2


def test_pause_stops_the_frames_and_resume_continues() -> None:
    runner = SedimentationRunner(SedimentationSettings(n=200), steps_hz=200.0)
    runner.start()
    try:
        deadline = time.monotonic() + 20
        while runner.state().frame < 3 and time.monotonic() < deadline:
            time.sleep(0.02)
        paused = runner.update(paused=True)
        assert paused.paused
        frame = runner.state().frame
        time.sleep(0.3)
        assert runner.state().frame == frame
        assert runner.toggle_pause().paused is False
        while runner.state().frame == frame and time.monotonic() < deadline:
            time.sleep(0.02)
        assert runner.state().frame > frame
    finally:
        runner.stop()


def test_speed_keeps_the_scene_and_n_rebuilds_it() -> None:
    runner = SedimentationRunner(SedimentationSettings(n=500, speed=0.5))
    for _ in range(5):
        runner.step_once()
    before = runner.latest().centres
    state = runner.update(speed=3.0)
    assert state.speed == 3.0 and state.frame == 5  # same scene, moving faster from here on
    after = runner.step_once()
    step = np.linalg.norm(after.centres - before, axis=1)
    assert np.median(step) == pytest.approx(3.0, rel=1e-6)  # most bodies meet no wall
    state = runner.update(n=800)
    assert state.n == 800 and state.frame == 0 and runner.latest().centres.shape == (800, 3)
    assert state.size == pytest.approx((800 / 0.0005) ** (1 / 3))
    state = runner.update(method="scd")
    assert state.method == "scd" and state.n == 800
    check_snapshot(runner.step_once())


@pytest.mark.parametrize(
    ("change", "error", "words"),
    [
        ({"n": 1}, InputError, "N (number of bodies) must be in [2, 1000]"),
        ({"n": 1001}, InputError, "must be in [2, 1000], got 1001"),
        ({"n": 2.5}, InputError, "whole number"),
        ({"speed": -0.1}, InputError, "SPEED must be in [0, 16]"),
        ({"speed": float("nan")}, InputError, "SPEED must be finite"),
        ({"density": 0.0}, InputError, "density must be in"),
        ({"method": "octree"}, UnknownNameError, "unknown broadphase method 'octree'"),
        ({"kind": "lattice"}, UnknownNameError, "unknown scene kind 'lattice'"),
        ({"colour": "red"}, InputError, "unknown sedimentation setting(s): colour"),
    ],
)
def test_bad_settings_are_refused_and_change_nothing(change, error, words) -> None:
    runner = SedimentationRunner(SedimentationSettings(n=100), max_n=1000)
    before = runner.settings
    with pytest.raises(error) as caught:
        runner.update(**change)
    assert words in str(caught.value)
    assert runner.settings == before


def test_brute_force_is_limited_to_small_scenes() -> None:
    runner = SedimentationRunner(SedimentationSettings(n=BRUTE_MAX_BODIES + 1))
    with pytest.raises(InputError, match="brute force is O"):
        runner.update(method="brute")
    assert runner.update(method="brute", n=200).method == "brute"
    with pytest.raises(InputError, match="brute force"):
        SedimentationRunner(SedimentationSettings(method="brute", n=BRUTE_MAX_BODIES + 1))


def test_api_reads_and_changes_the_simulation() -> None:
    settings = ConsoleSettings(sedimentation=True, sedimentation_n=300, sedimentation_max_n=5000)
    with TestClient(create_sedimentation_app(settings, build_page=False)) as client:
        assert client.get("/api/health").json() == {"status": "ok", "mode": "sedimentation"}
        state = client.get("/api/sedimentation").json()
        assert state["method"] == "usscd" and state["n"] == 300 and state["kind"] == "uniform"
        assert {"fps", "pairs", "frame", "speed"} <= set(state)
        changed = client.put("/api/sedimentation", json={"n": 1200, "speed": 2.5, "method": "icollide"})
        assert changed.status_code == 200
        assert (changed.json()["n"], changed.json()["speed"], changed.json()["method"]) == (1200, 2.5, "icollide")
        assert client.get("/api/sedimentation").json()["n"] == 1200
        bad = client.put("/api/sedimentation", json={"n": 6000})
        assert bad.status_code == 400
        assert bad.json() == {"error": "InputError", "detail": "N (number of bodies) must be in [2, 5000], got 6000"}
        unknown = client.put("/api/sedimentation", json={"method": "octree"})
        assert unknown.status_code == 400 and unknown.json()["error"] == "UnknownNameError"
        assert client.put("/api/sedimentation", json={"bodies": 5}).status_code == 422
        assert client.get("/api/sedimentation").json()["n"] == 1200
        assert "/api/sedimentation" in client.get("/openapi.json").json()["paths"]
        assert client.get("/docs").status_code == 200


def test_up_sedimentation_refuses_bad_starting_values_in_one_line(monkeypatch, capsys) -> None:
    from server.cli import main

    monkeypatch.setenv("TELEPROG_SEDIMENTATION_METHOD", "octree")
    assert main(["up", "--sedimentation", "--port", "0"]) == 1
    err = capsys.readouterr().err
    assert "teleprog: error: unknown broadphase method 'octree'" in err
    assert "Traceback" not in err
    with pytest.raises(SystemExit) as usage:
        main(["up", "--sedimentation", "--no-robot"])
    assert usage.value.code == 2 and "not allowed with argument" in capsys.readouterr().err
