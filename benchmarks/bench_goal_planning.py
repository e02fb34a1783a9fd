"""Goal planning (issue 40): how long the console takes to plan a goal of the cell's task space,
with the search's states visited, against SNAKES building the same net's reachability graph.

For each shipped cell with a task space (``assets/tasks/<cell>.toml``) and a few goals from the
cell's own marking: ``shared.tasknet.goals.plan_goal``
(grounded net, reachability graph, breadth-first search through markings that keep each object
at one feature, the action run), then the statements of its actions from their templates, then
the whole command in a console session (``session.task_commands.goal``: the search, the
templates from where the program ends, the insertion with the editor's checks). The comparison:
SNAKES's ``StateGraph`` of the same grounded net (the reachability graph alone, no search). The
figure is wall time, best of ``--repeat``. Goal: under 0.5 s a goal.

    .venv/bin/python benchmarks/bench_goal_planning.py          # table
    .venv/bin/python benchmarks/bench_goal_planning.py --json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "tasknet"))  # the SNAKES oracle the tests use

GOALS = {  # per shipped task space: goals from the cell as loaded (the last also in a console session)
    "peg_in_hole": (["HOLDING(PEG)"], ["PEGINHOLE(PEG,HOLE2)"], ["PEGINHOLE(PEG,HOLE2)", "HANDEEMPTY"]),
    "two_pegs": (["HOLDING(PEGB)"], ["PEGINHOLE(PEGB,HOLE1)", "HANDEEMPTY"], ["PEGINHOLE(PEGA,HOLE3)", "HANDEEMPTY"]),
}


def _best(fn, repeat: int):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def shipped() -> list[tuple[Path, Path]]:
    """(cell, task space) of every shipped cell with a task space."""
    out = []
    for task in sorted((ROOT / "assets" / "tasks").glob("*.toml")):
        cell = ROOT / "assets" / "cells" / task.name
        if cell.exists():
            out.append((cell, task))
    return out


def bench(repeat: int) -> list[dict]:
    from snakes_oracle import snakes_graph

    from server.console import Session
    from shared.cells.loader import load_cell
    from shared.tasknet.action_program import action_statements, cell_marking
    from shared.tasknet.goals import plan_goal
    from shared.tasknet.taskspace import load_task_space

    rows = []
    for cell_path, task_path in shipped():
        cell, space = load_cell(cell_path), load_task_space(task_path)
        start = cell_marking(space, cell)
        goals = GOALS[space.spec.name]
        for name, marking in (("as loaded", start),):
            snakes_s, graph = _best(lambda m=marking: snakes_graph(space.net(frozenset(m))), repeat)
            for goal in goals:
                plan_s, plan = _best(lambda m=marking, g=goal: plan_goal(space, m, g), repeat)
                statements_s, _ = _best(lambda p=plan: action_statements(space, cell, p.actions), repeat)
                rows.append({"cell": cell.name, "from": name, "goal": goal, "actions": plan.action_texts,
                             "states_visited": plan.states_visited, "snakes_states": len(graph),
                             "plan_s": plan_s, "statements_s": statements_s, "snakes_s": snakes_s,
                             "ratio_snakes_over_plan": snakes_s / plan_s})
        session = Session(cell)
        try:
            def command() -> int:
                session.program.load("", "empty.tp")
                return len(session.task_commands.goal(list(goals[-1])).rows)

            command()  # warm: the first play compiles nothing new, but fills the caches a console has
            session_s, _ = _best(command, repeat)
        finally:
            session.close()
        rows.append({"cell": cell.name, "from": "a console session (empty program)", "goal": list(goals[-1]),
                     "session_command_s": session_s})
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    load = os.getloadavg()[0]
    rows = bench(a.repeat)
    if a.json:
        print(json.dumps({"load": load, "rows": rows}, indent=2))
        return
    print(f"machine load {load:.1f}, best of {a.repeat}\n")
    print("| cell | from | goal | actions | states visited | plan_goal | + statements | SNAKES graph | SNAKES / ours |")
    print("|---|---|---|---|---:|---:|---:|---:|---:|")
    for r in rows:
        if "plan_s" not in r:
            continue
        print(f"| {r['cell']} | {r['from']} | {', '.join(r['goal'])} | {len(r['actions'])} | {r['states_visited']} "
              f"({r['snakes_states']}) | {1e3 * r['plan_s']:.2f} ms | {1e3 * r['statements_s']:.2f} ms | "
              f"{1e3 * r['snakes_s']:.2f} ms | {r['ratio_snakes_over_plan']:.1f}x |")
    for r in rows:
        if "session_command_s" in r:
            print(f"\n{r['cell']}: the whole command in a console session (search, templates, insertion), "
                  f"goal {', '.join(r['goal'])}: {1e3 * r['session_command_s']:.1f} ms (goal 500 ms)")


if __name__ == "__main__":
    main()
