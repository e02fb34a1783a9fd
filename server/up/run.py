"""Run the console under uvicorn and print the URL to open once it is listening.

``teleprog up`` starts the whole product: unless told otherwise (``--robot-url``: use a running
robot or link; ``--no-robot``: console only) it first starts the telerobot and the delayed link
as child processes (``server.up.stack``), says once that it waits for them and serves the console
only when both listen, so the console's first connection to the link reaches the robot and there
are no retries to log. It watches them (a child that exits is logged once, shown in ``/api/link``
and started again on its port, unless ``--no-restart``), and stops the children when the console
stops (Ctrl-C, SIGTERM). Stdout carries one URL, the console's (``teleprog console: open ...``).
``--sedimentation`` serves the particle-sedimentation view (``server.sedimentation.app``)
instead, with no robot and no link.
"""

from __future__ import annotations

import argparse
import logging
import signal
import socket
import sys

import uvicorn

from shared.errors import InputError

from server.app import create_app
from server.settings import ConsoleSettings
from server.viser_host import uvicorn_config_kwargs
from server.up.early import EarlyStart, start_early
from shared.startup_trace import mark

CONSOLE_SWITCH_INTERVAL_S = 0.001
"""How often the console's interpreter hands its lock to another thread that waits (``run_console``)."""

log = logging.getLogger(__name__)


class AnnouncingServer(uvicorn.Server):
    """A uvicorn server that prints the console's URL once its socket is bound."""

    label = "teleprog console"

    async def startup(self, sockets=None) -> None:  # type: ignore[override]
        await super().startup(sockets)
        for server in self.servers:
            for sock in server.sockets:
                host, port = sock.getsockname()[:2]
                print(f"{self.label}: open http://{host}:{port}/", flush=True)
                return


def bind_first(config: uvicorn.Config) -> socket.socket:
    """The console's socket, bound now: before the app's start-up opens viser's private port on
    an OS-assigned one, which could otherwise be the very port the console was told to use (a
    port found free and not yet bound). A port already taken is a one-line error."""
    host = config.host or "127.0.0.1"
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, config.port))
    except OSError as exc:
        sock.close()
        raise InputError(f"cannot listen on {host}:{config.port}: {exc.strerror or exc}") from None
    return sock


def exit_quietly(signum: int, frame: object) -> None:
    raise SystemExit(0)


def run_sedimentation(settings: ConsoleSettings) -> int:
    """``teleprog up --sedimentation``: the sedimentation view alone (no cell, no children)."""
    from server.sedimentation.app import create_sedimentation_app

    app = create_sedimentation_app(settings)  # bad starting values fail here, as one line
    signal.signal(signal.SIGTERM, exit_quietly)
    print("teleprog up: particle-sedimentation view (no robot)", flush=True)
    config = uvicorn.Config(
        app, host=settings.host, port=settings.port, log_level="warning", workers=1, **uvicorn_config_kwargs()
    )
    server = AnnouncingServer(config)
    server.run(sockets=[bind_first(config)])
    return 0 if server.started else 1


def run_console(args: argparse.Namespace, early: EarlyStart | None = None) -> int:
    """Serve the console; ``early``: what ``start_early`` already began before this module's
    imports (children spawned, robot client connecting); started here when not given."""
    mark("console", "console imports done")
    if early is None:
        early = start_early(args)
    settings = early.settings
    if settings.sedimentation:
        return run_sedimentation(settings)
    # uvicorn shuts down gracefully on SIGINT/SIGTERM and then re-raises the signal with the
    # handler that was in place before it; make that handler an orderly exit, so the children
    # are stopped (the finally below) instead of the process dying on the spot.
    signal.signal(signal.SIGTERM, exit_quietly)
    # The interpreter hands its lock between threads every 5 ms by default: a long computation of
    # the session's (a plan of thousands of statements) then delays each step of a STOP's way
    # (the HTTP request, the robot client's loop, the acknowledgement) by up to 5 ms. The
    # console's threads are mostly waiting; 1 ms costs little and shortens that chain.
    sys.setswitchinterval(CONSOLE_SWITCH_INTERVAL_S)
    from shared.collision import model_cache

    model_cache.configure(settings.cache_dir)  # the console's collision model, built once per robot and cell
    children: list = list(early.children)
    watcher: list = []  # the ChildWatch, once both children listen

    try:
        if early.robot is not None and children:
            from server.up.stack import ChildWatch

            robot, link = early.robot.wait_children()
            print(f"teleprog up: telerobot {robot.url}, link {link.url} ({settings.delay_ms:g} ms each way)", flush=True)
            watcher.append(ChildWatch(
                children, restart=settings.restart_children, start_timeout=settings.child_start_timeout_s
            ).start())
        elif settings.robot_url:
            print(f"teleprog up: using the robot at {settings.robot_url}", flush=True)
        else:
            print("teleprog up: console only (no robot)", flush=True)
        app = create_app(settings, children=watcher[0].status if watcher else None, robot=early.robot)
        config = uvicorn.Config(
            app, host=settings.host, port=settings.port, log_level="warning", workers=1, **uvicorn_config_kwargs()
        )
        server = AnnouncingServer(config)
        server.run(sockets=[bind_first(config)])
        return 0 if server.started else 1
    finally:
        from server.up.stack import stop_child

        if early.robot is not None:
            early.robot.close()
        if watcher:
            children = watcher[0].stop()  # no restart while the children are stopped on purpose
        for child in reversed(children):
            stop_child(child)


if __name__ == "__main__":
    sys.exit(run_console(argparse.Namespace()))
