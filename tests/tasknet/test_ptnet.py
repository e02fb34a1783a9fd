"""The firing rule and the state equation of P/T nets (thesis Definitions 3.3-3.4)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tasknet_nets import small_nets

from shared.errors import InputError
from shared.tasknet.ptnet import Arc, Place, PTNet, Transition, net_from_matrices


def _random_run(net: PTNet, choices: list[int]) -> tuple[np.ndarray, list[int]]:
    """Fire enabled transitions picked by ``choices`` one at a time; the firing sequence."""
    m, seq = np.array(net.m0), []
    for c in choices:
        enabled = np.flatnonzero(net.enabled(m))
        if not len(enabled):
            break
        t = int(enabled[c % len(enabled)])
        m = net.fire(m, t)
        seq.append(t)
    return m, seq


@settings(max_examples=80, deadline=None)
@given(net=small_nets(capacities=True), choices=st.lists(st.integers(0, 100), max_size=25))
def test_state_equation_holds_for_every_fired_sequence(net, choices):
    m, seq = _random_run(net, choices)
    sigma = net.parikh(seq)
    np.testing.assert_array_equal(m, net.state_equation(net.m0, sigma))
    np.testing.assert_array_equal(m, net.m0 + net.incidence @ sigma)
    assert (m >= 0).all() and (m <= net.capacity).all()


@settings(max_examples=80, deadline=None)
@given(net=small_nets(capacities=True), tokens=st.lists(st.integers(0, 4), min_size=5, max_size=5))
def test_vectorised_enabling_agrees_with_definition_3_4_place_by_place(net, tokens):
    # a marking holds at most K(s) on each place (Definition 3.4 i)
    m = np.minimum(np.array(tokens[: len(net.places)], dtype=np.int64), net.capacity)
    enabled = net.enabled(m)
    for j in range(len(net.transitions)):
        by_definition = all(
            net.pre[s, j] <= m[s] <= (net.capacity[s] - net.post[s, j]) for s in range(len(net.places))
        )
        assert enabled[j] == by_definition
    ts, nexts = net.successors(m)
    assert list(ts) == list(np.flatnonzero(enabled))
    for t, m2 in zip(ts, nexts):
        np.testing.assert_array_equal(m2, m - net.pre[:, t] + net.post[:, t])


def test_matrices_follow_the_arcs_and_their_weights():
    net = PTNet(
        places=(Place(id="a", initial=2), Place(id="b")),
        transitions=(Transition(id="t"),),
        arcs=(Arc(source="a", target="t", weight=2), Arc(source="t", target="b", weight=3)),
    )
    np.testing.assert_array_equal(net.pre, [[2], [0]])
    np.testing.assert_array_equal(net.post, [[0], [3]])
    np.testing.assert_array_equal(net.incidence, [[-2], [3]])
    assert net.preset("t") == ["a"] and net.postset("t") == ["b"]
    np.testing.assert_array_equal(net.fire(net.m0, "t"), [0, 3])


def test_a_full_output_place_disables_a_transition_by_its_capacity():
    # Definition 3.4: M(s) <= K(s) - W(t, s); b holds 1 of 2 and t would add 2
    net = net_from_matrices(np.array([[1], [0]]), np.array([[0], [2]]), np.array([1, 1]), capacity=[None, 2])
    assert not net.enabled(net.m0)[0]
    with pytest.raises(InputError, match="'t0' is not enabled"):
        net.fire(net.m0, "t0")
    roomy = net_from_matrices(np.array([[1], [0]]), np.array([[0], [2]]), np.array([1, 0]), capacity=[None, 2])
    np.testing.assert_array_equal(roomy.fire(roomy.m0, "t0"), [0, 2])


@settings(max_examples=60, deadline=None)
@given(net=small_nets(capacities=True), choices=st.lists(st.integers(0, 100), max_size=20))
def test_complement_places_replay_the_capacity_rule(net, choices):
    plain = net.without_capacities()
    assert not plain.has_capacities
    m, seq = _random_run(net, choices)
    m_plain = plain.fire_sequence(plain.m0, seq)
    n = len(net.places)
    np.testing.assert_array_equal(m_plain[:n], m)
    np.testing.assert_array_equal(plain.enabled(m_plain), net.enabled(m))


@pytest.mark.parametrize(
    ("places", "transitions", "arcs", "message"),
    [
        ((Place(id="a"),), (Transition(id="a"),), (), "used twice"),
        ((Place(id="a"), Place(id="b")), (), (Arc(source="a", target="b"),), "must join a place and a transition"),
        ((Place(id="a"),), (Transition(id="t"),), (Arc(source="a", target="x"),), "'x' is not a place or transition"),
        ((Place(id="a", initial=3, capacity=2),), (), (), "exceeds its capacity"),
    ],
)
def test_malformed_nets_are_refused_with_the_reason(places, transitions, arcs, message):
    with pytest.raises(ValueError, match=message):
        PTNet(places=places, transitions=transitions, arcs=arcs)
