"""``teleprog bench <name> [options]``: run one of the project's benchmarks.

Every script ``benchmarks/bench_<name>.py`` is a benchmark called ``<name>``; it can also run
alone. A script that defines ``add_arguments(parser)`` and ``main_with(args) -> int`` gets its
options parsed here (``teleprog bench collision --json``); any other script's ``main()`` runs with
the remaining arguments as its command line. Scripts are found and loaded only when ``bench`` is
the command, so other subcommands start fast. They live beside the source checkout, not in the
installed package, and compare against libraries of the ``bench`` extra.
"""

from __future__ import annotations

import argparse
import ast
import importlib.util
import sys
from pathlib import Path

from shared.errors import InputError

BENCH_DIR = Path(__file__).resolve().parents[3] / "benchmarks"


def discover() -> dict[str, Path]:
    """Benchmark name -> script, from the files in ``benchmarks/``."""
    if not BENCH_DIR.is_dir():
        return {}
    return {p.stem.removeprefix("bench_"): p for p in sorted(BENCH_DIR.glob("bench_*.py"))}


def _summary(path: Path) -> str:
    try:
        doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    except (OSError, SyntaxError):
        return ""
    return doc.strip().splitlines()[0] if doc.strip() else ""


def _load(path: Path):
    name = f"teleprog_bench_{path.stem}"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while the script runs
    try:
        spec.loader.exec_module(module)
    except ImportError as exc:
        del sys.modules[name]
        raise InputError(f"benchmark {path.name} needs the 'bench' extra (pip install -e '.[bench]'): {exc}") from None
    except BaseException:
        del sys.modules[name]
        raise
    return module


def _cmd_bench(args: argparse.Namespace) -> int:
    scripts = discover()
    if args.name not in scripts:
        raise InputError(f"unknown benchmark {args.name!r}; known: {', '.join(scripts) or 'none (no benchmarks/ folder)'}")
    path = scripts[args.name]
    module = _load(path)
    try:
        if hasattr(module, "add_arguments") and hasattr(module, "main_with"):
            parser = type(args._parser)(prog=f"teleprog bench {args.name}", description=_summary(path))
            module.add_arguments(parser)
            return int(module.main_with(parser.parse_args(args.rest)) or 0)
        sys.argv = [str(path), *args.rest]
        return int(module.main() or 0)
    except ImportError as exc:
        raise InputError(f"benchmark {args.name} needs the 'bench' extra (pip install -e '.[bench]'): {exc}") from None


def register(sub: argparse._SubParsersAction) -> None:
    lines = [f"  {name:<12} {_summary(path)}" for name, path in discover().items()]
    p = sub.add_parser(
        "bench",
        help="run a benchmark against established libraries",
        description="Run a benchmark of benchmarks/ (figures are recorded in benchmarks/README.md).",
        epilog="benchmarks:\n" + "\n".join(lines),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("name", help="which benchmark (see below)")
    p.add_argument("rest", nargs=argparse.REMAINDER, help="the benchmark's own options (e.g. --json)")
    p.set_defaults(handler=_cmd_bench, _parser=p)
