"""Transition refinement of P/T systems (thesis §3.4.2: Definition 3.15, Theorem 3.1).

A transition ``t1`` of an upper net PN1 is replaced by a subnet PN2. PN2 shares with PN1 exactly
the places ``pre(t1) | post(t1)`` (condition i), starts like ``t1`` does (condition ii) and, in
every terminal marking, has marked the whole postset of ``t1`` (condition iii). Theorem 3.1 then
builds the refined net N3 from PN1 without ``t1`` and the inside of PN2:

    S' = S2 - (pre(t1) | post(t1)),  T' = T2,  F' = F2 restricted to S' | T'
    S3 = S1 | S',  T3 = (T1 - {t1}) | T'
    F3 = F1 on X1 - {t1}  |  F'  |  F2 from pre(t1) into T'  |  F2 from T' into post(t1)

and the map ``f`` (identity on PN1, ``t1`` on everything from PN2) is a quotient morphism N3 -> N1.
Inner elements of PN2 get the id ``<t1>.<id>`` in N3, so a reader sees what they refine.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

import numpy as np

from shared.errors import FileFormatError, InputError
from shared.tasknet.analysis import DEFAULT_STATES_CAP, check_net, reachability_graph
from shared.tasknet.ptnet import Arc, PTNet


class Condition(str, Enum):
    """The three refinement conditions of Definition 3.15."""

    SHARED_ELEMENTS = "i"
    """X1 & X2 = pre(t) | post(t)."""
    START = "ii"
    """Some t' of PN2 has pre(t') = pre(t), and the places marked at M2_0 are exactly pre(t)."""
    END = "iii"
    """Every terminal marking of PN2 marks every place of post(t)."""


@dataclass(frozen=True)
class ConditionResult:
    condition: Condition
    holds: bool
    reason: str
    """One sentence: why it holds or why it fails."""


@dataclass(frozen=True)
class RefinementCheck:
    """Definition 3.15 checked for subnet PN2 against PN1 and its transition ``transition``."""

    upper: str
    subnet: str
    transition: str
    results: tuple[ConditionResult, ...]

    @property
    def ok(self) -> bool:
        return all(r.holds for r in self.results)

    @property
    def failed(self) -> tuple[ConditionResult, ...]:
        return tuple(r for r in self.results if not r.holds)

    def as_json(self) -> dict:
        return {
            "upper": self.upper, "subnet": self.subnet, "transition": self.transition, "ok": self.ok,
            "conditions": [{"condition": r.condition.value, "holds": r.holds, "reason": r.reason} for r in self.results],
        }


def _ids(net: PTNet) -> set[str]:
    return {p.id for p in net.places} | {t.id for t in net.transitions}


def _marked(net: PTNet, m: np.ndarray) -> set[str]:
    """SS_M: the places holding exactly one token (the thesis's C/E reading of a marking)."""
    return {net.places[i].id for i in np.flatnonzero(m == 1)}


def _fmt(ids: set[str]) -> str:
    return "{" + ", ".join(sorted(ids)) + "}"


def _check_shared(upper: PTNet, subnet: PTNet, t: str) -> ConditionResult:
    border = set(upper.preset(t)) | set(upper.postset(t))
    shared = _ids(upper) & _ids(subnet)
    subnet_places = {p.id for p in subnet.places}
    if shared != border:
        extra, missing = shared - border, border - shared
        parts = []
        if extra:
            parts.append(f"they also share {_fmt(extra)}")
        if missing:
            parts.append(f"the subnet lacks {_fmt(missing)}")
        return ConditionResult(Condition.SHARED_ELEMENTS, False,
                               f"the nets must share exactly pre({t}) u post({t}) = {_fmt(border)}, but {' and '.join(parts)}.")
    if not border <= subnet_places:
        return ConditionResult(Condition.SHARED_ELEMENTS, False,
                               f"{_fmt(border - subnet_places)} of pre({t}) u post({t}) are transitions, not places, of the subnet.")
    return ConditionResult(Condition.SHARED_ELEMENTS, True,
                           f"the nets share exactly pre({t}) u post({t}) = {_fmt(border)}.")


def _check_start(upper: PTNet, subnet: PTNet, t: str) -> ConditionResult:
    pre_t = set(upper.preset(t))
    starters = [u.id for u in subnet.transitions if set(subnet.preset(u.id)) == pre_t]
    marked = _marked(subnet, subnet.m0)
    if not starters:
        return ConditionResult(Condition.START, False,
                               f"no transition of the subnet has the preset pre({t}) = {_fmt(pre_t)}.")
    if marked != pre_t or np.any(subnet.m0 > 1):
        return ConditionResult(Condition.START, False,
                               f"the subnet's initial marking marks {_fmt(marked)}, not exactly pre({t}) = {_fmt(pre_t)} with one token each.")
    return ConditionResult(Condition.START, True,
                           f"{', '.join(starters)} has the preset {_fmt(pre_t)}, which is what the initial marking marks.")


def _check_end(upper: PTNet, subnet: PTNet, t: str, cap: int) -> ConditionResult:
    post_t = set(upper.postset(t))
    graph = reachability_graph(subnet, cap, strict=True)
    terminals = [_marked(subnet, graph.markings[i]) for i in graph.dead]
    for ss in terminals:
        if not post_t <= ss:
            return ConditionResult(Condition.END, False,
                                   f"the terminal marking {_fmt(ss)} of the subnet does not mark all of post({t}) = {_fmt(post_t)}.")
    if not terminals:
        return ConditionResult(Condition.END, True,
                               "the subnet has no terminal marking, so the condition holds vacuously (Definition 3.15 iii).")
    return ConditionResult(Condition.END, True,
                           f"all {len(terminals)} terminal marking(s) of the subnet mark post({t}) = {_fmt(post_t)}.")


def check_refinement(upper: PTNet, transition: str, subnet: PTNet, cap: int = DEFAULT_STATES_CAP) -> RefinementCheck:
    """Definition 3.15 for refining ``transition`` of ``upper`` by ``subnet``; all three are reported."""
    upper.transition_index_of(transition)  # raises UnknownNameError with the valid choices
    results = (
        _check_shared(upper, subnet, transition),
        _check_start(upper, subnet, transition),
        _check_end(upper, subnet, transition, cap),
    )
    return RefinementCheck(upper=upper.id, subnet=subnet.id, transition=transition, results=results)


# -- Theorem 3.1 --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Refinement:
    """The refined net N3 and the quotient map f: X3 -> X1 of Theorem 3.1."""

    net: PTNet
    transition: str
    morphism: dict[str, str]
    """f: every id of N3 to the id of PN1 it maps to (inner subnet elements to the refined transition)."""
    check: RefinementCheck


def inner_id(transition: str, node: str) -> str:
    return f"{transition}.{node}"


def build_refinement(upper: PTNet, transition: str, subnet: PTNet, cap: int = DEFAULT_STATES_CAP) -> Refinement:
    """N3 of Theorem 3.1, after checking Definition 3.15 (InputError naming each failed condition)."""
    check = check_refinement(upper, transition, subnet, cap)
    if not check.ok:
        raise InputError(f"cannot refine {transition} of {upper.id} by {subnet.id}: "
                         + " ".join(f"condition {r.condition.value} fails: {r.reason}" for r in check.failed))
    pre_t, post_t = set(upper.preset(transition)), set(upper.postset(transition))
    border = pre_t | post_t
    inner_places = [p for p in subnet.places if p.id not in border]  # S'
    inner = {p.id for p in inner_places} | {u.id for u in subnet.transitions}  # X'
    rename = {x: inner_id(transition, x) for x in inner}

    def sub(x: str) -> str:
        return rename.get(x, x)

    places = list(upper.places) + [p.model_copy(update={"id": sub(p.id), "initial": 0}) for p in inner_places]
    transitions = [u for u in upper.transitions if u.id != transition]
    transitions += [u.model_copy(update={"id": sub(u.id)}) for u in subnet.transitions]
    arcs = [a for a in upper.arcs if transition not in (a.source, a.target)]  # F1 on X1 - {t1}
    for a in subnet.arcs:
        inside = a.source in inner and a.target in inner  # F'
        entering = a.source in pre_t and a.target in inner  # pre(t1) -> T'
        leaving = a.source in inner and a.target in post_t  # T' -> post(t1)
        if inside or entering or leaving:
            arcs.append(Arc(source=sub(a.source), target=sub(a.target), weight=a.weight))
    name = f"{upper.name or upper.id}, {transition} refined by {subnet.name or subnet.id}"
    net = PTNet(id=f"{upper.id}_{transition}_refined", name=name,
                places=tuple(places), transitions=tuple(transitions), arcs=tuple(arcs))
    morphism = {x: x for x in _ids(upper) if x != transition} | {sub(x): transition for x in inner}
    return Refinement(net=net, transition=transition, morphism=morphism, check=check)


# -- what is preserved ----------------------------------------------------------------------------


@dataclass(frozen=True)
class PropertyPreservation:
    name: str
    upper: bool | None
    refined: bool | None

    @property
    def preserved(self) -> bool | None:
        """True when PN1 has the property and N3 keeps it, False when N3 loses it; None otherwise."""
        if self.upper is None or self.refined is None:
            return None
        return self.refined if self.upper else None


@dataclass(frozen=True)
class PreservationReport:
    """Theorem 3.1 checked on the actual nets: f is a quotient, and bounded/safe/live carry over."""

    surjective: bool
    """f(X3) = X1."""
    arcs_covered: bool
    """Every arc of F1 is the image of an arc of F3 (quotient condition ii)."""
    arcs_mapped: bool
    """Every arc of F3 maps to an arc of F1 or inside t1 (net morphism condition i)."""
    properties: tuple[PropertyPreservation, ...]

    @property
    def quotient(self) -> bool:
        return self.surjective and self.arcs_covered and self.arcs_mapped

    @property
    def ok(self) -> bool:
        return self.quotient and all(p.preserved is not False for p in self.properties)

    def as_json(self) -> dict:
        return {
            "quotient": self.quotient, "surjective": self.surjective, "arcs_covered": self.arcs_covered,
            "arcs_mapped": self.arcs_mapped, "ok": self.ok,
            "properties": [{"name": p.name, "upper": p.upper, "refined": p.refined, "preserved": p.preserved}
                           for p in self.properties],
        }


def check_preservation(upper: PTNet, refinement: Refinement, cap: int = DEFAULT_STATES_CAP) -> PreservationReport:
    f, t1 = refinement.morphism, refinement.transition
    f1 = {(a.source, a.target) for a in upper.arcs}
    images = {(f[a.source], f[a.target]) for a in refinement.net.arcs}
    mapped = all(pair in f1 or pair == (t1, t1) for pair in images)
    before, after = check_net(upper, cap), check_net(refinement.net, cap)
    props = tuple(PropertyPreservation(name, getattr(before, name), getattr(after, name))
                  for name in ("bounded", "safe", "live"))
    return PreservationReport(surjective=set(f.values()) == _ids(upper), arcs_covered=f1 <= images,
                              arcs_mapped=mapped, properties=props)


# -- the refinement file ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RefinementSpec:
    """A TOML file naming the upper net and, per refined transition, its subnet."""

    path: Path
    upper: Path
    steps: tuple[tuple[str, Path], ...] = field(default=())


def load_spec(path: str | Path) -> RefinementSpec:
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(path, f"not valid TOML: {exc}") from None
    upper = data.get("upper")
    refine = data.get("refine")
    if not isinstance(upper, str):
        raise FileFormatError(path, "needs a string: the upper net's file", field="upper")
    if not isinstance(refine, list) or not refine:
        raise FileFormatError(path, "needs one or more [[refine]] tables", field="refine")
    steps = []
    for i, r in enumerate(refine):
        if not (isinstance(r, dict) and isinstance(r.get("transition"), str) and isinstance(r.get("subnet"), str)):
            raise FileFormatError(path, "needs string fields transition and subnet", field=f"refine[{i}]")
        steps.append((r["transition"], path.parent / r["subnet"]))
    return RefinementSpec(path=path, upper=path.parent / upper, steps=tuple(steps))


def refine_spec(spec: RefinementSpec, cap: int = DEFAULT_STATES_CAP) -> tuple[PTNet, tuple[Refinement, ...]]:
    """Apply the spec's refinements in order; returns the upper net and each step."""
    from shared.tasknet.jsonform import load_net

    upper = load_net(spec.upper)
    net, steps = upper, []
    for transition, subnet_path in spec.steps:
        step = build_refinement(net, transition, load_net(subnet_path), cap)
        steps.append(step)
        net = step.net
    return upper, tuple(steps)


__all__ = [
    "Condition", "ConditionResult", "RefinementCheck", "Refinement", "PropertyPreservation", "PreservationReport",
    "RefinementSpec", "check_refinement", "build_refinement", "check_preservation", "load_spec", "refine_spec",
    "inner_id",
]
