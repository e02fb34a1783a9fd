"""``teleprog link``: the delayed line between console and robot, as its own process."""

from __future__ import annotations

import argparse


def _ms(value: float | None) -> float | None:
    return None if value is None else value / 1000.0


def _cmd_link(args: argparse.Namespace) -> int:
    import asyncio

    from server.cli import print_json
    from server.relay.link_relay import CHANNEL_PATHS, LinkSettings, serve_link

    settings = LinkSettings.load(
        host=args.host, port=args.port, robot=args.robot, delay_s=_ms(args.delay_ms), jitter_s=_ms(args.jitter_ms),
        bandwidth_bytes_per_s=args.bandwidth_bytes_per_s, drop_probability=args.drop_probability,
        outage_s=_ms(args.outage_ms), seed=args.seed,
    )

    def ready(port: int) -> None:
        if args.json:
            print_json({"listening": f"ws://{settings.host}:{port}", "paths": list(CHANNEL_PATHS),
                        "robot": settings.robot, "delay_s": settings.delay_s, "jitter_s": settings.jitter_s,
                        "bandwidth_bytes_per_s": settings.bandwidth_bytes_per_s,
                        "drop_probability": settings.drop_probability})
        else:
            rate = f"{settings.bandwidth_bytes_per_s:.0f} bytes/s" if settings.bandwidth_bytes_per_s else "unlimited"
            print(f"teleprog link: ws://{settings.host}:{port} ({', '.join(CHANNEL_PATHS)}) -> {settings.robot}; "
                  f"delay {settings.delay_s * 1e3:.1f} ms each way, jitter {settings.jitter_s * 1e3:.1f} ms, "
                  f"bandwidth {rate}, loss {settings.drop_probability:g}", flush=True)

    asyncio.run(serve_link(settings, on_ready=ready))
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("link", help="relay console <-> robot with delay, jitter, bandwidth limit and faults")
    p.add_argument("--port", type=int, default=None, help="port consoles connect to (default 8765; 0: any free)")
    p.add_argument("--host", default=None, help="address to bind (default 127.0.0.1)")
    p.add_argument("--robot", default=None, help="robot base URL (default ws://127.0.0.1:8766)")
    p.add_argument("--delay-ms", type=float, default=None, help="delay each way in ms (default 3000)")
    p.add_argument("--jitter-ms", type=float, default=None, help="extra delay drawn in [0, jitter] ms (default 0)")
    p.add_argument("--bandwidth-bytes-per-s", type=float, default=None, help="line rate each way (default 0: unlimited)")
    p.add_argument("--drop-probability", type=float, default=None, help="chance a message is lost, cutting the connection")
    p.add_argument("--outage-ms", type=float, default=None, help="after a fault, ms until reconnecting works (default 1000)")
    p.add_argument("--seed", type=int, default=None, help="seed of jitter and loss draws (default 0)")
    p.add_argument("--json", action="store_true", help="print the listening address as JSON")
    p.set_defaults(handler=_cmd_link)
