"""`teleprog up` as a real process: health, another cell, the jog API, bad input."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
from support import PROJECT_DIR, start_console, stop_process


def test_up_opens_another_cell(tmp_path) -> None:
    running = start_console(tmp_path, "--cell", str(PROJECT_DIR / "assets/cells/puma562_empty.toml"))
    try:
        assert running.api("GET", "/api/health").json()["cell"] == "puma562_empty"
        assert "teleprog console: open http://127.0.0.1:" in running.log_path.read_text()
        assert running.api("GET", "/docs").status_code == 200
    finally:
        stop_process(running.proc)


def test_jog_api_moves_and_refuses_with_reasons(console) -> None:
    state = console.api("GET", "/api/state").json()
    moved = console.api("POST", "/api/jog/joint", json={"joint": 2, "delta_deg": 5.0}).json()
    assert moved["q_deg"][1] == state["q_deg"][1] + 5.0
    tool = console.api(
        "POST", "/api/jog/tool", json={"frame": "world", "constraint": "z", "motion": "translate", "displacement": [5.0, 5.0, 10.0]}
    ).json()
    np.testing.assert_allclose(np.array(tool["tool_xyz_mm"]) - moved["tool_xyz_mm"], [0.0, 0.0, 10.0], atol=1e-6)
    limited = console.api("POST", "/api/jog/joint", json={"joint": 5, "delta_deg": 900.0}).json()
    assert limited["blocked"] == "joint_limit"
    bad = console.api("PUT", "/api/robot/joints", json={"deg": [0, 0, 0]})
    assert bad.status_code == 400
    assert "6 joints" in bad.json()["detail"]
    out = console.api("PUT", "/api/robot/joints", json={"deg": [0, 90, 0, 0, 0, 0]})
    assert out.status_code == 422 and "joint 2" in out.json()["detail"]


def test_broken_cell_is_one_clear_line(tmp_path) -> None:
    broken = tmp_path / "broken.toml"
    broken.write_text('name = "x"\n[robot]\nref = "nobot"\n')
    out = subprocess.run(
        [sys.executable, "-m", "server.cli", "up", "--port", "0", "--cell", str(broken)],
        capture_output=True, text=True, timeout=60, cwd=PROJECT_DIR,
    )
    assert out.returncode == 1
    assert f"{broken}: robot.ref: unknown robot 'nobot'" in out.stderr
    assert "Traceback" not in out.stderr
