"""``teleprog net``: place/transition nets from PNML or JSON files.

``teleprog net check FILE`` prints boundedness, safeness, liveness, terminal markings and the
number of reachable markings; ``teleprog net show FILE`` prints the net's places and
transitions, or with ``--svg OUT`` / ``--png OUT`` writes a picture of it (both options may be
given together).
"""

from __future__ import annotations

import argparse
import sys

from server.cli import print_json


def _cmd_check(args: argparse.Namespace) -> int:
    from shared.errors import InputError
    from shared.tasknet.analysis import check_net
    from shared.tasknet.jsonform import load_net

    if args.bound < 1:
        raise InputError(f"--bound must be at least 1; got {args.bound}")
    net = load_net(args.file)
    report = check_net(net, cap=args.bound)
    if args.json:
        print_json({"file": str(args.file), "net": net.id, **report.as_json()})
        return 0

    def yn(v: bool | None) -> str:
        return "unknown" if v is None else ("yes" if v else "no")

    count = f"{report.reachable_markings}" if report.reachability_complete else f"more than {report.states_cap} (the states cap, --bound)"
    print(f"net {net.id}: {report.places} places, {report.transitions} transitions, {report.arcs} arcs")
    print(f"reachable markings: {count}")
    bounds = ""
    if report.bounds is not None:
        bounds = " (" + ", ".join(f"{p} {'omega' if b is None else b}" for p, b in report.bounds.items()) + ")"
    print(f"bounded: {yn(report.bounded)}{bounds}")
    print(f"safe (1-bounded): {yn(report.safe)}")
    print(f"deadlock-free: {yn(report.deadlock_free)}")
    for m in report.dead_markings:
        print("  terminal marking: {" + ", ".join(f"{p}: {n}" for p, n in m.items()) + "}")
    live = ""
    if report.live_transitions is not None:
        dead_t = [t for t, v in report.live_transitions.items() if not v]
        live = f" (not live: {', '.join(dead_t)})" if dead_t else ""
    print(f"live (L4): {yn(report.live)}{live}")
    for note in report.notes:
        print(f"note: {note}")
    return 0


def _cmd_show(args: argparse.Namespace) -> int:
    from shared.errors import InputError
    from shared.tasknet.jsonform import load_net
    from shared.tasknet.layout import net_to_svg

    net = load_net(args.file)
    pictures = []
    if args.svg is not None:
        pictures.append((args.svg, net_to_svg(net).encode("utf-8")))
    if args.png is not None:
        if args.png == "-":
            raise InputError("--png: a PNG cannot go to the terminal; give a file name")
        from shared.tasknet.raster import net_to_png

        pictures.append((args.png, net_to_png(net)))
    if pictures:
        for target, data in pictures:
            if target == "-":
                sys.stdout.write(data.decode("utf-8"))
                continue
            try:
                with open(target, "wb") as fh:
                    fh.write(data)
            except OSError as exc:
                raise InputError(f"{target}: cannot write the picture: {exc.strerror or exc}") from None
            print(f"wrote {target}")
        return 0
    print(f"net {net.id}" + (f" ({net.name})" if net.name else ""))
    print("places:")
    for p in net.places:
        extra = [x for x in (p.predicate, f"{p.initial} token(s)" if p.initial else None,
                             f"capacity {p.capacity}" if p.capacity else None) if x]
        print(f"  {p.id}" + (f"  {'; '.join(extra)}" if extra else ""))
    print("transitions:")
    for t in net.transitions:
        j = net.transition_index[t.id]
        pre = ", ".join(f"{s}" + (f"*{net.pre[net.place_index[s], j]}" if net.pre[net.place_index[s], j] > 1 else "")
                        for s in net.preset(t.id))
        post = ", ".join(f"{s}" + (f"*{net.post[net.place_index[s], j]}" if net.post[net.place_index[s], j] > 1 else "")
                         for s in net.postset(t.id))
        print(f"  {t.id}" + (f" {t.action}" if t.action else "") + f": {{{pre}}} -> {{{post}}}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("net", help="place/transition nets (PNML or JSON): check properties, draw")
    nsub = p.add_subparsers(dest="net_command", required=True, parser_class=type(p))
    c = nsub.add_parser("check", help="boundedness, safeness, liveness, deadlocks, reachable markings")
    c.add_argument("file", help="net file: .pnml (ISO/IEC 15909-2 P/T net) or .json")
    c.add_argument("--json", action="store_true", help="print the report as one JSON document")
    c.add_argument("--bound", type=int, default=100_000, metavar="N",
                   help="the most markings to explore (default 100000); past it, properties come from coverability")
    c.set_defaults(handler=_cmd_check)
    s = nsub.add_parser("show", help="print a net's places and transitions, or draw it (SVG, PNG)")
    s.add_argument("file", help="net file: .pnml or .json")
    s.add_argument("--svg", metavar="OUT", help="write an SVG picture to OUT ('-' for stdout)")
    s.add_argument("--png", metavar="OUT", help="write a PNG picture to OUT")
    s.set_defaults(handler=_cmd_show)
    from server.cli.commands import net_plan, net_recognise, net_refine

    net_recognise.register(nsub)
    net_refine.register(nsub)
    net_plan.register_net(nsub)
