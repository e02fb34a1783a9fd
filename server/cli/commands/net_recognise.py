"""``teleprog net recognise PROGRAM --cell CELL``: play a program on the virtual cell with the
console's interpreter, planner and collision core, recognise the task's actions from the feature
faces' contacts (thesis §3.5.3-3.5.4), and print them with the generated task net (§3.5.5).

The task space comes from ``--task FILE`` or, by default, ``assets/tasks/<cell name>.toml``.
``--save OUT`` writes the generated net (``.pnml`` or ``.json``).
"""

from __future__ import annotations

import argparse

from server.cli import print_json


def cell_task_space(cell, task: str | None):
    """The task space ``--task`` names, else the cell's own (``assets/tasks/<cell>.toml``); a
    one-line ``InputError`` when the cell has none."""
    from shared.errors import InputError
    from shared.tasknet.taskspace import load_task_space, task_file_for_cell

    task_file = task or task_file_for_cell(cell.name)
    if task_file is None:
        raise InputError(f"cell {cell.name!r} has no task file (assets/tasks/{cell.name}.toml); name one with --task")
    return load_task_space(task_file)


def _cmd_recognise(args: argparse.Namespace) -> int:
    from shared.cells.loader import load_cell
    from shared.errors import InputError
    from shared.language.parser import parse_file
    from shared.tasknet.jsonform import save_net
    from shared.tasknet.playback import recognise_program

    cell = load_cell(args.cell)
    space = cell_task_space(cell, args.task)
    parsed = parse_file(args.program)
    if not parsed.ok:
        raise InputError(f"{args.program}: " + "; ".join(parsed.error_lines()))
    result = recognise_program(parsed.statements, cell, space)
    if args.save:
        save_net(result.net.net, args.save)
    if args.json:
        print_json({
            "program": str(args.program),
            "cell": cell.name,
            "task": space.spec.name,
            "actions": [a.action for a in result.actions],
            "recognised": [{"action": a.action, "statement": a.statement, "t_s": None if a.t is None else round(a.t, 3)}
                           for a in result.actions],
            "initial_marking": list(result.m0),
            "final_marking": list(result.final_marking),
            "net": result.net.model.model_dump(),
            "samples": result.samples,
            "refusal": result.refusal,
        })
        return 0
    print(f"task {space.spec.name} on cell {cell.name}: {len(result.actions)} action(s) recognised over {result.samples} samples")
    for a in result.actions:
        print(f"  {a.index + 1}. {a.action}  (statement {a.statement}, t = {a.t:.2f} s)")
    if result.refusal:
        print(f"the program stopped being played at a refusal: {result.refusal}")
    print("initial marking: {" + ", ".join(result.m0) + "}")
    print("final marking:   {" + ", ".join(result.final_marking) + "}")
    print("generated task net:")
    for p in result.net.model.places:
        mark = " *" if p.id in result.net.model.initial_marking else ""
        print(f"  {p.id}  {p.predicate}{mark}")
    for t in result.net.model.transitions:
        print(f"  {t.id}  {t.action}: {{{', '.join(t.pre)}}} -> {{{', '.join(t.post)}}}")
    if args.save:
        print(f"wrote {args.save}")
    return 0


def register(nsub: argparse._SubParsersAction) -> None:
    r = nsub.add_parser("recognise", help="recognise a program's task actions on the virtual cell and generate its net")
    r.add_argument("program", help="program file (.tp or .json)")
    r.add_argument("--cell", required=True, help="cell file (.toml)")
    r.add_argument("--task", help="task space file (.toml); default assets/tasks/<cell>.toml")
    r.add_argument("--save", metavar="OUT", help="write the generated net to OUT (.pnml or .json)")
    r.add_argument("--json", action="store_true", help="print actions and net as one JSON document")
    r.set_defaults(handler=_cmd_recognise)
