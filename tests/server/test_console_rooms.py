"""The console stays in parts (issue 15): no class in server/ or webui/ over 400 lines, no module
over 600, and no kinematics or collision call left in the console's own rooms."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MAX_CLASS_LINES = 400
MAX_MODULE_LINES = 600


def _sources() -> list[Path]:
    return sorted(p for d in ("server", "webui") for p in (ROOT / d).rglob("*.py"))


def test_no_class_or_module_outgrows_its_room() -> None:
    too_big = []
    for path in _sources():
        text = path.read_text()
        lines = text.count("\n")
        if lines > MAX_MODULE_LINES:
            too_big.append(f"{path.relative_to(ROOT)}: {lines} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > MAX_CLASS_LINES:
                too_big.append(f"{path.relative_to(ROOT)}:{node.lineno} class {node.name}: {node.end_lineno - node.lineno + 1} lines")
    assert not too_big, too_big


def test_the_console_asks_shared_for_geometry() -> None:
    """The console's parts call no forward kinematics and no scene check themselves: those are
    ``shared``'s (plan checks, the cell's collision report, the expectation of the arm)."""
    calls = []
    for path in sorted((ROOT / "server" / "console").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in {"fk", "check_world", "exact_check"}:
                calls.append(f"{path.name}:{node.lineno} .{node.func.attr}()")
            if isinstance(node, ast.Attribute) and node.attr == "scene" and isinstance(node.value, ast.Attribute) and node.value.attr == "collision":
                calls.append(f"{path.name}:{node.lineno} reaches into the collision scene")
    assert not calls, calls
