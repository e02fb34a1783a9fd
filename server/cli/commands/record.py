"""``teleprog record summary FILE``: what a session recording holds (channels, duration, the
statements submitted and their final statuses); ``--json`` for scripts."""

from __future__ import annotations

import argparse
import sys

from server.cli import print_json


def _cmd_summary(args: argparse.Namespace) -> int:
    from server.recording.reader import read_recording
    from server.recording.summary import summarize, summary_lines

    recording = read_recording(args.file)
    if recording.problem:
        print(f"teleprog: warning: {recording.problem}", file=sys.stderr)
    summary = summarize(recording)
    if args.json:
        print_json(summary.model_dump(mode="json"))
    else:
        print("\n".join(summary_lines(summary)))
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("record", help="session recordings (MCAP): summary")
    what = p.add_subparsers(dest="record_command", required=True, parser_class=type(p))
    s = what.add_parser("summary", help="channels, duration and the statements with their final statuses")
    s.add_argument("file", help="a recording (.mcap)")
    s.add_argument("--json", action="store_true", help="print one JSON document")
    s.set_defaults(handler=_cmd_summary)
