"""``teleprog up``: the console (web page, API and 3D scene)."""

from __future__ import annotations

import argparse


def _cmd_up(args: argparse.Namespace) -> int:
    from server.run import run_console

    return run_console(args)


def register(sub: argparse._SubParsersAction) -> None:
    up = sub.add_parser("up", help="start the console (web page, API and 3D scene)")
    up.add_argument("--port", type=int, default=None, help="HTTP port (default 8080)")
    up.add_argument("--host", default=None, help="address to bind (default 127.0.0.1)")
    up.add_argument("--cell", default=None, help="cell file (default assets/cells/peg_in_hole.toml)")
    up.set_defaults(handler=_cmd_up)
