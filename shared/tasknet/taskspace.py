"""The task space of §3.5.2 as data: individuals, predicates, and STRIPS F-rules, grounded into
the place/transition net the console recognises actions on.

A task file (``assets/tasks/*.toml``) names the individuals ``D`` (each bound to what it is in
the cell: the hand, a movable object, a feature), the predicates ``P`` with their contact
conditions (Definition 3.26, read by :mod:`shared.tasknet.contacts`), and the rules ``Γ`` (each
with PRE, DEL and ADD lists of literals over the rule's typed variables).

Grounding unfolds the predicate/transition net of §3.5.2 into a P/T net: one place per ground
atom (``PEGINHOLE(PEG,HOLE1)``), one transition per ground rule instance whose variables take
individuals of their kinds (``part(PEG,HOLE1)``); a transition takes a token from every PRE atom
and puts one on every atom of ``PRE - DEL + ADD``, so an atom the rule needs and keeps (HOLDING
for part) is a side condition. The marking of this net is the set of true atoms.
"""

from __future__ import annotations

import itertools
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from shared.errors import FileFormatError, InputError
from shared.tasknet.ptnet import Arc, Place, PTNet, Transition

_ATOM = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:\(\s*([^()]*?)\s*\))?\s*$")


def parse_atom(text: str) -> tuple[str, tuple[str, ...]]:
    """``"PEGINHOLE(p, h)"`` -> ``("PEGINHOLE", ("p", "h"))``; ``"HANDEEMPTY"`` -> no arguments."""
    m = _ATOM.match(text)
    if m is None:
        raise InputError(f"{text!r} is not an atom: write NAME or NAME(arg, ...)")
    args = tuple(a.strip() for a in m.group(2).split(",")) if m.group(2) else ()
    if any(not a for a in args):
        raise InputError(f"{text!r} has an empty argument")
    return m.group(1), args


def atom_text(name: str, args: tuple[str, ...]) -> str:
    """The one spelling of a ground atom or action: ``PEGINHOLE(PEG,HOLE1)``, ``grasp(PEG)``."""
    return f"{name}({','.join(args)})" if args else name


# -- the file's shape ----------------------------------------------------------------------------
class FaceSpec(BaseModel):
    """A feature face: a rectangle ``centre ± u ± v`` (mm) in its individual's frame."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(min_length=1)
    centre: tuple[float, float, float]
    u: tuple[float, float, float]
    v: tuple[float, float, float]


class KindSpec(BaseModel):
    """The faces of one kind of individual. The hand has two sets, for the gripper open and
    closed; other kinds one (``faces``). ``groups`` name subsets (``f_h1``)."""

    model_config = ConfigDict(extra="forbid")
    faces: list[FaceSpec] = []
    faces_open: list[FaceSpec] = []
    faces_closed: list[FaceSpec] = []
    groups: dict[str, list[str]] = {}


class IndividualSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    kind: str = Field(min_length=1)
    object: str | None = None  # a movable object of the cell
    feature: str | None = None  # a feature of the cell


class PredicateSpec(BaseModel):
    """A predicate and its condition (Definition 3.26): every pair in ``present`` touches and no
    pair in ``absent`` does. A pair is two terms ``WHO:FACES``."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(min_length=1)
    params: dict[str, str] = {}  # variable -> kind, in argument order
    meaning: str = ""
    present: list[tuple[str, str]] = []
    absent: list[tuple[str, str]] = []


TEMPLATE_FIELD = re.compile(r"\{(\w+)((?:\s+\w+)+)\}")
"""A field of a rule's statements: ``{what VAR ...}``."""
TEMPLATE_FIELDS = ("obj", "feat", "above", "grip", "carry", "over")
"""What a field may ask for (``shared.tasknet.action_program``): the object's or the feature's
cell name, the approach over an object, the grip on it, the carry height over a feature, an
object held over a feature's mouth."""


