"""Transition refinement (thesis Definition 3.15, Theorem 3.1) on the §3.4.3 hole search."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.errors import InputError, UnknownNameError
from shared.tasknet.analysis import check_net, reachability_graph
from shared.tasknet.jsonform import load_net
from shared.tasknet.ptnet import Arc, Place, PTNet, Transition
from shared.tasknet.refinement import (
    Condition,
    build_refinement,
    check_preservation,
    check_refinement,
    load_spec,
    refine_spec,
)

TASKS = Path(__file__).resolve().parents[2] / "assets" / "tasks"


@pytest.fixture(scope="module")
def upper() -> PTNet:
    return load_net(TASKS / "peg_in_hole.pnml")


@pytest.fixture(scope="module")
def subnet() -> PTNet:
    return load_net(TASKS / "hole_search.pnml")


def edited(net: PTNet, places=None, transitions=None, arcs=None, drop=()) -> PTNet:
    """A copy of ``net`` with extra places/transitions/arcs and the arcs in ``drop`` removed."""
    keep = tuple(a for a in net.arcs if (a.source, a.target) not in drop)
    return net.model_copy(update={
        "places": net.places + tuple(places or ()),
        "transitions": net.transitions + tuple(transitions or ()),
        "arcs": keep + tuple(Arc(source=s, target=t) for s, t in (arcs or ())),
    }).model_validate(net.model_copy(update={
        "places": net.places + tuple(places or ()),
        "transitions": net.transitions + tuple(transitions or ()),
        "arcs": keep + tuple(Arc(source=s, target=t) for s, t in (arcs or ())),
    }).model_dump())


def failed(upper: PTNet, subnet: PTNet) -> set[Condition]:
    return {r.condition for r in check_refinement(upper, "t1", subnet).failed}


# -- the thesis's example --------------------------------------------------------------------------


def test_the_hole_search_meets_all_three_conditions(upper, subnet):
    check = check_refinement(upper, "t1", subnet)
    assert check.ok, check.as_json()
    assert [r.condition for r in check.results] == [Condition.SHARED_ELEMENTS, Condition.START, Condition.END]
    assert "{s0, s4}" in check.results[0].reason


def test_the_spec_file_builds_the_refined_net_of_theorem_3_1(upper, subnet):
    spec = load_spec(TASKS / "hole_search.toml")
    assert [t for t, _ in spec.steps] == ["t1"]
    up, (step,) = refine_spec(spec)
    net = step.net
    assert up.model_dump() == upper.model_dump()
    # S3 = S1 u S', S' = S2 - {s0, s4}; T3 = (T1 - {t1}) u T2
    assert [p.id for p in net.places] == ["s0", "s4", "s_in", "t1.s1", "t1.s2", "t1.s3", "t1.s9"]
    assert [t.id for t in net.transitions] == ["t2", "t3"] + [f"t1.a{i}" for i in range(1, 7)]
    arcs = {(a.source, a.target) for a in net.arcs}
    assert len(arcs) == 4 + 12  # F1 without t1's two arcs, and all twelve of F2
    assert ("s0", "t1.a1") in arcs and {("t1.a5", "s4"), ("t1.a6", "s4")} <= arcs  # pre(t1) -> T', T' -> post(t1)
    assert not any("t1" in (s, t) for s, t in arcs)
    assert net.marking_dict(net.m0) == {"s0": 1}
    assert net.places[3].name == subnet.places[1].name  # labels carried over
    assert step.morphism["t1.a3"] == "t1" and step.morphism["t1.s9"] == "t1" and step.morphism["s4"] == "s4"


def test_the_refined_net_keeps_bounded_safe_and_live(upper, subnet):
    step = build_refinement(upper, "t1", subnet)
    report = check_preservation(upper, step)
    assert report.quotient and report.ok
    assert {p.name: (p.upper, p.refined, p.preserved) for p in report.properties} == {
        "bounded": (True, True, True), "safe": (True, True, True), "live": (True, True, True)}
    assert len(reachability_graph(step.net).markings) == 7  # s0, s1, s2, s3, s9, s4, s_in


def test_a_lost_property_is_reported_as_not_preserved(upper, subnet):
    # the subnet can leave a token behind in a new place: still conforming, but no longer safe
    leaky = edited(subnet, places=[Place(id="trace")], arcs=[("a2", "trace")])
    step = build_refinement(upper, "t1", leaky)
    props = {p.name: p for p in check_preservation(upper, step).properties}
    assert props["bounded"].preserved is False and props["safe"].preserved is False
    assert check_preservation(upper, step).ok is False


# -- each condition of Definition 3.15 refused ------------------------------------------------------


def test_condition_i_refuses_a_subnet_sharing_more_than_the_border(upper, subnet):
    bad = edited(subnet, places=[Place(id="s_in")], arcs=[("a5", "s_in")])
    assert failed(upper, bad) == {Condition.SHARED_ELEMENTS}
    with pytest.raises(InputError, match=r"condition i fails: .*also share \{s_in\}"):
        build_refinement(upper, "t1", bad)


def test_condition_i_refuses_a_subnet_without_the_postset(upper, subnet):
    bad = PTNet(id="short", places=(Place(id="s0", initial=1), Place(id="x")),
                transitions=(Transition(id="a1"),), arcs=(Arc(source="s0", target="a1"), Arc(source="a1", target="x")))
    assert Condition.SHARED_ELEMENTS in failed(upper, bad)
    assert "lacks {s4}" in check_refinement(upper, "t1", bad).failed[0].reason


def test_condition_ii_refuses_an_extra_initial_token(upper, subnet):
    places = tuple(p.model_copy(update={"initial": 1}) if p.id == "s2" else p for p in subnet.places)
    bad = PTNet.model_validate({**subnet.model_dump(), "places": [q.model_dump() for q in places]})  # fresh matrices
    assert Condition.START in failed(upper, bad)
    with pytest.raises(InputError, match=r"condition ii fails: .*marks \{s0, s2\}"):
        build_refinement(upper, "t1", bad)


def test_condition_ii_refuses_a_subnet_whose_start_needs_more_than_pre_t(upper, subnet):
    bad = edited(subnet, places=[Place(id="gripper_ok")], arcs=[("gripper_ok", "a1")])
    assert Condition.START in failed(upper, bad)
    assert "no transition of the subnet has the preset" in check_refinement(upper, "t1", bad).results[1].reason


def test_condition_iii_refuses_a_subnet_that_can_stop_short_of_the_hole(upper, subnet):
    bad = edited(subnet, drop={("a6", "s4")})  # a6 now ends the search with nothing marked
    assert failed(upper, bad) == {Condition.END}
    with pytest.raises(InputError, match=r"condition iii fails: the terminal marking \{\}"):
        build_refinement(upper, "t1", bad)


def test_an_unknown_transition_is_named(upper, subnet):
    with pytest.raises(UnknownNameError):
        check_refinement(upper, "t9", subnet)


# -- property: a conforming subnet keeps a live safe ring live and safe --------------------------


@st.composite
def ring_and_subnet(draw):
    """A one-token ring p0 -> u0 -> p1 -> ... -> p0 and a subnet for one of its transitions made of
    steps that are a choice between 1-3 transitions or a fork into two parallel places and a join."""
    n = draw(st.integers(2, 5))
    ring = PTNet(
        id="ring",
        places=tuple(Place(id=f"p{i}", initial=int(i == 0)) for i in range(n)),
        transitions=tuple(Transition(id=f"u{i}") for i in range(n)),
        arcs=tuple(a for i in range(n) for a in (Arc(source=f"p{i}", target=f"u{i}"),
                                                 Arc(source=f"u{i}", target=f"p{(i + 1) % n}"))),
    )
    k = draw(st.integers(0, n - 1))
    start, end = f"p{k}", f"p{(k + 1) % n}"
    kinds = draw(st.lists(st.sampled_from(["choice1", "choice2", "choice3", "fork"]), min_size=1, max_size=4))
    chain = [start] + [f"q{j}" for j in range(len(kinds) - 1)] + [end]
    places = [Place(id=start, initial=1), Place(id=end)] + [Place(id=q) for q in chain[1:-1]]
    transitions, arcs = [], []
    for j, kind in enumerate(kinds):
        a, b = chain[j], chain[j + 1]
        if kind == "fork":
            left, right = f"l{j}", f"r{j}"
            places += [Place(id=left), Place(id=right)]
            transitions += [Transition(id=f"f{j}"), Transition(id=f"g{j}")]
            arcs += [(a, f"f{j}"), (f"f{j}", left), (f"f{j}", right), (left, f"g{j}"), (right, f"g{j}"), (f"g{j}", b)]
        else:
            for c in range(int(kind[-1])):
                transitions.append(Transition(id=f"v{j}_{c}"))
                arcs += [(a, f"v{j}_{c}"), (f"v{j}_{c}", b)]
    sub = PTNet(id="sub", places=tuple(places), transitions=tuple(transitions),
                arcs=tuple(Arc(source=s, target=t) for s, t in arcs))
    return ring, f"u{k}", sub


@settings(max_examples=60, deadline=None)
@given(ring_and_subnet())
def test_refining_a_live_safe_ring_keeps_it_live_and_safe(case):
    ring, t, sub = case
    assert check_refinement(ring, t, sub).ok
    step = build_refinement(ring, t, sub)
    report = check_preservation(ring, step)
    assert report.quotient
    after = check_net(step.net)
    assert after.safe is True and after.live is True
    assert len(step.net.transitions) == len(ring.transitions) - 1 + len(sub.transitions)
