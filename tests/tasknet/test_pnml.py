"""PNML and JSON forms of a net: round trips, files other tools write, and bad files."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from hypothesis import given, settings
from tasknet_nets import small_nets

from shared.errors import FileFormatError
from shared.tasknet.jsonform import load_net, net_from_json, net_to_json, save_net
from shared.tasknet.layout import layered_positions, net_to_svg
from shared.tasknet.pnml import PNML_NS, PTNET_TYPE, net_to_pnml, pnml_to_net

ROOT = Path(__file__).resolve().parents[2]
ASSETS = sorted((ROOT / "assets" / "tasks").glob("*.pnml"))


@settings(max_examples=40, deadline=None)
@given(net=small_nets(capacities=True))
def test_nets_round_trip_through_pnml_and_json(net):
    assert pnml_to_net(net_to_pnml(net, layered_positions(net))) == net
    assert net_from_json(net_to_json(net)) == net


@pytest.mark.parametrize("path", ASSETS, ids=lambda p: p.name)
def test_the_example_nets_round_trip_through_files(path, tmp_path):
    net = load_net(path)
    assert net.places and net.transitions
    for suffix in (".pnml", ".json"):
        save_net(net, tmp_path / f"copy{suffix}")
        assert load_net(tmp_path / f"copy{suffix}") == net


def test_written_pnml_is_a_standard_pt_net():
    net = load_net(ROOT / "assets" / "tasks" / "producer_consumer.pnml")
    root = ET.fromstring(net_to_pnml(net))
    ns = {"p": PNML_NS}
    assert root.tag == f"{{{PNML_NS}}}pnml"
    assert root.find("p:net", ns).get("type") == PTNET_TYPE
    # what P/T PNML has no element for stays inside toolspecific, never as extra place elements
    assert len(list(root.iter(f"{{{PNML_NS}}}place"))) == len(net.places)
    assert root.find(".//p:place[@id='buffer']/p:toolspecific/p:info", ns).get("capacity") == "3"
    weights = [a.find("p:inscription/p:text", ns).text for a in root.iter(f"{{{PNML_NS}}}arc") if a.find("p:inscription", ns) is not None]
    assert weights == ["2"]
    marked = {pl.get("id"): pl.find("p:initialMarking/p:text", ns).text for pl in root.iter(f"{{{PNML_NS}}}place") if pl.find("p:initialMarking", ns) is not None}
    assert marked == {"ready_to_produce": "1", "ready_to_take": "1"}


def test_a_file_without_namespace_and_with_nested_pages_reads():
    text = f"""<pnml><net id="n" type="{PTNET_TYPE}"><name><text>two pages</text></name>
      <page id="top"><place id="a"><initialMarking><text> 2 </text></initialMarking></place>
        <page id="inner"><transition id="t"/><arc id="x" source="a" target="t"><inscription><text>2</text></inscription></arc></page>
      </page></net></pnml>"""
    net = pnml_to_net(text)
    assert net.name == "two pages" and net.m0.tolist() == [2] and net.pre.tolist() == [[2]]


BAD = {
    "not xml": ("<pnml><net>", r"bad\.pnml: not well-formed XML at line 1"),
    "no net": ("<pnml/>", r"bad\.pnml: no <net> element"),
    "coloured net": (
        '<pnml><net id="n" type="http://www.pnml.org/version-2009/grammar/symmetricnet"><page id="g"/></net></pnml>',
        r"only P/T nets",
    ),
    "place without id": (
        f'<pnml><net id="n" type="{PTNET_TYPE}"><page id="g"><place/></page></net></pnml>',
        r"bad\.pnml: <place> #1 of the page: missing id attribute",
    ),
    "bad marking": (
        f'<pnml><net id="n" type="{PTNET_TYPE}"><page id="g"><place id="p"><initialMarking><text>two</text></initialMarking></place></page></net></pnml>',
        r"bad\.pnml: <place id='p'>: initialMarking must be a non-negative integer; got 'two'",
    ),
    "zero weight": (
        f'<pnml><net id="n" type="{PTNET_TYPE}"><page id="g"><place id="p"/><transition id="t"/>'
        '<arc id="a" source="p" target="t"><inscription><text>0</text></inscription></arc></page></net></pnml>',
        r"<arc id='a'>: inscription must be a positive integer; got '0'",
    ),
    "dangling arc": (
        f'<pnml><net id="n" type="{PTNET_TYPE}"><page id="g"><place id="p"/><arc id="a" source="p" target="nowhere"/></page></net></pnml>',
        r"bad\.pnml: <net id='n'>: arc p->nowhere: 'nowhere' is not a place or transition",
    ),
}


@pytest.mark.parametrize("case", BAD, ids=list(BAD))
def test_a_bad_pnml_file_names_the_file_and_the_element(case, tmp_path):
    text, message = BAD[case]
    path = tmp_path / "bad.pnml"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=message):
        load_net(path)


def test_a_bad_json_net_names_the_field(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text('{"places": [{"id": "p", "initial": -1}], "transitions": []}')
    with pytest.raises(FileFormatError, match=r"bad\.json: places\.0\.initial: "):
        load_net(path)
    with pytest.raises(FileFormatError, match="unknown net file suffix '.txt'"):
        load_net(tmp_path / "net.txt")


def test_the_svg_draws_every_place_with_its_tokens_and_every_transition():
    net = load_net(ROOT / "assets" / "tasks" / "peg_transfer_ce.pnml")
    svg = ET.fromstring(net_to_svg(net))
    ns = "{http://www.w3.org/2000/svg}"
    groups = {g.get("data-id"): g for g in svg.iter(f"{ns}g")}
    tokens = {pid: groups[pid].get("data-tokens") for pid in net.place_index}
    assert tokens == {"P1": "1", "P2": "1", "P3": "0", "P4": "1", "P5": "0", "P6": "1", "P7": "0"}
    assert all(groups[t].get("class") == "transition" for t in net.transition_index)
    assert len([p for p in svg.iter(f"{ns}path") if p.get("class") == "arc"]) == len(net.arcs)
