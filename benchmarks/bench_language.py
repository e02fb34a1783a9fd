"""Statement language benchmark: parse, format and check a 10,000-statement program.

The program cycles the peg-transfer motions of ``assets/programs/peg_transfer.tp`` over the
peg-in-hole cell (Cartesian moves in WORK and TOOL, joint moves, DRIVEs, SPEED, MODE, EVENT
statements; every Cartesian statement costs one or two closed-form IK calls in the checks).
The established library is the way the same program is read in its JSON form: ``json.loads``
plus pydantic validation of the statement models (``program_from_json``); the ratio is their
time over ours for parsing (above 1: our text parser is faster). Run:
``.venv/bin/python benchmarks/bench_language.py [--statements 10000] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

from shared.cells.loader import load_cell
from shared.language.checks import check_program
from shared.language.formatter import format_program
from shared.language.parser import parse_program
from shared.language.statements import program_from_json, program_to_json

ROOT = Path(__file__).resolve().parents[1]
CYCLE = """\
SPEED 50 %
MOVES TO (0, -80, 160) mm (180, 0, 0) deg IN WORK   # above the peg
DRAW TO (0, -80, 70) mm IN WORK WITH SPEED 10 mm/s UNTIL CONTACT
EVENT at_peg
DRAW TO (0, -80, 160) mm IN WORK WITH SPEED 30 mm/s
DRAW TO (0, 80, 160) mm IN WORK
ROTATE TO (180, 0, 15) deg IN WORK WITH SPEED 10 deg/s
DRAW TO (0, 0, 20) mm IN TOOL UNTIL FORCE > 5 N
MODE FORCE
MODE POSITION
MOVE (-15.18, -45.52, 196.42, 0, 29.1, 164.82) deg WITH SPEED 20 %
DRIVE J1 TO -20 deg
DRIVE J1 TO -15.18 deg UNTIL TIME 2.5 s
"""


def make_program(n: int) -> str:
    lines = [line for line in CYCLE.splitlines() if line.strip()]
    return "\n".join(lines[i % len(lines)] for i in range(n)) + "\n"


def timed(fn: Callable[[], object], repeat: int) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--statements", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=3, help="best of this many runs (parse/format/JSON)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    cell = load_cell(ROOT / "assets" / "cells" / "peg_in_hole.toml")
    text = make_program(args.statements)
    t_parse, parsed = timed(lambda: parse_program(text), args.repeat)
    assert parsed.ok and len(parsed.statements) == args.statements, parsed.error_lines()[:3]
    t_format, formatted = timed(lambda: format_program(parsed.statements), args.repeat)
    json_text = json.dumps(program_to_json(parsed.statements))
    t_json, from_json = timed(lambda: program_from_json(json.loads(json_text)), args.repeat)
    assert program_to_json(from_json) == program_to_json(parsed.statements)
    assert program_to_json(parse_program(formatted).statements) == program_to_json(parsed.statements)
    t_check, result = timed(lambda: check_program(parsed.statements, cell.robot, cell, lines=parsed.lines), 1)
    assert result.ok, [p.format("bench") for p in result.problems[:3]]

    n = args.statements
    figures = {
        "statements": n,
        "parse_s": t_parse,
        "format_s": t_format,
        "json_pydantic_s": t_json,
        "check_s": t_check,
        "parse_per_s": n / t_parse,
        "format_per_s": n / t_format,
        "json_pydantic_per_s": n / t_json,
        "check_per_s": n / t_check,
        "parse_check_per_s": n / (t_parse + t_check),
        "ratio_parse_vs_json_pydantic": t_json / t_parse,
    }
    if args.json:
        print(json.dumps(figures))
        return
    print(f"{n} statements ({len(text) / 1e3:.0f} kB of text, {len(json_text) / 1e3:.0f} kB of JSON)")
    print(f"{'measure':<40}{'time':>10}{'statements/s':>16}")
    for label, t in (
        ("parse text (ours)", t_parse),
        ("json.loads + pydantic (established)", t_json),
        ("format text (ours)", t_format),
        ("check vs robot and cell (ours)", t_check),
        ("parse + check", t_parse + t_check),
    ):
        print(f"{label:<40}{t * 1e3:>8.1f} ms{n / t:>16,.0f}")
    print(f"ratio parse vs json+pydantic: {t_json / t_parse:.2f}x (their time / ours)")


if __name__ == "__main__":
    main()
