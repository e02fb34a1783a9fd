"""The action-level task net of a free-motion path (thesis §3.3.2, Figures 3.4 and 3.5).

A task in free motion is a sequence of states and actions ``s0 a1 s1 a2 ... an sn``: the states
are where the tool is at rest or changes course (the path's key points,
``shared.tasknet.keypoints``), the actions the motions between them. As a condition/event net:
one place per state, one transition per action, ``s_{i-1} -> a_i -> s_i``, the first state
marked. A key point where the tool stops and the one where it moves again are one state (it
rests there), so a rest adds no action. An action that carries conditions (a statement's
``WITH ...`` or ``UNTIL ...``) gets one constraint place per condition in its preset, marked
initially (Figure 3.5): the action can fire only while its condition holds.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from shared.errors import InputError
from shared.tasknet.cenet import EventModel, condition_event_net
from shared.tasknet.keypoints import KeyPoint
from shared.tasknet.ptnet import PTNet


def states_of(points: Sequence[KeyPoint]) -> list[KeyPoint]:
    """The states among the key points: a stop and the move after it are one (the first kept)."""
    states: list[KeyPoint] = []
    for k in points:
        if k.kind == "move" and states and states[-1].kind == "stop":
            continue
        states.append(k)
    return states


def action_net(points: Sequence[KeyPoint], constraints: Mapping[int, Sequence[str]] | None = None,
               net_id: str = "actions") -> PTNet:
    """The ``s0 a1 s1 ... an sn`` net of the key points ``points`` (path order);
    ``constraints[i]``: the conditions of action ``i`` (1-based), each a constraint place."""
    states = states_of(points)
    if not states:
        raise InputError("an action net needs at least one key point")
    n = len(states) - 1
    constraints = dict(constraints or {})
    bad = sorted(i for i in constraints if not 1 <= i <= n)
    if bad:
        raise InputError(f"constraints given for actions {bad}, but the path has actions 1..{n}")
    conditions: dict[str, str | None] = {}
    for i, k in enumerate(states):
        x, y, z = (1e3 * c for c in k.position)
        conditions[f"S{i}"] = f"AT(s{i}: {x:.1f}, {y:.1f}, {z:.1f} mm, t={k.t:.2f})"
    events, holding = [], ["S0"]
    for i in range(1, n + 1):
        pre = [f"S{i - 1}"]
        for j, text in enumerate(constraints.get(i, ()), start=1):
            cid = f"C{i}_{j}"
            conditions[cid] = text
            pre.append(cid)
            holding.append(cid)
        events.append(EventModel(id=f"A{i}", action=f"move(s{i - 1},s{i})", pre=pre, post=[f"S{i}"]))
    return condition_event_net(conditions, events, holding, net_id=net_id)
