"""The console's parts import one way (issue 35): no import circle among the modules of
server/console (counting imports made only for type checking and imports inside functions), the
data path arm -> program -> preview -> dispatch -> remote never imported backwards, and each
typed view a part holds of a part downstream (``server.console.ports``) matched by that part."""

from __future__ import annotations

import ast
import typing
from pathlib import Path

from server.console import ports

CONSOLE = Path(__file__).resolve().parents[2] / "server" / "console"
FLOW = ("arm", "program_desk", "previewer", "dispatch", "remote")


def _imports(path: Path, modules: set[str]) -> set[str]:
    """The console modules ``path`` imports, anywhere in the file."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            parts = node.module.split(".")
            if parts[:2] == ["server", "console"]:
                if len(parts) > 2:
                    found.add(parts[2])
                else:
                    found.update(a.name for a in node.names)
        elif isinstance(node, ast.Import):
            for a in node.names:
                parts = a.name.split(".")
                if parts[:2] == ["server", "console"] and len(parts) > 2:
                    found.add(parts[2])
    return (found & modules) - {path.stem}


def _graph() -> dict[str, set[str]]:
    modules = {p.stem for p in CONSOLE.glob("*.py")}
    return {p.stem: _imports(p, modules) for p in CONSOLE.glob("*.py")}


def _circle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph`` (its modules in order, the first repeated last), or None."""
    state: dict[str, int] = {}  # 1: on the path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)) is not None:
                return found
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state and (found := visit(start)) is not None:
            return found
    return None


def test_the_circle_finder_finds_a_circle() -> None:
    assert _circle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert _circle({"a": {"b"}, "b": set()}) is None


def test_no_console_module_imports_itself_back() -> None:
    graph = _graph()
    assert set(FLOW) <= set(graph)
    assert _circle(graph) is None, " -> ".join(_circle(graph) or [])


def test_the_data_path_is_never_imported_backwards() -> None:
    graph = _graph()
    backwards = [f"{a} imports {b}" for i, a in enumerate(FLOW) for b in FLOW[i + 1:] if b in graph[a]]
    assert not backwards, backwards


def _members(protocol: type) -> set[str]:
    """What a view names: its attributes, methods and properties."""
    names = set(vars(protocol).get("__annotations__", {}))
    names |= {n for n, v in vars(protocol).items() if not n.startswith("_") and (callable(v) or isinstance(v, property))}
    return names


def test_each_part_offers_what_its_view_names(session) -> None:
    """The session's parts have every member of the views the parts upstream hold of them."""
    offers = {
        ports.StrokeTaker: session.program, ports.PreviewRun: session.preview, ports.Submitter: session.dispatch,
        ports.GroundContacts: session.terrain, ports.RemoteSink: session.remote, ports.LinkRead: session.link,
        ports.PendingRecoveries: session.recovery,
    }
    declared = {obj for obj in vars(ports).values() if isinstance(obj, type) and getattr(obj, "_is_protocol", False)}
    assert declared - {typing.Protocol} == set(offers)
    missing = [f"{type(part).__name__} lacks {name} ({view.__name__})"
               for view, part in offers.items() for name in sorted(_members(view)) if not hasattr(part, name)]
    assert not missing, missing
    # and the session hands each upstream part the downstream one it views
    assert session.arm._desk is session.program and session.arm._preview is session.preview
    assert session.program.preview is session.preview and session.program.dispatch is session.dispatch
    assert session.dispatch.remote is session.remote and session.dispatch.link is session.link
    assert session.remote.link is session.link and session.link.recovery is session.recovery
