"""PNML (ISO/IEC 15909-2) for place/transition nets: read and write the P/T subset.

Written: one ``<net>`` of type ``http://www.pnml.org/version-2009/grammar/ptnet`` with one
page; places with ``name`` and ``initialMarking``, transitions with ``name``, arcs with an
``inscription`` (the weight, written when it is not 1) and, where a layout is given,
``graphics/position``. What the standard P/T grammar has no element for (a place's predicate
and capacity, a transition's action) goes into ``<toolspecific tool="teleprog"><info .../>``, which other
tools keep or ignore.

Read: the first net of the file, every page and nested page flattened; the PNML namespace may
be absent. ``referencePlace``/``referenceTransition`` nodes are refused with a clear message.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from pydantic import ValidationError

from shared.errors import FileFormatError
from shared.tasknet.ptnet import MAX_TOKENS, Arc, Place, PTNet, Transition

PNML_NS = "http://www.pnml.org/version-2009/grammar/pnml"
PTNET_TYPE = "http://www.pnml.org/version-2009/grammar/ptnet"
TOOL = "teleprog"
TOOL_VERSION = "1"


# -- writing -------------------------------------------------------------------------------


def net_to_pnml(net: PTNet, positions: dict[str, tuple[float, float]] | None = None) -> str:
    """The PNML document of ``net``; ``positions`` (node id to x, y in PNML units) adds graphics."""
    ET.register_namespace("", PNML_NS)

    def q(tag: str) -> str:
        return f"{{{PNML_NS}}}{tag}"

    root = ET.Element(q("pnml"))
    enet = ET.SubElement(root, q("net"), id=net.id, type=PTNET_TYPE)
    if net.name:
        _text(ET.SubElement(enet, q("name")), q, net.name)
    page = ET.SubElement(enet, q("page"), id=f"{net.id}-page")

    def graphics(node: ET.Element, nid: str) -> None:
        if positions and nid in positions:
            x, y = positions[nid]
            ET.SubElement(ET.SubElement(node, q("graphics")), q("position"), x=f"{x:g}", y=f"{y:g}")

    for p in net.places:
        ep = ET.SubElement(page, q("place"), id=p.id)
        if p.name:
            _text(ET.SubElement(ep, q("name")), q, p.name)
        graphics(ep, p.id)
        if p.initial:
            _text(ET.SubElement(ep, q("initialMarking")), q, str(p.initial))
        extra = {k: str(v) for k, v in (("predicate", p.predicate), ("capacity", p.capacity)) if v is not None}
        if extra:
            ET.SubElement(ET.SubElement(ep, q("toolspecific"), tool=TOOL, version=TOOL_VERSION), q("info"), extra)
    for t in net.transitions:
        et = ET.SubElement(page, q("transition"), id=t.id)
        if t.name:
            _text(ET.SubElement(et, q("name")), q, t.name)
        graphics(et, t.id)
        if t.action is not None:
            ET.SubElement(
                ET.SubElement(et, q("toolspecific"), tool=TOOL, version=TOOL_VERSION), q("info"), action=t.action
            )
    for k, a in enumerate(net.arcs):
        ea = ET.SubElement(page, q("arc"), id=f"a{k}-{a.source}-{a.target}", source=a.source, target=a.target)
        if a.weight != 1:
            _text(ET.SubElement(ea, q("inscription")), q, str(a.weight))
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def write_pnml(net: PTNet, path: str | Path, positions: dict[str, tuple[float, float]] | None = None) -> None:
    Path(path).write_text(net_to_pnml(net, positions), encoding="utf-8")


def _text(parent: ET.Element, q, value: str) -> None:
    ET.SubElement(parent, q("text")).text = value


# -- reading -------------------------------------------------------------------------------


def read_pnml(path: str | Path) -> PTNet:
    """The first P/T net of a PNML file; FileFormatError naming the file and the element."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FileFormatError(path, f"cannot read: {exc.strerror or exc}") from None
    return pnml_to_net(data, path)


