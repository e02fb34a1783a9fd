"""``teleprog net refine SPEC.toml``: hierarchical task models by transition refinement (§3.4).

The spec names an upper net and, per step, a transition and the subnet that refines it (for
example ``assets/tasks/hole_search.toml``, the hole search of §3.4.3). Each step is checked
against the three conditions of Definition 3.15, the refined net is built as Theorem 3.1 states,
and the theorem's claims are checked on the nets themselves: the map back to the upper net is a
quotient, and boundedness, safeness and liveness carry over. ``--save OUT`` writes the refined net
(``.pnml`` or ``.json``). The exit status is 1 when a condition fails or a property is lost.
"""

from __future__ import annotations

import argparse
import sys

from server.cli import print_json


def _cmd_refine(args: argparse.Namespace) -> int:
    from shared.errors import InputError
    from shared.tasknet.analysis import check_net
    from shared.tasknet.jsonform import load_net, save_net
    from shared.tasknet.refinement import build_refinement, check_preservation, check_refinement, load_spec

    if args.bound < 1:
        raise InputError(f"--bound must be at least 1; got {args.bound}")
    spec = load_spec(args.spec)
    upper = load_net(spec.upper)
    net, steps, failure = upper, [], None
    for transition, subnet_path in spec.steps:
        subnet = load_net(subnet_path)
        check = check_refinement(net, transition, subnet, args.bound)
        step: dict = {"transition": transition, "subnet": str(subnet_path), "check": check.as_json()}
        steps.append(step)
        if not check.ok:
            failure = (f"cannot refine {transition} of {net.id} by {subnet.id}: "
                       + " ".join(f"condition {r.condition.value} fails: {r.reason}" for r in check.failed))
            break
        refinement = build_refinement(net, transition, subnet, args.bound)
        preservation = check_preservation(net, refinement, args.bound)
        step["preservation"] = preservation.as_json()
        step["net"] = {"id": refinement.net.id, "places": len(refinement.net.places),
                       "transitions": len(refinement.net.transitions)}
        if not preservation.ok:
            failure = f"refining {transition} of {net.id}: Theorem 3.1's claims do not hold on these nets"
        net = refinement.net
    final = check_net(net, cap=args.bound) if failure is None else None
    if args.save and failure is None:
        save_net(net, args.save)
    if args.json:
        print_json({
            "spec": str(args.spec), "upper": upper.id, "ok": failure is None, "steps": steps,
            "refined": None if final is None else {"id": net.id, **final.as_json(),
                                                   "place_ids": [p.id for p in net.places],
                                                   "transition_ids": [t.id for t in net.transitions]},
            "error": failure,
        })
    else:
        print(f"upper net {upper.id}: {len(upper.places)} places, {len(upper.transitions)} transitions")
        for step in steps:
            print(f"refine {step['transition']} by {step['subnet']}")
            for c in step["check"]["conditions"]:
                print(f"  Definition 3.15 ({c['condition']}): {'holds' if c['holds'] else 'FAILS'}: {c['reason']}")
            if "preservation" in step:
                pres = step["preservation"]
                print(f"  refined net {step['net']['id']}: {step['net']['places']} places, {step['net']['transitions']} transitions")
                print(f"  quotient morphism to the upper net: {'yes' if pres['quotient'] else 'NO'}")
                for p in pres["properties"]:
                    verdict = {True: "preserved", False: "LOST", None: "not claimed (the upper net lacks it)"}[p["preserved"]]
                    print(f"  {p['name']}: upper {p['upper']}, refined {p['refined']}: {verdict}")
        if final is not None:
            print(f"refined net: {final.reachable_markings} reachable markings, bounded {final.bounded}, "
                  f"safe {final.safe}, live {final.live}")
        if args.save and failure is None:
            print(f"wrote {args.save}")
    if failure is not None:
        print(f"error: {failure}", file=sys.stderr)
        return 1
    return 0


def register(nsub: argparse._SubParsersAction) -> None:
    r = nsub.add_parser("refine", help="refine transitions by subnets (Definition 3.15, Theorem 3.1) and check the result")
    r.add_argument("spec", help="refinement file (.toml): upper = NET, [[refine]] transition = T, subnet = NET")
    r.add_argument("--save", metavar="OUT", help="write the refined net to OUT (.pnml or .json)")
    r.add_argument("--bound", type=int, default=100_000, metavar="N", help="the most markings to explore (default 100000)")
    r.add_argument("--json", action="store_true", help="print the checks and the refined net's properties as JSON")
    r.set_defaults(handler=_cmd_refine)
