"""``teleprog parse``: read a program (text or ``.json``) and print its JSON or text form."""

from __future__ import annotations

import argparse
import json
import sys

from server.cli import print_json


def _cmd_parse(args: argparse.Namespace) -> int:
    from shared.language.formatter import format_program
    from shared.language.parser import parse_file
    from shared.language.statements import program_to_json

    parsed = parse_file(args.file)
    if parsed.errors:
        for line in parsed.error_lines():
            print(line, file=sys.stderr)
        print(f"teleprog: error: {len(parsed.errors)} error(s) in {args.file}", file=sys.stderr)
        return 1
    if args.text:
        sys.stdout.write(format_program(parsed.statements))
    elif args.json:
        print_json(program_to_json(parsed.statements))
    else:
        print(json.dumps(program_to_json(parsed.statements), indent=2))
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("parse", help="parse a program and print its JSON form (or its text form)")
    p.add_argument("file", help="program file: text form (.tp) or JSON form (.json)")
    p.add_argument("--text", action="store_true", help="print the text form instead of JSON")
    p.add_argument("--json", action="store_true", help="print the JSON form on one line")
    p.set_defaults(handler=_cmd_parse)
