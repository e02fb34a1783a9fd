"""``teleprog robot``: the simulated telerobot as its own process (``robot_sim``)."""

from __future__ import annotations

import argparse
import math


def _cmd_robot(args: argparse.Namespace) -> int:
    import asyncio

    from robot_sim.service import RobotService, RobotSettings
    from server.cli import print_json

    settings = RobotSettings()
    overrides: dict[str, object] = {
        k: v
        for k, v in (
            ("host", args.host), ("port", args.port), ("cell", args.cell),
            ("heartbeat_s", args.heartbeat_s), ("silence_limit_s", args.silence_limit_s),
            ("listen_first", True if args.listen_first else None), ("cache_dir", args.cache_dir),
            ("credential_file", args.credential_file),
        )
        if v is not None
    }
    executor = {k: v for k, v in (("max_queue", args.max_queue),) if v is not None}
    world = {
        k: v
        for k, v in (
            ("seed", args.seed),
            ("object_offset", None if args.object_offset_mm is None else args.object_offset_mm / 1000.0),
            ("force_noise", args.force_noise_n),
            ("engine", args.world),
            ("grasp_tilt", None if args.grasp_tilt_deg is None else math.radians(args.grasp_tilt_deg)),
            ("friction", args.friction),
            ("clearance", None if args.clearance_mm is None else args.clearance_mm / 1000.0),
        )
        if v is not None
    }
    settings = settings.model_copy(update={
        **overrides,
        "world": settings.world.model_copy(update=world),
        "executor": settings.executor.model_copy(update=executor),
    })
    settings = RobotSettings.model_validate(settings.model_dump())  # validate the overrides too
    if not settings.listen_first:
        from shared.cells.loader import load_cell

        load_cell(settings.cell)  # a broken cell is a one-line error before anything listens

    service = RobotService(settings)  # a bad credential or credential file is a one-line error here

    def ready(port: int) -> None:
        url = f"ws://{settings.host}:{port}"
        door = service.credential
        made = str(door.file) if door is not None and door.source == "made" else None
        if args.json:
            print_json({"listening": url, "paths": ["/command", "/telemetry"], "cell": settings.cell,
                        "world": settings.world.model_dump(), "credential": door.source if door else None,
                        "credential_file": made})
        else:
            if made:
                print(f"teleprog robot: no credential given; made one in {made} "
                      f"(give the console --robot-credential-file {made})", flush=True)
            w = settings.world
            print(f"teleprog robot: {url} (/command, /telemetry) on {settings.cell}; seed {w.seed}, "
                  f"object offsets up to {w.object_offset * 1e3:g} mm, force noise {w.force_noise:g} N, "
                  f"{w.engine} world" + (f", grasp tilt {math.degrees(w.grasp_tilt):g} deg" if w.grasp_tilt else "")
                  + (f", friction {w.friction:g}" if w.friction is not None else "")
                  + (f", clearance {w.clearance * 1e3:g} mm" if w.clearance is not None else ""), flush=True)

    try:
        asyncio.run(service.run(on_ready=ready))
    except OSError as exc:
        from shared.errors import InputError

        raise InputError(f"cannot listen on {settings.host}:{settings.port}: {exc.strerror or exc}") from None
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("robot", help="run the simulated telerobot (command and telemetry channels)")
    p.add_argument("--port", type=int, default=None, help="port to listen on (default 8766; 0: any free)")
    p.add_argument("--host", default=None, help="address to bind (default 127.0.0.1)")
    p.add_argument("--cell", default=None, help="cell file (default assets/cells/peg_in_hole.toml)")
    p.add_argument("--seed", type=int, default=None, help="seed of the world's offsets and noise (default 0)")
    p.add_argument("--object-offset-mm", type=float, default=None, help="largest xy offset of pegs and holes from the model")
    p.add_argument("--force-noise-n", type=float, default=None, help="std of force-sensor noise in N")
    p.add_argument("--world", choices=("physics", "kinematic"), default=None,
                   help="the world: MuJoCo contact physics (default) or the kinematic stand-in")
    p.add_argument("--grasp-tilt-deg", type=float, default=None, help="tilt the peg settles at in the fingers once out of its hole")
    p.add_argument("--friction", type=float, default=None, help="sliding friction of the cell's contacts (default: the cell's)")
    p.add_argument("--clearance-mm", type=float, default=None, help="fit of the peg in its hole (default: the cell's geometry)")
    p.add_argument("--heartbeat-s", type=float, default=None, help="interval of the robot's heartbeats in s (default 0.2)")
    p.add_argument("--silence-limit-s", type=float, default=None,
                   help="silence from the console beyond the heartbeat at which the robot stops, in s (default 1)")
    p.add_argument("--max-queue", type=int, default=None, help="statements the robot's buffer holds (default 5000)")
    p.add_argument(
        "--credential-file", default=None,
        help="file (readable by its owner alone) with the credential consoles must present; default "
        "$TELEPROG_ROBOT_CREDENTIAL, else a new one written to ~/.local/state/teleprog/robot-<port>.credential",
    )
    p.add_argument("--json", action="store_true", help="print the listening address as JSON")
    p.add_argument(
        "--cache-dir", default=None,
        help="folder of the collision-model cache (default ~/.cache/teleprog; 'none': build every time)",
    )
    p.add_argument(
        "--listen-first", action="store_true",
        help="listen at once, then load the cell and build the core (/health: core_ready); teleprog up starts it so",
    )
    p.set_defaults(handler=_cmd_robot)
