"""Reachability of generated nets: ``shared.tasknet.analysis.reachability_graph`` against SNAKES's
``StateGraph`` on the same net (issue 18's benchmark).

Nets, all generated here:

* ``ring N``: N places in a cycle, one token, N transitions: N reachable markings (the shape of a
  long action-level task net ``s0 a1 s1 ... an sn`` closed into a loop);
* ``toggles M``: M independent two-place switches (2M places, 2M transitions): 2^M markings, each
  with M enabled transitions (wide, not long).

Both tools build the whole reachability graph; the figure is wall time (best of ``--repeat``),
the ratio SNAKES / ours (above 1: ours is faster). Marking counts must agree.

    .venv/bin/python benchmarks/bench_tasknet.py          # table
    .venv/bin/python benchmarks/bench_tasknet.py --json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "tasknet"))  # the SNAKES oracle the tests use

from shared.tasknet.analysis import reachability_graph  # noqa: E402
from shared.tasknet.ptnet import Arc, Place, PTNet, Transition  # noqa: E402
from snakes_oracle import snakes_graph  # noqa: E402


def ring(n: int) -> PTNet:
    places = tuple(Place(id=f"p{i}", initial=int(i == 0)) for i in range(n))
    transitions = tuple(Transition(id=f"t{i}") for i in range(n))
    arcs = tuple(a for i in range(n) for a in (Arc(source=f"p{i}", target=f"t{i}"), Arc(source=f"t{i}", target=f"p{(i + 1) % n}")))
    return PTNet(id=f"ring{n}", places=places, transitions=transitions, arcs=arcs)


def toggles(m: int) -> PTNet:
    places = tuple(Place(id=f"{s}{i}", initial=int(s == "off")) for i in range(m) for s in ("off", "on"))
    transitions = tuple(Transition(id=f"{s}{i}") for i in range(m) for s in ("up", "down"))
    arcs = tuple(a for i in range(m) for a in (
        Arc(source=f"off{i}", target=f"up{i}"), Arc(source=f"up{i}", target=f"on{i}"),
        Arc(source=f"on{i}", target=f"down{i}"), Arc(source=f"down{i}", target=f"off{i}")))
    return PTNet(id=f"toggles{m}", places=places, transitions=transitions, arcs=arcs)


def snakes_count(net: PTNet) -> int:
    return len(snakes_graph(net))


def best(fn, repeat: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    rows = []
    for name, net in (("ring 1,000", ring(1000)), ("ring 3,000", ring(3000)), ("toggles 10", toggles(10)),
                      ("toggles 12", toggles(12))):
        ours_s, graph = best(lambda: reachability_graph(net, cap=10_000_000), args.repeat)
        theirs_s, count = best(lambda: snakes_count(net), max(1, args.repeat - 1))
        if len(graph) != count:
            print(f"{name}: ours finds {len(graph)} markings, SNAKES {count}", file=sys.stderr)
            return 1
        rows.append({"net": name, "places": len(net.places), "transitions": len(net.transitions), "markings": count,
                     "ours_s": ours_s, "snakes_s": theirs_s, "ratio": theirs_s / ours_s})
        print(f"{name}: {count} markings, ours {ours_s:.3f} s, SNAKES {theirs_s:.3f} s", file=sys.stderr)
    if args.json:
        print(json.dumps(rows))
    else:
        print("| net | places | transitions | markings | ours | SNAKES | ratio (SNAKES / ours) |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        for r in rows:
            print(f"| {r['net']} | {r['places']:,} | {r['transitions']:,} | {r['markings']:,} | {r['ours_s'] * 1e3:.0f} ms | "
                  f"{r['snakes_s'] * 1e3:.0f} ms | {r['ratio']:.1f}x |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
