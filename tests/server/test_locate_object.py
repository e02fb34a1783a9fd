"""Correcting a virtual object's pose from a camera image (thesis §4.2.3) in the console session
and over HTTP: the peg-in-hole cell's front camera sees the peg's four feature points."""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from server.console import ArmChanged
from shared.errors import InputError, UnknownNameError
from shared.spatial import pose_to_transform


def seen(cell, world_T_peg: np.ndarray, noise_px: float = 0.0, seed: int = 0) -> np.ndarray:
    peg = cell.object("peg")
    world_p = peg.keypoints @ world_T_peg[:3, :3].T + world_T_peg[:3, 3]
    pixels = cell.cameras["front"].project(world_p)
    return pixels + np.random.default_rng(seed).normal(0.0, noise_px, pixels.shape)


def test_the_peg_seen_elsewhere_moves_the_virtual_peg_there(session) -> None:
    cell = session.cell
    model = cell.object("peg").world_T_object
    real = model @ pose_to_transform(np.array([0.004, -0.003, 0.0]), np.radians([0.0, 0.0, 4.0]))
    events = []
    session.subscribe_events(events.append)
    view = session.locator.locate_object("peg", "front", seen(cell, real).tolist())
    np.testing.assert_allclose(view.world_T_object, real, atol=1e-9)
    assert view.moved == pytest.approx(np.linalg.norm(real[:3, 3] - model[:3, 3]))
    np.testing.assert_allclose(session.arm.view().object_poses["peg"], real, atol=1e-9)
    assert any(isinstance(e, ArmChanged) and "peg" in e.arm.object_poses for e in events)


def test_pixel_noise_keeps_the_peg_within_a_millimetre_across_the_image(session) -> None:
    cell = session.cell
    real = cell.object("peg").world_T_object @ pose_to_transform(np.array([0.002, 0.001, 0.0]), np.zeros(3))
    view = session.locator.locate_object("peg", "front", seen(cell, real, noise_px=0.3, seed=5).tolist())
    err = np.array(view.world_T_object)[:3, 3] - real[:3, 3]
    camera = cell.cameras["front"]
    ray = real[:3, 3] - camera.world_T_camera[:3, 3]
    ray /= np.linalg.norm(ray)
    assert np.linalg.norm(err - np.dot(err, ray) * ray) < 0.001
    assert view.residual_px < 1.0


def test_refusals_say_what_is_wrong(session) -> None:
    cell = session.cell
    pixels = seen(cell, cell.object("peg").world_T_object)
    with pytest.raises(UnknownNameError, match="camera"):
        session.locator.locate_object("peg", "rear", pixels.tolist())
    with pytest.raises(UnknownNameError, match="object"):
        session.locator.locate_object("bolt", "front", pixels.tolist())
    with pytest.raises(InputError, match="4"):
        session.locator.locate_object("table", "front", pixels.tolist())  # the table has no feature points
    with pytest.raises(InputError, match="one pixel"):
        session.locator.locate_object("peg", "front", pixels[:3].tolist())
    with pytest.raises(InputError, match="do not fit|behind"):
        session.locator.locate_object("peg", "front", pixels[[2, 0, 3, 1]].tolist())  # wrong order
    np.testing.assert_allclose(session.arm.view().object_poses.get("peg", cell.object("peg").world_T_object),
                               cell.object("peg").world_T_object)  # nothing changed


def test_locate_over_http(cell_and_scene) -> None:
    from server.app import create_app
    from server.settings import ConsoleSettings

    cell, _ = cell_and_scene
    app = create_app(ConsoleSettings(no_robot=True), build_page=False)
    with TestClient(app) as client:
        cameras = client.get("/api/cameras").json()
        assert [c["name"] for c in cameras] == ["front"] and cameras[0]["width"] == 640
        keypoints = client.get("/api/objects/keypoints").json()
        assert [k["object"] for k in keypoints] == ["peg"] and len(keypoints[0]["keypoints"]) == 4
        real = cell.object("peg").world_T_object @ pose_to_transform(np.array([0.003, 0.0, 0.0]), np.zeros(3))
        reply = client.post("/api/objects/peg/locate", json={"camera": "front", "pixels": seen(cell, real).tolist()})
        assert reply.status_code == 200, reply.text
        np.testing.assert_allclose(client.get("/api/arm").json()["object_poses"]["peg"], real, atol=1e-9)
        bad = client.post("/api/objects/peg/locate", json={"camera": "rear", "pixels": seen(cell, real).tolist()})
        assert bad.status_code == 400 and "camera" in bad.json()["detail"]
