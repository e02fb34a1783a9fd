"""The rover terrain cell end to end: ``teleprog up --cell rover_terrain`` starts console,
link and telerobot; a placement planned at a ground position goes into the program, is
submitted over the delayed link, and the telerobot's arm ends at the planned configuration with
the instrument head within 30 mm of the ground (seed 004's in-situ detection)."""

from __future__ import annotations

import numpy as np
import pytest

import support
from shared.paths import ASSETS_DIR
from support import start_console, stop_process

ROVER_TERRAIN = ASSETS_DIR / "cells" / "rover_terrain.toml"


def call(up, method: str, path: str, body: dict | None = None) -> dict:
    reply = up.api(method, path, json=body) if body is not None else up.api(method, path)
    assert reply.status_code < 300, (path, reply.status_code, reply.text)
    return reply.json()


@pytest.fixture
def up(tmp_path):
    running = start_console(tmp_path, "--cell", str(ROVER_TERRAIN), "--delay-ms", "100")
    yield running
    stop_process(running.proc)


def test_placement_program_runs_on_the_telerobot(up) -> None:
    support.wait_for(lambda: call(up, "GET", "/api/link")["connected"], timeout=60, what="the link")
    call(up, "PUT", "/api/regime", {"regime": "quasi"})  # program, preview, confirm, send
    placed = call(up, "POST", "/api/terrain/placement", {"ground_mm": [700, 0]})
    assert placed["candidates"], placed["message"]
    program = call(up, "POST", "/api/terrain/placement/insert")
    n = program["empty_index"]
    assert n == len(placed["program"])
    preview = call(up, "POST", "/api/preview/begin", {"start": 0, "stop": n})
    assert not [w for w in preview["warnings"] if w["kind"] == "collision"], preview["warnings"]
    call(up, "POST", "/api/preview/seek", {"t": preview["duration"]})  # watched to the end: confirmed
    call(up, "POST", "/api/preview/end")
    call(up, "POST", "/api/submit", {"start": 0, "stop": n})
    sent = support.wait_for(lambda: (s := call(up, "GET", "/api/sent"))["pending"] == 0 and s, timeout=90,
                            what="the placement program final")
    assert [i["status"] for i in sent["items"]] == ["done"] * n, [(i["text"], i["status"], i["reason"]) for i in sent["items"]]
    best = np.array(placed["candidates"][0]["q"])
    remote = support.wait_for(lambda: (r := call(up, "GET", "/api/remote"))["state"] == "idle" and r, what="robot idle")
    np.testing.assert_allclose(remote["q"], best, atol=np.radians(0.01))
    # the console's own check of the reached pose: the head near the ground, nothing touching
    call(up, "POST", "/api/resync")
    terrain = call(up, "GET", "/api/terrain")
    assert 0.0 < terrain["head_distance"] <= 0.030 and not terrain["in_collision"]
