"""SNAKES (an independent Petri-net library) as an oracle: the same net built in SNAKES and its
state graph, for the reachability tests and ``benchmarks/bench_tasknet.py``."""

from __future__ import annotations

from shared.tasknet.ptnet import PTNet


def snakes_graph(net: PTNet):
    """SNAKES's ``StateGraph`` of ``net``, built (black tokens, weights as multi-arcs)."""
    from snakes.nets import MultiArc, PetriNet, Place, StateGraph, Transition, Value, dot

    def weighted(w: int):
        return Value(dot) if w == 1 else MultiArc([Value(dot)] * w)

    sn = PetriNet(net.id)
    for p in net.places:
        sn.add_place(Place(p.id, [dot] * p.initial))
    for t in net.transitions:
        sn.add_transition(Transition(t.id))
    for a in net.arcs:
        if a.source in net.place_index:
            sn.add_input(a.source, a.target, weighted(a.weight))
        else:
            sn.add_output(a.target, a.source, weighted(a.weight))
    graph = StateGraph(sn)
    graph.build()
    return graph


def snakes_reachable(net: PTNet) -> set[tuple[int, ...]]:
    """The reachable markings as SNAKES finds them, in the order of ``net.places``."""
    graph = snakes_graph(net)
    out = set()
    for state in graph:
        graph.goto(state)
        marking = graph.net.get_marking()
        out.add(tuple(len(marking(p.id)) if p.id in marking else 0 for p in net.places))
    return out
