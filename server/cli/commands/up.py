"""``teleprog up``: the whole product: telerobot, delayed link and console (web page, API, 3D scene).

``teleprog up --sedimentation`` serves the particle-sedimentation view instead (no robot, no link).
"""

from __future__ import annotations

import argparse


def _cmd_up(args: argparse.Namespace) -> int:
    # the telerobot and the link start, and the robot connection with them, before the
    # console's heavy imports (about 2 s): the hello crosses the delay meanwhile
    from server.up.early import start_early

    early = start_early(args)
    from server.up.run import run_console

    return run_console(args, early)


def register(sub: argparse._SubParsersAction) -> None:
    up = sub.add_parser(
        "up", help="start the telerobot, the delayed link and the console; print the URL to open"
    )
    up.add_argument("--port", type=int, default=None, help="HTTP port of the console (default 8080; 0: any free)")
    up.add_argument("--host", default=None, help="address to bind (default 127.0.0.1)")
    up.add_argument("--cell", default=None, help="cell file (default assets/cells/peg_in_hole.toml)")
    up.add_argument("--delay-ms", type=float, default=None, help="link delay each way in ms (default 3000)")
    up.add_argument("--robot-port", type=int, default=None, help="port of the started telerobot (default: any free)")
    up.add_argument("--link-port", type=int, default=None, help="port of the started link (default: any free)")
    up.add_argument(
        "--no-restart", action="store_true", help="leave a telerobot or link child that exits stopped (default: start it again)"
    )
    up.add_argument("--strict-editing", action="store_true", default=None,
                    help="keep the thesis's editing rules (§4.3.6): refuse edits that break them (default: free editing)")
    up.add_argument("--handover-timeout-s", type=float, default=None, metavar="S",
                    help="a request for control the holder does not answer passes control after S s (default 30)")
    rec = up.add_mutually_exclusive_group()
    up.add_argument("--fault-injection", action="store_true",
                    help="serve /api/faults: the console misbehaves on request (tests, surprise campaigns)")
    rec.add_argument("--record", metavar="DIR", default=None, help="folder for the session's MCAP recording (default recordings/)")
    rec.add_argument("--no-record", action="store_true", help="record nothing")
    group = up.add_mutually_exclusive_group()
    group.add_argument("--no-robot", action="store_true", help="console only: start no robot and no link")
    group.add_argument("--robot-url", default=None, help="use a running robot or link at this ws:// URL")
    up.add_argument(
        "--robot-credential-file", default=None,
        help="file (readable by its owner alone) with the credential of the robot at --robot-url "
        "(default $TELEPROG_ROBOT_CREDENTIAL; the robot teleprog up starts gets a new one)",
    )
    group.add_argument(
        "--sedimentation", action="store_true",
        help="serve the particle-sedimentation view (many-body collision detection, thesis ch. 5); no robot, no link",
    )
    up.set_defaults(handler=_cmd_up)
