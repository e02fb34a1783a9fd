"""``teleprog bench <name>``: run one of the project's benchmarks (``benchmarks/bench_<name>.py``).

Each benchmark is a script in ``benchmarks/`` that can also run alone. To be reachable from here
it defines ``add_arguments(parser)`` and ``main_with(args) -> int`` (importing what it compares
against only when run) and is listed in ``BENCHMARKS`` below (name -> file, one-line help); it
then becomes ``teleprog bench <name>``.
The scripts live beside the source checkout, not in the installed package: they compare against
libraries of the ``bench`` extra.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

from shared.errors import InputError

BENCH_DIR = Path(__file__).resolve().parents[2] / "benchmarks"

BENCHMARKS: dict[str, tuple[str, str]] = {
    "collision": ("bench_collision.py", "scene collision checks and distances against coal and python-fcl"),
}


def _load(file: str):
    path = BENCH_DIR / file
    if not path.is_file():
        raise InputError(f"benchmark script {path} is missing (benchmarks run from a source checkout)")
    name = f"teleprog_bench_{path.stem}"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while the script runs
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def _add_arguments_of(file: str, parser: argparse.ArgumentParser) -> None:
    """The script declares its own options (loading it only defines functions: it imports its
    comparison libraries when run). If it cannot be loaded the error comes when run."""
    try:
        _load(file).add_arguments(parser)
    except InputError:
        parser.add_argument("--json", action="store_true")


def _handler(file: str):
    def run(args: argparse.Namespace) -> int:
        try:
            import coal  # noqa: F401
            import fcl  # noqa: F401
        except ImportError as exc:
            raise InputError(f"benchmark needs the 'bench' extra (pip install -e '.[bench]'): {exc}") from None
        return int(_load(file).main_with(args))

    return run


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="run a benchmark against established libraries")
    bench_sub = p.add_subparsers(dest="bench_name", required=True, parser_class=type(p))
    for name, (file, help_) in BENCHMARKS.items():
        b = bench_sub.add_parser(name, help=help_)
        _add_arguments_of(file, b)
        b.set_defaults(handler=_handler(file))
