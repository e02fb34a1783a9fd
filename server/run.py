"""Run the console under uvicorn and print the URL to open once it is listening."""

from __future__ import annotations

import argparse
import logging
import sys

import uvicorn

from server.app import create_app
from server.settings import ConsoleSettings
from server.viser_host import uvicorn_config_kwargs

log = logging.getLogger(__name__)


class _AnnouncingServer(uvicorn.Server):
    """A uvicorn server that prints the console's URL once its socket is bound."""

    async def startup(self, sockets=None) -> None:  # type: ignore[override]
        await super().startup(sockets)
        for server in self.servers:
            for sock in server.sockets:
                host, port = sock.getsockname()[:2]
                print(f"teleprog console: open http://{host}:{port}/", flush=True)
                return


def run_console(args: argparse.Namespace) -> int:
    settings = ConsoleSettings().with_overrides(port=args.port, host=args.host, cell=args.cell)
    app = create_app(settings)
    config = uvicorn.Config(
        app, host=settings.host, port=settings.port, log_level="warning", workers=1, **uvicorn_config_kwargs()
    )
    server = _AnnouncingServer(config)
    server.run()
    return 0 if server.started else 1


if __name__ == "__main__":
    sys.exit(run_console(argparse.Namespace(port=None, host=None, cell=None)))
