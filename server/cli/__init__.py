"""The one command line: ``teleprog <subcommand>`` (``python -m server.cli`` runs it too).

One module per subcommand in ``server.cli.commands``.

Errors the project raises on purpose print one line on stderr and exit 1; usage errors exit 2
(argparse). ``--json`` prints machine-readable output on stdout.
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import re
import pkgutil
import sys
from collections.abc import Callable, Sequence

from pydantic import ValidationError

from server.cli import commands
from shared.errors import TeleprogError

log = logging.getLogger("teleprog")

Handler = Callable[[argparse.Namespace], int]
"""What every subcommand sets as ``handler``: parsed arguments in, exit code out."""


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line usage error."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def print_json(obj: object) -> None:
    """Print one JSON document on stdout (the ``--json`` form of every subcommand)."""
    print(json.dumps(obj))


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="teleprog", description="Teleprogramming console for a robot arm across seconds of delay")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        importlib.import_module(f"{commands.__name__}.{info.name}").register(sub)
    return parser


class _HideCredentials(logging.Filter):
    """No log line shows a credential: websockets logs a handshake's headers at debug level (``-v``),
    the robot's ``Authorization: Bearer ...`` among them (``shared.wire.credential``)."""

    _BEARER = re.compile(r"(?i)(bearer\s+)\S+")

    def filter(self, record: logging.LogRecord) -> bool:
        message = record.getMessage()
        if "earer" in message:
            record.msg, record.args = self._BEARER.sub(r"\1[hidden]", message), ()
        return True


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s"
    )
    for handler in logging.getLogger().handlers:
        handler.addFilter(_HideCredentials())
    try:
        return int(args.handler(args))
    except TeleprogError as exc:
        print(f"teleprog: error: {exc}", file=sys.stderr)
        return 1
    except ValidationError as exc:
        # a settings object refused a value from a flag or a TELEPROG_* variable
        err = exc.errors()[0]
        where = ".".join(str(p) for p in err.get("loc", ())) or "(value)"
        print(f"teleprog: error: {exc.title} {where}: {err.get('msg', 'invalid')}; got {err.get('input')!r}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # the reader of our output went away (e.g. `| head`): nothing left to say to it
        sys.stderr.close()
        return 0