class RuleSpec(BaseModel):
    """An F-rule: an action over typed variables with its PRE, DEL and ADD lists."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)
    name: str = Field(min_length=1)
    params: dict[str, str] = {}
    pre: list[str] = []
    delete: list[str] = Field(default=[], alias="del")
    add: list[str] = []
    statements: list[str] = []
    """The action's motion template (task-level commands): statement lines whose fields, such as
    ``{above p}`` or ``{over p h}``, are filled from the modelled poses of what the variables name
    (``shared.tasknet.action_program``)."""

    @field_validator("pre", "delete", "add")
    @classmethod
    def _atoms(cls, v: list[str]) -> list[str]:
        for text in v:
            parse_atom(text)
        return v

    @model_validator(mode="after")
    def _template_fields(self) -> "RuleSpec":
        for line in self.statements:
            for what, names in TEMPLATE_FIELD.findall(line):
                if what not in TEMPLATE_FIELDS:
                    raise ValueError(f"rule {self.name}: statement {line!r}: {{{what} ...}} is not one of "
                                     f"{', '.join(TEMPLATE_FIELDS)}")
                unknown = [n for n in names.split() if n not in self.params]
                if unknown:
                    raise ValueError(f"rule {self.name}: statement {line!r} names {', '.join(unknown)}, "
                                     f"not a variable of the rule ({', '.join(self.params) or 'none'})")
        return self


class TaskSpaceSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: str = Field(min_length=1)
    cell: str | None = None
    description: str = ""
    contact_tolerance_mm: float = Field(0.5, ge=0.0)
    kinds: dict[str, KindSpec]
    individuals: dict[str, IndividualSpec]
    predicates: list[PredicateSpec]
    rules: list[RuleSpec]


# -- the grounded task space ------------------------------------------------------------------------
@dataclass(frozen=True)
class GroundAtom:
    predicate: str
    args: tuple[str, ...]

    @property
    def text(self) -> str:
        return atom_text(self.predicate, self.args)


@dataclass(frozen=True)
class GroundAction:
    """A rule instance: ``rule(args)`` with the ground atoms it needs, removes and adds."""

    rule: str
    args: tuple[str, ...]
    pre: tuple[str, ...]
    delete: tuple[str, ...]
    add: tuple[str, ...]

    @property
    def text(self) -> str:
        return atom_text(self.rule, self.args)

    @property
    def post(self) -> tuple[str, ...]:
        """The atoms true after the action of those it touches: PRE - DEL + ADD, in order."""
        kept = [a for a in self.pre if a not in self.delete]
        return tuple(dict.fromkeys([*kept, *self.add]))


@dataclass(frozen=True)
class TaskSpace:
    """A task file grounded over its individuals: ``atoms`` are the places of the task space's
    net (in predicate order, then individual order) and ``actions`` its transitions (in rule
    order)."""

    spec: TaskSpaceSpec
    source: str
    atoms: tuple[GroundAtom, ...]
    actions: tuple[GroundAction, ...]

    @property
    def atom_texts(self) -> tuple[str, ...]:
        return tuple(a.text for a in self.atoms)

    def atom_index(self) -> dict[str, int]:
        return {a.text: i for i, a in enumerate(self.atoms)}

    def action(self, text: str) -> GroundAction:
        for a in self.actions:
            if a.text == text:
                return a
        raise InputError(f"the task space {self.spec.name!r} has no action {text!r}")

    def rule_order(self, action: GroundAction) -> int:
        return [r.name for r in self.spec.rules].index(action.rule)

    def net(self, marking: frozenset[str] = frozenset()) -> PTNet:
        """The grounded net: places named by their atoms, transitions by their actions; the
        marking given as the set of true atoms."""
        places = [Place(id=a.text, predicate=a.text, initial=1 if a.text in marking else 0) for a in self.atoms]
        transitions = [Transition(id=act.text, action=act.text) for act in self.actions]
        arcs = [Arc(source=p, target=act.text) for act in self.actions for p in act.pre]
        arcs += [Arc(source=act.text, target=p) for act in self.actions for p in act.post]
        return PTNet(id=self.spec.name, places=places, transitions=transitions, arcs=arcs)


def _bindings(params: dict[str, str], by_kind: dict[str, list[str]], where: str):
    """Every assignment of individuals to the typed variables ``params`` (distinct individuals
    for distinct variables)."""
    names = list(params)
    pools = []
    for var, kind in params.items():
        if kind not in by_kind:
            raise InputError(f"{where}: variable {var!r} is of kind {kind!r}, which no individual has")
        pools.append(by_kind[kind])
    for combo in itertools.product(*pools):
        if len(set(combo)) == len(combo):
            yield dict(zip(names, combo))


def _ground(text: str, binding: dict[str, str], individuals: dict[str, IndividualSpec], where: str) -> str:
    name, args = parse_atom(text)
    out = []
    for a in args:
        if a in binding:
            out.append(binding[a])
        elif a in individuals:
            out.append(a)
        else:
            raise InputError(f"{where}: {text!r} names {a!r}, neither a variable of the rule nor an individual")
    return atom_text(name, tuple(out))


def ground(spec: TaskSpaceSpec, source: str = "<task>") -> TaskSpace:
    """Unfold the rules over the individuals (checks names, kinds and arities on the way)."""
    by_kind: dict[str, list[str]] = {}
    for ind, s in spec.individuals.items():
        if s.kind not in spec.kinds:
            raise InputError(f"{source}: individual {ind!r} is of kind {s.kind!r}, which [kinds] does not define")
        by_kind.setdefault(s.kind, []).append(ind)
    atoms: list[GroundAtom] = []
    arity: dict[str, int] = {}
    for p in spec.predicates:
        if p.name in arity:
            raise InputError(f"{source}: predicate {p.name!r} is defined twice")
        arity[p.name] = len(p.params)
        for b in _bindings(p.params, by_kind, f"{source}: predicate {p.name}"):
            atoms.append(GroundAtom(p.name, tuple(b[v] for v in p.params)))
    known = {a.text for a in atoms}
    actions: list[GroundAction] = []
    for r in spec.rules:
        where = f"{source}: rule {r.name}"
        for lit in (*r.pre, *r.delete, *r.add):
            name, args = parse_atom(lit)
            if name not in arity:
                raise InputError(f"{where}: {lit!r} uses predicate {name!r}, which [[predicates]] does not define")
            if len(args) != arity[name]:
                raise InputError(f"{where}: {lit!r} gives {name} {len(args)} argument(s), it takes {arity[name]}")
        for lit in r.delete:
            if lit not in r.pre:
                raise InputError(f"{where}: DEL {lit!r} is not in PRE (a deleted literal must be a precondition)")
        for b in _bindings(r.params, by_kind, where):
            g = [tuple(_ground(t, b, spec.individuals, where) for t in lits) for lits in (r.pre, r.delete, r.add)]
            if not all(a in known for lits in g for a in lits):
                continue  # an atom whose individuals are not of the predicate's kinds: no such instance
            actions.append(GroundAction(r.name, tuple(b[v] for v in r.params), *g))
    if not actions:
        raise InputError(f"{source}: no rule has an instance over the individuals")
    return TaskSpace(spec, source, tuple(atoms), tuple(actions))


def load_task_space(path: str | Path) -> TaskSpace:
    """Read and ground a task file; a bad file is one clear error naming the file and the field."""
    p = Path(path)
    try:
        raw = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{p}: no such task file") from None
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(p, f"not valid TOML ({exc})") from None
    try:
        spec = TaskSpaceSpec.model_validate(raw)
    except ValidationError as exc:
        err = exc.errors()[0]
        where = ".".join(str(x) for x in err["loc"])
        raise FileFormatError(p, err["msg"], where) from None
    return ground(spec, str(p))


def task_file_for_cell(cell_name: str) -> Path | None:
    """The task file shipped for a cell (``assets/tasks/<cell>.toml``), or None."""
    from shared.paths import ASSETS_DIR

    path = ASSETS_DIR / "tasks" / f"{cell_name}.toml"
    return path if path.is_file() else None


def marking_vector(space: TaskSpace, true_atoms: frozenset[str] | set[str]) -> np.ndarray:
    """The marking (one entry per atom, 0 or 1) of a set of true atoms."""
    return np.array([1 if a in true_atoms else 0 for a in space.atom_texts], dtype=np.int64)
