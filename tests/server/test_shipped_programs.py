"""Every shipped program (``assets/programs/*``) gets the same verdict from the console's editor
(``POST /api/program/load`` and the page's upload, ``POST /api/program/upload``) as from
``teleprog check``: both apply one rule for what may follow a task call
(``shared.language.task_rule``). Each program names its robot and cell in its ``# check:`` line;
``teleprog check`` runs as the command a user types, the console as its real HTTP app."""

from __future__ import annotations

import re
import subprocess
import sys
from collections.abc import Callable, Iterator
from contextlib import ExitStack
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.settings import ConsoleSettings

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = sorted((ROOT / "assets" / "programs").glob("*.tp")) + sorted((ROOT / "assets" / "programs").glob("*.json"))
CHECK_LINE = re.compile(r"^#\s*check:\s*teleprog check \S+ --robot (?P<robot>\S+) --cell (?P<cell>\S+)\s*$", re.MULTILINE)


def _robot_and_cell(path: Path) -> tuple[str, str]:
    m = CHECK_LINE.search(path.read_text(encoding="utf-8"))
    assert m, f"{path.name} has no '# check: teleprog check ... --robot R --cell C' line"
    return m["robot"], m["cell"]


def _check(path: Path, robot: str, cell: str) -> tuple[bool, str]:
    done = subprocess.run(
        [sys.executable, "-m", "server.cli", "check", str(path), "--robot", robot, "--cell", cell],
        cwd=ROOT, capture_output=True, text=True, timeout=120, check=False,
    )
    assert done.returncode in (0, 1), done.stderr
    return done.returncode == 0, done.stdout + done.stderr


@pytest.fixture(scope="module")
def consoles() -> Iterator[Callable[[str], TestClient]]:
    """The console's HTTP app for a cell, started once per cell for the module (no robot)."""
    with ExitStack() as stack:
        opened: dict[str, TestClient] = {}

        def console(cell: str) -> TestClient:
            if cell not in opened:
                app = create_app(ConsoleSettings(cell=ROOT / cell, no_robot=True), build_page=False)
                opened[cell] = stack.enter_context(TestClient(app))
            return opened[cell]

        yield console


def _editor(client: TestClient, path: Path, text: str) -> list[tuple[bool, str]]:
    """The verdict of the console's two ways in: the load endpoint and the page's upload."""
    client.post("/api/program/load", json={"text": "", "filename": "empty.tp"})
    loaded = client.post("/api/program/load", json={"text": text, "filename": path.name})
    if loaded.status_code == 200:
        kinds = [e["kind"] for e in client.get("/api/program").json()["entries"]]
        assert kinds[-1] == "EMPTY" and len(kinds) > 1
    client.post("/api/program/load", json={"text": "", "filename": "empty.tp"})
    uploaded = client.post(f"/api/program/upload?filename={path.name}", content=text.encode("utf-8"))
    answers = [loaded, uploaded]
    assert all(r.status_code in (200, 400) for r in answers), [r.text for r in answers]
    return [(r.status_code == 200, r.text) for r in answers]


def test_there_are_shipped_programs() -> None:
    assert {p.name for p in PROGRAMS} >= {"peg_transfer.tp", "rover_placement.tp"}


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.name)
def test_a_shipped_program_loads_in_the_editor_and_passes_check(path: Path, consoles) -> None:
    robot, cell = _robot_and_cell(path)
    ok, said = _check(path, robot, cell)
    assert ok, said
    for accepted, answer in _editor(consoles(cell), path, path.read_text(encoding="utf-8")):
        assert accepted, answer


def test_the_editor_and_check_refuse_a_motion_after_an_unknown_end_alike(tmp_path: Path, consoles) -> None:
    source = (ROOT / "assets" / "programs" / "peg_transfer.tp").read_text(encoding="utf-8")
    broken = tmp_path / "after_insert.tp"
    broken.write_text(source.replace("TASK release()", "DRAW TO (0, 80, 160) mm IN WORK"), encoding="utf-8")
    robot, cell = _robot_and_cell(ROOT / "assets" / "programs" / "peg_transfer.tp")
    ok, said = _check(broken, robot, cell)
    assert not ok and "DRAW cannot follow TASK insert_peg" in said, said
    for accepted, answer in _editor(consoles(cell), broken, broken.read_text(encoding="utf-8")):
        assert not accepted and "DRAW cannot follow TASK insert_peg" in answer, answer
