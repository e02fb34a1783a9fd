"""``teleprog net plan --cell CELL --goal GOAL``: plan a goal of the cell's task space (issue 40).

The marking is recognised in the cell as loaded (the arm at home); the goal's atoms
(``"PEGINHOLE(PEG,HOLE2)"``, several separated by ``;``) are searched for on the task space's
net (:func:`shared.tasknet.goals.plan_goal`) and the actions found are turned into statements
from their motion templates (:mod:`shared.tasknet.action_program`). Prints the actions and the
program text; ``--json`` gives ``{"actions", "program", "states_visited", ...}``. The task space
comes from ``--task FILE`` or ``assets/tasks/<cell name>.toml``.
"""

from __future__ import annotations

import argparse

from server.cli import print_json


def _cmd_plan(args: argparse.Namespace) -> int:
    from shared.cells.loader import load_cell
    from shared.tasknet.action_program import action_statements, cell_marking, program_text
    from shared.tasknet.goals import plan_goal
    from server.cli.commands.net_recognise import cell_task_space

    cell = load_cell(args.cell)
    space = cell_task_space(cell, args.task)
    goal = "; ".join(args.goal)  # atoms separated by ';' or by commas outside parentheses (parse_goal)
    plan = plan_goal(space, cell_marking(space, cell), goal, keep=not args.exact)
    rows = action_statements(space, cell, plan.actions)
    program = program_text(rows)
    if args.json:
        print_json({
            "actions": plan.action_texts,
            "program": program,
            "states_visited": plan.states_visited,
            "goal": list(plan.goal),
            "kept": list(plan.kept),
            "initial_marking": list(plan.start),
            "final_marking": list(plan.final),
            "statements": [{"action": r.action, "statements": list(r.statements)} for r in rows],
        })
        return 0
    print(f"task {space.spec.name} on cell {cell.name}: goal {{{', '.join(plan.goal)}}}"
          + (f", keeping {{{', '.join(plan.kept)}}}" if plan.kept else "")
          + f" ({plan.states_visited} states visited)")
    print("initial marking: {" + ", ".join(plan.start) + "}")
    if not plan.actions:
        print("the goal holds already: nothing to do")
        return 0
    for k, a in enumerate(plan.action_texts, 1):
        print(f"  {k}. {a}")
    print("final marking:   {" + ", ".join(plan.final) + "}")
    print("program:")
    print(program, end="")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """The top-level hook every module of ``server.cli.commands`` has: nothing, since ``plan``
    is a top-level command of its own (``teleprog plan PROGRAM``); ``net`` adds this one."""


def register_net(nsub: argparse._SubParsersAction) -> None:
    """Add ``plan`` to ``teleprog net``."""
    p = nsub.add_parser("plan", help="plan a goal of the cell's task space: the actions and their statements")
    p.add_argument("--cell", required=True, help="cell file (.toml)")
    p.add_argument("--goal", required=True, action="append",
                   help="goal atoms, e.g. 'PEGINHOLE(PEG,HOLE2)' (several separated by ';' or --goal repeated)")
    p.add_argument("--task", help="task space file (.toml); default assets/tasks/<cell>.toml")
    p.add_argument("--exact", action="store_true",
                   help="reach the goal only, without keeping the other atoms of the starting marking")
    p.add_argument("--json", action="store_true", help="print actions, program and states visited as one JSON document")
    p.set_defaults(handler=_cmd_plan)
