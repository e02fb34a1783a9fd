"""Condition/event nets as 1-safe P/T nets: every arc of weight 1, no capacities, at most one
token per place in every reachable marking. A place is a condition (it holds or not), a
transition an event; a marking is the set of conditions that hold (``SS_M`` of §3.4.2).

Side conditions (a place both before and after an event, as HOLDING(PEG) is for part and mate
in Table 3.2) are allowed: the event needs the condition and leaves it holding.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping, Sequence

from pydantic import BaseModel, ConfigDict, Field

from shared.errors import InputError
from shared.tasknet.analysis import DEFAULT_STATES_CAP
from shared.tasknet.ptnet import Arc, Place, PTNet, Transition


class ConditionModel(BaseModel):
    model_config = ConfigDict(extra="forbid")
    id: str = Field(min_length=1)
    predicate: str | None = None


class EventModel(BaseModel):
    model_config = ConfigDict(extra="forbid")
    id: str = Field(min_length=1)
    action: str | None = None
    pre: list[str] = []
    post: list[str] = []


class ConditionEventModel(BaseModel):
    """The compact JSON form of a C/E net: conditions, events with their pre- and post-sets,
    and the conditions that hold initially."""

    model_config = ConfigDict(extra="forbid")
    places: list[ConditionModel]
    transitions: list[EventModel]
    initial_marking: list[str] = []


def condition_event_net(
    conditions: Sequence[str] | Mapping[str, str | None],
    events: Iterable[EventModel | Mapping],
    holding: Iterable[str] = (),
    net_id: str = "net",
    cap: int = DEFAULT_STATES_CAP,
) -> PTNet:
    """A C/E net from conditions (ids, or ids to predicates), events and the initial case;
    InputError if the result is not 1-safe."""
    preds = dict(conditions) if isinstance(conditions, Mapping) else {c: None for c in conditions}
    initial = set(holding)
    unknown = initial - preds.keys()
    if unknown:
        raise InputError(f"initial conditions {sorted(unknown)} are not conditions of the net; valid: {sorted(preds)}")
    places = tuple(Place(id=c, predicate=p, initial=int(c in initial)) for c, p in preds.items())
    transitions, arcs = [], []
    for ev in events:
        ev = ev if isinstance(ev, EventModel) else EventModel.model_validate(ev)
        transitions.append(Transition(id=ev.id, action=ev.action))
        arcs += [Arc(source=s, target=ev.id) for s in dict.fromkeys(ev.pre)]
        arcs += [Arc(source=ev.id, target=s) for s in dict.fromkeys(ev.post)]
    try:
        net = PTNet(id=net_id, places=places, transitions=tuple(transitions), arcs=tuple(arcs))
    except ValueError as exc:  # pydantic's ValidationError is a ValueError
        raise InputError(f"condition/event net {net_id!r}: {_first_error(exc)}") from None
    check_condition_event(net, cap)
    return net


def check_condition_event(net: PTNet, cap: int = DEFAULT_STATES_CAP) -> None:
    """Raise InputError naming the first reason ``net`` is not a condition/event net."""
    for arc in net.arcs:
        if arc.weight != 1:
            raise InputError(f"net {net.id!r}: arc {arc.source}->{arc.target} has weight {arc.weight}; a C/E net has weight 1")
    for p in net.places:
        if p.capacity is not None:
            raise InputError(f"net {net.id!r}: place {p.id!r} has a capacity; a C/E net has none (1-safety bounds it)")
        if p.initial > 1:
            raise InputError(f"net {net.id!r}: place {p.id!r} starts with {p.initial} tokens; a condition holds or not")
    # breadth-first like reachability_graph, but stopping at the first marking over 1
    seen = {net.m0.tobytes()}
    queue = deque([net.m0])
    while queue:
        _, nexts = net.successors(queue.popleft())
        over = (nexts > 1).any(axis=1)
        if over.any():
            m = nexts[int(over.argmax())]
            raise InputError(f"net {net.id!r} is not 1-safe: it reaches the marking {net.marking_dict(m)}")
        for m in nexts:
            key = m.tobytes()
            if key not in seen:
                if len(seen) >= cap:
                    raise InputError(f"net {net.id!r}: more than {cap} reachable markings; 1-safety not established")
                seen.add(key)
                queue.append(m)


def to_condition_event_model(net: PTNet) -> ConditionEventModel:
    """The compact form of a C/E net (checked first)."""
    check_condition_event(net)
    return ConditionEventModel(
        places=[ConditionModel(id=p.id, predicate=p.predicate) for p in net.places],
        transitions=[
            EventModel(id=t.id, action=t.action, pre=net.preset(t.id), post=net.postset(t.id)) for t in net.transitions
        ],
        initial_marking=[p.id for p in net.places if p.initial],
    )


def from_condition_event_model(model: ConditionEventModel, net_id: str = "net") -> PTNet:
    return condition_event_net(
        {c.id: c.predicate for c in model.places}, model.transitions, model.initial_marking, net_id=net_id
    )


def _first_error(exc: Exception) -> str:
    errors = getattr(exc, "errors", None)
    if callable(errors):
        first = errors()[0]
        where = ".".join(str(x) for x in first.get("loc", ()))
        msg = str(first.get("msg", exc)).removeprefix("Value error, ")
        return f"{where}: {msg}" if where else msg
    return str(exc)
