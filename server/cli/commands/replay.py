"""``teleprog replay FILE``: a recorded session in the browser, read-only, with a timeline
(play, pause, step from event to event, scrub) and each submitted range's plan drawn against
what the robot reported."""

from __future__ import annotations

import argparse
from pathlib import Path


def _cmd_replay(args: argparse.Namespace) -> int:
    import signal

    import uvicorn

    from server.replay.app import create_replay_app
    from server.settings import ConsoleSettings
    from server.up.run import AnnouncingServer, bind_first, exit_quietly
    from server.viser_host import uvicorn_config_kwargs

    settings = ConsoleSettings().with_overrides(port=args.port, host=args.host)
    folder = Path(args.dir) if args.dir else None
    app = create_replay_app(args.file, settings, folder=folder)  # a bad file fails here, as one line
    signal.signal(signal.SIGTERM, exit_quietly)
    print(f"teleprog replay: {args.file}", flush=True)
    config = uvicorn.Config(app, host=settings.host, port=settings.port, log_level="warning", workers=1,
                            **uvicorn_config_kwargs())
    server = AnnouncingServer(config)
    server.label = "teleprog replay"
    server.run(sockets=[bind_first(config)])
    return 0 if server.started else 1


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="open a session recording (.mcap) read-only in the browser, with a timeline")
    p.add_argument("file", help="a recording (.mcap), e.g. one GET /api/sessions lists")
    p.add_argument("--port", type=int, default=None, help="HTTP port (default 8080; 0: any free)")
    p.add_argument("--host", default=None, help="address to bind (default 127.0.0.1)")
    p.add_argument("--dir", default=None, help="folder of recordings the page may open (default: the file's own)")
    p.set_defaults(handler=_cmd_replay)
