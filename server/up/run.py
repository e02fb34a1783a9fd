"""Run the console under uvicorn and print the URL to open once it is listening.

``teleprog up`` starts the whole product: unless told otherwise (``--robot-url``: use a running
robot or link; ``--no-robot``: console only) it first starts the telerobot and the delayed link
as child processes (``server.up.stack``), connects the console to the link, watches them (a child
that exits is logged once, shown in ``/api/link`` and started again on its port, unless
``--no-restart``), and stops the children when the console stops (Ctrl-C, SIGTERM).
``--sedimentation`` serves the particle-sedimentation view (``server.sedimentation.app``)
instead, with no robot and no link.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading

import uvicorn

from server.app import create_app
from server.settings import ConsoleSettings
from server.viser_host import uvicorn_config_kwargs
from shared.errors import InputError

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


def _exit_quietly(signum: int, frame: object) -> None:
    raise SystemExit(0)


def settings_from_args(args: argparse.Namespace) -> ConsoleSettings:
    get = lambda name: getattr(args, name, None)  # noqa: E731 - flags absent from older callers
    return ConsoleSettings().with_overrides(
        port=get("port"), host=get("host"), cell=get("cell"), delay_ms=get("delay_ms"), robot_url=get("robot_url"),
        no_robot=True if get("no_robot") else None, robot_port=get("robot_port"), link_port=get("link_port"),
        sedimentation=True if get("sedimentation") else None, restart_children=False if get("no_restart") else None,
    )


def run_sedimentation(settings: ConsoleSettings) -> int:
    """``teleprog up --sedimentation``: the sedimentation view alone (no cell, no children)."""
    from server.sedimentation.app import create_sedimentation_app

    app = create_sedimentation_app(settings)  # bad starting values fail here, as one line
    signal.signal(signal.SIGTERM, _exit_quietly)
    print("teleprog up: particle-sedimentation view (no robot)", flush=True)
    config = uvicorn.Config(
        app, host=settings.host, port=settings.port, log_level="warning", workers=1, **uvicorn_config_kwargs()
    )
    server = _AnnouncingServer(config)
    server.run()
    return 0 if server.started else 1


def run_console(args: argparse.Namespace) -> int:
    settings = settings_from_args(args)
    if settings.sedimentation:
        return run_sedimentation(settings)
    # uvicorn shuts down gracefully on SIGINT/SIGTERM and then re-raises the signal with the
    # handler that was in place before it; make that handler an orderly exit, so the children
    # are stopped (the finally below) instead of the process dying on the spot.
    signal.signal(signal.SIGTERM, _exit_quietly)
    from shared.cells.loader import load_cell

    load_cell(settings.cell)  # a broken cell fails here, before any child starts
    children = []
    watcher: list = []  # the ChildWatch, once both children listen

    def children_status() -> dict[str, str]:
        return watcher[0].status() if watcher else {c.name: "starting" for c in children}

    try:
        watch = None
        if not settings.no_robot and not settings.robot_url:
            from server.up.stack import spawn_robot_and_link

            robot, link, link_url = spawn_robot_and_link(
                cell=settings.cell, robot_port=settings.robot_port, link_port=settings.link_port, delay_ms=settings.delay_ms
            )
            children = [robot, link]
            settings = settings.model_copy(update={"robot_url": link_url})
            watch = (robot, link)
        elif settings.robot_url:
            print(f"teleprog up: using the robot at {settings.robot_url}", flush=True)
        else:
            print("teleprog up: console only (no robot)", flush=True)
        app = create_app(settings, children=children_status if watch is not None else None)
        config = uvicorn.Config(
            app, host=settings.host, port=settings.port, log_level="warning", workers=1, **uvicorn_config_kwargs()
        )
        server = _AnnouncingServer(config)
        failed: list[str] = []
        if watch is not None:
            # the children start while the console does; a child that fails stops the console
            def wait_children() -> None:
                try:
                    for child in watch:
                        child.wait_ready(settings.child_start_timeout_s)
                except InputError as exc:
                    failed.append(str(exc))
                    print(f"teleprog up: {exc}", file=sys.stderr, flush=True)
                    server.should_exit = True
                    return
                robot, link = watch
                print(f"teleprog up: telerobot {robot.url}, link {link.url} ({settings.delay_ms:g} ms each way)", flush=True)
                from server.up.stack import ChildWatch

                watcher.append(ChildWatch(
                    list(watch), restart=settings.restart_children, start_timeout=settings.child_start_timeout_s
                ).start())

            threading.Thread(target=wait_children, name="children", daemon=True).start()
        server.run()
        return 0 if server.started and not failed else 1
    finally:
        from server.up.stack import stop_child

        if watcher:
            children = watcher[0].stop()  # no restart while the children are stopped on purpose
        for child in reversed(children):
            stop_child(child)


if __name__ == "__main__":
    sys.exit(run_console(argparse.Namespace()))
