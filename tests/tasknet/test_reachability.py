"""Reachability against SNAKES (an independent implementation), Karp-Miller coverability,
and the properties `check_net` reports, on random nets and on the thesis's Table 3.2 net."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from snakes_oracle import snakes_reachable
from tasknet_nets import small_nets

from shared.errors import InputError
from shared.tasknet.analysis import (
    OMEGA,
    StateSpaceTooLarge,
    check_net,
    coverability_tree,
    live_transitions,
    reachability_graph,
)
from shared.tasknet.cenet import check_condition_event, condition_event_net, to_condition_event_model
from shared.tasknet.jsonform import load_net
from shared.tasknet.ptnet import PTNet, net_from_matrices

ROOT = Path(__file__).resolve().parents[2]
PEG = ROOT / "assets" / "tasks" / "peg_transfer_ce.pnml"


@settings(max_examples=40, deadline=None)
@given(net=small_nets(max_places=4, max_transitions=4, capacities=True))
def test_reachable_markings_are_those_snakes_finds(net):
    graph = reachability_graph(net, cap=200)
    assume(graph.complete)
    # SNAKES has no capacities: it explores the complement-place form, projected on our places
    plain = net.without_capacities()
    theirs = {m[: len(net.places)] for m in snakes_reachable(plain)}
    assert graph.marking_set() == theirs


@settings(max_examples=40, deadline=None)
@given(net=small_nets(max_places=4, max_transitions=4, capacities=True))
def test_every_reachable_marking_is_covered_by_the_karp_miller_tree(net):
    try:
        tree = coverability_tree(net, cap=3000)
    except StateSpaceTooLarge:
        assume(False)
    graph = reachability_graph(net, cap=300)
    for m in graph.markings:
        assert tree.covers(m)
    bounds = tree.bounds()
    capped = net.capacity < np.iinfo(np.int64).max
    assert (bounds[capped] != OMEGA).all() and (bounds[capped] <= net.capacity[capped]).all()
    if graph.complete:
        # bounded: the tree holds exactly the reachable markings, no omega
        assert (bounds != OMEGA).all()
        np.testing.assert_array_equal(bounds, graph.markings.max(axis=0))
    else:
        assert (bounds == OMEGA).any()


def test_karp_miller_finds_the_unbounded_place_of_a_generator():
    # t0: p0 -> p0 + p1 puts a token on p1 each time; t1: p1 -> p2 moves one on; p3 stays empty
    pre = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 0], [0, 0, 1]])
    post = np.array([[1, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0]])
    net = net_from_matrices(pre, post, np.array([1, 0, 0, 0]))
    tree = coverability_tree(net)
    np.testing.assert_array_equal(tree.bounds(), [1, OMEGA, OMEGA, 0])
    np.testing.assert_array_equal(tree.quasi_live(), [True, True, False])
    report = check_net(net, cap=50)
    assert report.reachability_complete is False and report.reachable_markings == 50
    assert report.bounded is False and report.safe is False
    assert report.bounds == {"p0": 1, "p1": None, "p2": None, "p3": 0}
    assert report.live is False  # t2 never fires
    assert report.quasi_live_transitions == {"t0": True, "t1": True, "t2": False}


def test_a_strict_cap_raises_instead_of_flagging():
    net = net_from_matrices(np.array([[1]]), np.array([[2]]), np.array([1]))
    assert reachability_graph(net, cap=5).complete is False
    with pytest.raises(StateSpaceTooLarge, match="more than 5 reachable markings"):
        reachability_graph(net, cap=5, strict=True)


def _live_by_definition(net: PTNet, graph) -> list[bool]:
    """L4 straight from the definition: from every reachable marking some firing of t is reachable."""
    n = len(graph.markings)
    succ = [[] for _ in range(n)]
    fires = [set() for _ in range(n)]
    for s, t, d in graph.edges:
        succ[s].append(d)
        fires[s].add(int(t))
    out = []
    for t in range(len(net.transitions)):
        ok = True
        for start in range(n):
            seen, stack = {start}, [start]
            found = False
            while stack and not found:
                i = stack.pop()
                found = t in fires[i]
                for j in succ[i]:
                    if j not in seen:
                        seen.add(j)
                        stack.append(j)
            ok &= found
        out.append(ok)
    return out


@settings(max_examples=60, deadline=None)
@given(net=small_nets(max_places=4, max_transitions=4, capacities=True))
def test_liveness_from_bottom_components_matches_the_definition(net):
    graph = reachability_graph(net, cap=150)
    assume(graph.complete)
    assert list(live_transitions(graph)) == _live_by_definition(net, graph)
    report = check_net(net, cap=150)
    assert report.deadlock_free == (len(graph.dead) == 0)
    assert report.safe == bool((graph.markings <= 1).all())


def test_the_peg_transfer_net_of_table_3_2():
    net = load_net(PEG)
    assert [p.predicate for p in net.places] == [
        "HANDEEMPTY", "PEGFREE(PEG)", "HOLDING(PEG)", "PEGINHOLE(PEG,HOLE1)",
        "HOLEEMPTY(HOLE1)", "HOLEEMPTY(HOLE2)", "PEGINHOLE(PEG,HOLE2)",
    ]  # fmt: skip
    check_condition_event(net)
    actions = {t.action: t.id for t in net.transitions}
    seq = [actions[a] for a in ("grasp(PEG)", "part(PEG,HOLE1)", "mate(PEG,HOLE2)", "release(PEG)")]
    end = net.fire_sequence(net.m0, seq)
    assert net.marking_dict(end) == {"P1": 1, "P5": 1, "P7": 1}
    assert net.enabled_ids(end) == []  # a terminal marking (Definition 3.14)
    report = check_net(net)
    assert report.safe and report.bounded and report.reachable_markings == 9
    assert {"P1": 1, "P5": 1, "P7": 1} in report.dead_markings
    assert report.live is False and report.deadlock_free is False
    compact = to_condition_event_model(net)
    assert compact.initial_marking == ["P1", "P2", "P4", "P6"]
    assert next(t for t in compact.transitions if t.action == "part(PEG,HOLE1)").post == ["P3", "P5"]


def test_condition_event_nets_must_stay_1_safe():
    # e puts a token on a condition that may already hold: not a C/E net
    with pytest.raises(InputError, match="not 1-safe"):
        condition_event_net(["a", "b"], [{"id": "e", "pre": ["a"], "post": ["a", "b"]}], ["a"])
    weighted = net_from_matrices(np.array([[2]]), np.array([[0]]), np.array([1]))
    with pytest.raises(InputError, match="weight 2"):
        check_condition_event(weighted)
    with pytest.raises(InputError, match="not conditions of the net"):
        condition_event_net(["a"], [], ["z"])
