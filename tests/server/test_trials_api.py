"""``POST /api/trials`` and ``GET /api/trials/{id}`` on the console app (issue 19, point 6): a
batch on the console's cell in virtual time, in a spawned process, with its progress, its table,
its summary and its plots; the same report ``teleprog trial --clock virtual`` gives."""

from __future__ import annotations

import time

from fastapi.testclient import TestClient

from server.app import create_app
from server.settings import ConsoleSettings
from server.trials.batch import RunSpec, TrialWorld, run_spec, world_seed
from server.trials.programs import transfer_program
from shared.cells.loader import DEFAULT_CELL


def _wait_done(client: TestClient, batch_id: int, timeout: float = 180.0) -> dict:
    deadline = time.monotonic() + timeout
    while True:
        view = client.get(f"/api/trials/{batch_id}").json()
        if view["state"] != "running":
            return view
        assert time.monotonic() < deadline, f"batch {batch_id} still running: {view['runs_done']}/{view['runs_total']}"
        time.sleep(0.2)


def test_a_batch_runs_on_the_consoles_cell_and_reports_its_table_summary_and_plots() -> None:
    app = create_app(ConsoleSettings(no_robot=True), build_page=False)
    with TestClient(app) as client:
        started = client.post("/api/trials", json={"kind": "extract", "runs": 3, "seed": 4,
                                                   "world": {"friction": 0.45}})
        assert started.status_code == 200, started.text
        batch = started.json()
        assert batch["state"] == "running" and batch["runs_total"] == 3 and batch["request"]["clock"] == "virtual"
        again = client.post("/api/trials", json={"kind": "grasp"})
        assert again.status_code == 409 and "running" in again.json()["detail"]
        view = _wait_done(client, batch["id"])
        assert view["state"] == "done" and view["runs_done"] == 3 and view["error"] is None, view
        summary = view["summary"]
        assert summary["kind"] == "extract" and [r["world_seed"] for r in summary["runs"]] == [4000, 4001, 4002]
        assert any(line.startswith("| supervised | 3 |") for line in view["table"])
        # the same runs in this process give the same results
        world = TrialWorld(friction=0.45)
        program = transfer_program(DEFAULT_CELL)
        here = [run_spec(RunSpec("extract", "supervised", i, world.settings(world_seed(4, i)), 3000.0, "virtual", "/tmp",
                                 program=program)) for i in range(3)]
        assert [r["success"] for r in summary["runs"]] == [r.success for r in here]
        assert [r["total_s"] for r in summary["runs"]] == [r.total_s for r in here]
        assert set(view["plots"]) == {"times.png", "success.png"}
        png = client.get(f"/api/trials/{batch['id']}/plots/success.png")
        assert png.status_code == 200 and png.headers["content-type"] == "image/png" and png.content[:4] == b"\x89PNG"
        assert client.get(f"/api/trials/{batch['id']}/plots/nothing.png").status_code == 404
        assert client.get("/api/trials/999").status_code == 404


def test_a_bad_batch_is_refused_before_anything_runs() -> None:
    app = create_app(ConsoleSettings(no_robot=True), build_page=False)
    with TestClient(app) as client:
        mode = client.post("/api/trials", json={"kind": "transfer", "modes": ["sideways"]})
        assert mode.status_code == 422 and "sideways" in mode.json()["detail"]
        many = client.post("/api/trials", json={"kind": "grasp", "runs": 500})
        assert many.status_code == 422
        real = client.post("/api/trials", json={"kind": "grasp", "clock": "real"})
        assert real.status_code == 422  # real-time batches are the CLI's: a session per run
        empty = create_app(ConsoleSettings(cell=DEFAULT_CELL.parent / "puma562_empty.toml", no_robot=True), build_page=False)
    with TestClient(empty) as client:
        none = client.post("/api/trials", json={"kind": "insert"})
        assert none.status_code == 422 and "no movable box-shaped object" in none.json()["detail"]