def pnml_to_net(data: bytes | str, path: str | Path = "<pnml>") -> PTNet:
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        line, col = exc.position
        raise FileFormatError(path, f"not well-formed XML at line {line}, column {col + 1}") from None
    for el in root.iter():
        if isinstance(el.tag, str) and "}" in el.tag:
            el.tag = el.tag.split("}", 1)[1]
    if root.tag != "pnml":
        raise FileFormatError(path, f"the root element is <{root.tag}>, not <pnml>")
    enet = root.find("net")
    if enet is None:
        raise FileFormatError(path, "no <net> element under <pnml>")
    net_id = enet.get("id")
    if not net_id:
        raise FileFormatError(path, "the <net> element has no id attribute")
    net_type = enet.get("type")
    if net_type is None:
        raise FileFormatError(path, f"<net id={net_id!r}> has no type attribute; expected {PTNET_TYPE}")
    if net_type.rstrip("#") != PTNET_TYPE:
        raise FileFormatError(path, f"<net id={net_id!r}> is of type {net_type!r}; only P/T nets ({PTNET_TYPE}) are read")

    places: list[Place] = []
    transitions: list[Transition] = []
    arcs: list[Arc] = []
    pages = enet.findall("page")
    if not pages:
        raise FileFormatError(path, f"<net id={net_id!r}> has no <page> element")
    nodes: list[ET.Element] = []
    while pages:  # pages nest; their places, transitions and arcs are direct children
        page = pages.pop(0)
        pages[:0] = page.findall("page")
        nodes += [el for el in page if el.tag in _NODE_TAGS]
    for k, el in enumerate(nodes):
        eid = el.get("id")
        where = f"<{el.tag} id={eid!r}>" if eid else f"<{el.tag}> #{k + 1} of the page"
        if el.tag.startswith("reference"):
            raise FileFormatError(path, "reference nodes (modular PNML) are not supported", field=where)
        if not eid:
            raise FileFormatError(path, "missing id attribute", field=where)
        if el.tag == "place":
            tool = _tool(el)
            initial = _int_text(path, where, el.find("initialMarking"), "initialMarking", default=0, minimum=0)
            capacity = _int_attr(path, where, tool, "capacity", minimum=1)
            places.append(
                Place(id=eid, name=_name(el), predicate=tool.get("predicate") if tool is not None else None,
                      initial=initial, capacity=capacity)
            )
        elif el.tag == "transition":
            tool = _tool(el)
            transitions.append(Transition(id=eid, name=_name(el), action=tool.get("action") if tool is not None else None))
        else:
            src, tgt = el.get("source"), el.get("target")
            if not src or not tgt:
                raise FileFormatError(path, "an arc needs source and target attributes", field=where)
            weight = _int_text(path, where, el.find("inscription"), "inscription", default=1, minimum=1)
            arcs.append(Arc(source=src, target=tgt, weight=weight))
    name = _name(enet)
    try:
        return PTNet(id=net_id, name=name, places=tuple(places), transitions=tuple(transitions), arcs=tuple(arcs))
    except ValidationError as exc:
        first = exc.errors()[0]
        raise FileFormatError(path, str(first["msg"]).removeprefix("Value error, "), field=f"<net id={net_id!r}>") from None


_NODE_TAGS = ("place", "transition", "arc", "referencePlace", "referenceTransition")


def _name(el: ET.Element) -> str | None:
    text = el.find("name/text")
    return text.text.strip() if text is not None and text.text else None


def _tool(el: ET.Element) -> ET.Element | None:
    """The ``<info>`` this tool wrote under a node (predicate, capacity, action), if any."""
    for ts in el.findall("toolspecific"):
        if ts.get("tool") == TOOL:
            return ts.find("info")
    return None


def _int_text(path, where: str, label: ET.Element | None, what: str, default: int, minimum: int) -> int:
    if label is None:
        return default
    text = label.find("text")
    if text is None or text.text is None or not text.text.strip():
        raise FileFormatError(path, f"<{what}> has no <text> value", field=where)
    return _parse_int(path, where, what, text.text.strip(), minimum)


def _int_attr(path, where: str, el: ET.Element | None, what: str, minimum: int) -> int | None:
    if el is None or el.get(what) is None:
        return None
    return _parse_int(path, where, what, el.get(what), minimum)


def _parse_int(path, where: str, what: str, raw: str, minimum: int) -> int:
    shown = raw if len(raw) <= 40 else raw[:40] + "..."
    digits = raw.strip().removeprefix("+").lstrip("0")
    if digits.isascii() and digits.isdigit() and len(digits) > 18:
        value: int | None = MAX_TOKENS + 1  # beyond the bound, without converting a long digit string
    else:
        try:
            value = int(raw)
        except ValueError:
            value = None
    if value is None or value < minimum:
        kind = "a positive integer" if minimum >= 1 else "a non-negative integer"
        raise FileFormatError(path, f"{what} must be {kind}; got {shown!r}", field=where)
    if value > MAX_TOKENS:
        raise FileFormatError(path, f"{what} {shown} is above the bound of {MAX_TOKENS} tokens", field=where)
    return value
