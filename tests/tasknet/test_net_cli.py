"""``teleprog net check`` and ``teleprog net show`` as a person runs them: a real process."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PEG = ROOT / "assets" / "tasks" / "peg_transfer_ce.pnml"
PC = ROOT / "assets" / "tasks" / "producer_consumer.pnml"


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "server.cli", "net", *args], capture_output=True, text=True, timeout=120, cwd=ROOT
    )


def test_check_json_reports_the_properties_of_the_peg_transfer_net():
    out = run("check", str(PEG), "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["net"] == "peg_transfer"
    assert (data["places"], data["transitions"]) == (7, 4)
    assert data["reachable_markings"] == 9 and data["reachability_complete"] is True
    assert data["bounded"] is True and data["safe"] is True
    assert data["bounds"] == {f"P{i}": 1 for i in range(1, 8)}
    assert data["deadlock_free"] is False and {"P1": 1, "P5": 1, "P7": 1} in data["dead_markings"]
    assert data["live"] is False and set(data["live_transitions"]) == {"T1", "T2", "T3", "T4"}


def test_check_of_a_weighted_net_with_a_capacity():
    data = json.loads(run("check", str(PC), "--json").stdout)
    assert data["bounds"]["buffer"] == 3 and data["safe"] is False
    assert data["live"] is True and data["deadlock_free"] is True and data["dead_markings"] == []


def test_check_past_the_bound_falls_back_to_coverability(tmp_path):
    net = {
        "id": "generator",
        "places": [{"id": "p", "initial": 1}, {"id": "q"}],
        "transitions": [{"id": "t"}],
        "arcs": [{"source": "p", "target": "t"}, {"source": "t", "target": "p"}, {"source": "t", "target": "q"}],
    }
    path = tmp_path / "generator.json"
    path.write_text(json.dumps(net))
    data = json.loads(run("check", str(path), "--json", "--bound", "20").stdout)
    assert data["reachability_complete"] is False and data["reachable_markings"] == 20 and data["states_cap"] == 20
    assert data["bounded"] is False and data["bounds"] == {"p": 1, "q": None}
    assert data["live"] is None and data["deadlock_free"] is None
    text = run("check", str(path), "--bound", "20").stdout
    assert "more than 20" in text and "q omega" in text


def test_show_writes_an_svg_and_lists_the_net(tmp_path):
    out = run("show", str(PEG), "--svg", str(tmp_path / "peg.svg"))
    assert out.returncode == 0, out.stderr
    svg = ET.parse(tmp_path / "peg.svg").getroot()
    assert svg.tag == "{http://www.w3.org/2000/svg}svg"
    listing = run("show", str(PEG)).stdout
    assert "T3 part(PEG,HOLE1): {P3, P4} -> {P3, P5}" in listing
    assert "take: {buffer*2, ready_to_take} -> {ready_to_consume}" in run("show", str(PC)).stdout


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["check", "missing.pnml"], "missing.pnml: cannot read"),
        (["check", "README.md"], "unknown net file suffix '.md'"),
        (["check", "BAD"], "initialMarking must be a non-negative integer"),
        (["check", str(PEG), "--bound", "0"], "--bound must be at least 1"),
        (["show", str(PEG), "--svg", "/nonexistent-dir/x.svg"], "cannot write the picture"),
    ],
)
def test_errors_are_one_line_on_stderr(args, message, tmp_path):
    if "BAD" in args:
        bad = tmp_path / "bad.pnml"
        bad.write_text(
            '<pnml><net id="n" type="http://www.pnml.org/version-2009/grammar/ptnet"><page id="g">'
            '<place id="p"><initialMarking><text>-1</text></initialMarking></place></page></net></pnml>'
        )
        args = [str(bad) if a == "BAD" else a for a in args]
    out = run(*args)
    assert out.returncode == 1
    assert out.stdout == ""
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("teleprog: error: ") and message in lines[0], out.stderr
