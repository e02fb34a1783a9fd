"""Recognition kept per statement (issue 35): the task panel's play of a program that changed at
its end, against playing it whole (``recognise_program``, the code before), on the peg cell.

For a program of N small joint moves: the whole play, then the kept play's first run (the same
work plus a snapshot per statement), then one statement added at the end, played by both. The
kept play's result is checked equal to the whole play's. Also the editor's own rule checks at
the same sizes (``shared.program.editor``: an insertion at the end and in the middle, a deletion,
a selection), per operation.

    .venv/bin/python benchmarks/bench_prefix_recognition.py            # table
    .venv/bin/python benchmarks/bench_prefix_recognition.py --json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))


def plays(n: int) -> dict:
    from bench_program_scale import program_text
    from shared.cells.loader import load_cell
    from shared.language.parser import parse_program, parse_statement
    from shared.tasknet.playback import PrefixRecognition, recognise_program
    from shared.tasknet.taskspace import load_task_space

    cell = load_cell(ROOT / "assets" / "cells" / "peg_in_hole.toml")
    space = load_task_space(ROOT / "assets" / "tasks" / "peg_in_hole.toml")
    program = list(parse_program(program_text(cell, n)).statements)
    t = time.perf_counter()
    recognise_program(program, cell, space, cell.q_home.copy())
    whole = time.perf_counter() - t
    kept = PrefixRecognition(cell, space, cell.q_home.copy())
    t = time.perf_counter()
    kept.recognise(program)
    first = time.perf_counter() - t
    grown = [*program, parse_statement("DRIVE J1 TO 10 deg")]
    t = time.perf_counter()
    again = kept.recognise(grown)
    added_kept = time.perf_counter() - t
    t = time.perf_counter()
    fresh = recognise_program(grown, cell, space, cell.q_home.copy())
    added_whole = time.perf_counter() - t
    assert again.actions == fresh.actions and again.samples == fresh.samples and kept.replayed == 1
    return {"statements": n, "whole_s": whole, "kept_first_s": first, "added_kept_s": added_kept,
            "added_whole_s": added_whole, "ratio": added_whole / added_kept}


def edits(n: int, rounds: int = 20) -> dict:
    from shared.language.parser import parse_statement
    from shared.program.editor import Editor, ProgramState

    statements = [parse_statement(f"DRAW TO ({600 + i % 50}, 0, 400) mm") for i in range(n)]
    editor = Editor(ProgramState.of(statements))
    new = parse_statement("DRAW TO (650, 10, 400) mm")
    t = time.process_time()
    for _ in range(rounds):
        editor.insert(new)
        editor.select(n // 2)
        editor.insert(new)
        editor.delete()
        editor.select_empty()
    return {"statements": n, "ms_per_edit": 1e3 * (time.process_time() - t) / (5 * rounds)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[100, 1000])
    p.add_argument("--edit-sizes", type=int, nargs="+", default=[10, 1000, 10000])
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    load = os.getloadavg()[0]
    rows = [plays(n) for n in a.sizes]
    edit_rows = [edits(n) for n in a.edit_sizes]
    if a.json:
        print(json.dumps({"load": load, "plays": rows, "edits": edit_rows}, indent=2))
        return
    print(f"machine load {load:.1f}\n")
    print("| statements | whole play | kept play, first | one added: kept | one added: whole | ratio |")
    print("|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['statements']:,} | {r['whole_s']:.3f} s | {r['kept_first_s']:.3f} s | {1e3 * r['added_kept_s']:.1f} ms "
              f"| {r['added_whole_s']:.3f} s | {r['ratio']:.0f}x |")
    print("\n| statements | editor CPU per edit |\n|---:|---:|")
    for r in edit_rows:
        print(f"| {r['statements']:,} | {r['ms_per_edit']:.3f} ms |")


if __name__ == "__main__":
    main()
