"""The action-level net of a path (thesis Figures 3.4 and 3.5): states at the key points,
one action between each two, a rest one state, constraint places before constrained actions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from shared.errors import InputError
from shared.tasknet.action_net import action_net, states_of
from shared.tasknet.analysis import reachability_graph
from shared.tasknet.keypoints import key_points

JOG = Path(__file__).parents[1] / "program" / "data" / "puma_jog_100hz.npz"


def square(step=0.001) -> np.ndarray:
    corners = np.array([(0, 0, 0), (0.1, 0, 0), (0.1, 0.1, 0), (0, 0.1, 0)], dtype=float)
    out = [corners[0]]
    for a, b in zip(corners, corners[1:]):
        out += [a + (b - a) * s for s in np.linspace(0, 1, 101)[1:]]
    return np.array(out)


def test_a_path_with_two_corners_is_s0_a1_s1_a2_s2_a3_s3() -> None:
    net = action_net(key_points(square()))
    assert [p.id for p in net.places] == ["S0", "S1", "S2", "S3"]
    assert [t.action for t in net.transitions] == ["move(s0,s1)", "move(s1,s2)", "move(s2,s3)"]
    for i, t in enumerate(net.transitions):
        assert net.preset(t.id) == [f"S{i}"] and net.postset(t.id) == [f"S{i + 1}"]
    assert "100.0, 0.0, 0.0 mm" in net.places[1].predicate  # the state says where it is
    graph = reachability_graph(net)
    assert len(graph) == 4  # one token walks the chain: s0, s1, s2, s3
    m = net.m0
    for t in net.transitions:  # the actions fire in order, and only so
        assert net.enabled_ids(m) == [t.id]
        m = net.fire(m, t.id)
    assert net.marking_dict(m) == {"S3": 1} and net.enabled_ids(m) == []


def test_a_constrained_action_waits_for_its_condition_place() -> None:
    net = action_net(key_points(square()), {2: ["UNTIL FORCE > 5 N", "WITH SPEED 20 %"]})
    assert net.preset("A2") == ["S1", "C2_1", "C2_2"]
    assert [p.predicate for p in net.places if p.id.startswith("C")] == ["UNTIL FORCE > 5 N", "WITH SPEED 20 %"]
    assert net.marking_dict(net.m0)["C2_1"] == 1
    with pytest.raises(InputError, match="actions 1..3"):
        action_net(key_points(square()), {4: ["UNTIL CONTACT"]})


def test_a_rest_is_one_state_and_the_recorded_jog_gives_its_actions() -> None:
    data = np.load(JOG)
    points = key_points(data["world_T_tool"][:, :3, 3], data["t"])
    states = states_of(points)
    assert all(not (a.kind == "stop" and b.kind == "move") for a, b in zip(states, states[1:]))
    net = action_net(points)
    assert len(net.transitions) == len(states) - 1 and len(net.places) == len(states)
    kinds = [k.kind for k in points]
    assert len(states) == len(points) - sum(1 for a, b in zip(kinds, kinds[1:]) if (a, b) == ("stop", "move"))
