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


def test_show_writes_a_png_of_the_net_with_its_initial_marking(tmp_path):
    import numpy as np
    from PIL import Image

    from shared.tasknet.layout import arc_geometry, layered_positions
    from shared.tasknet.pnml import read_pnml
    from shared.tasknet.raster import MARKED, WHITE

    out = run("show", str(PEG), "--png", str(tmp_path / "peg.png"), "--svg", str(tmp_path / "peg.svg"))
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["wrote", str(tmp_path / "peg.svg"), "wrote", str(tmp_path / "peg.png")]
    data = (tmp_path / "peg.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    image = Image.open(tmp_path / "peg.png").convert("RGB")
    svg = ET.parse(tmp_path / "peg.svg").getroot()
    # the same canvas as the SVG, 1.5 pixels a unit
    assert image.size == (round(1.5 * float(svg.get("width"))), round(1.5 * float(svg.get("height"))))
    net = read_pnml(PEG)
    pos = layered_positions(net)
    # every place is drawn where the layout puts it: shaded when M0 marks it, white when not;
    # a pixel a little off the centre, clear of the token count
    for p in net.places:
        x, y = pos[p.id]
        colour = image.getpixel((round(1.5 * (x + 10)), round(1.5 * y)))
        assert colour == (MARKED if p.initial else WHITE), (p.id, colour)
    # transitions are solid bars
    for t in net.transitions:
        x, y = pos[t.id]
        assert image.getpixel((round(1.5 * x), round(1.5 * y))) == (51, 51, 51), t.id
    # every arc is drawn: ink at its curve's midpoint (or a pixel beside it)
    pixels = np.asarray(image)
    for g in arc_geometry(net, pos):
        mx, my = g.points()[8]
        near = pixels[round(1.5 * my) - 1:round(1.5 * my) + 2, round(1.5 * mx) - 1:round(1.5 * mx) + 2]
        assert (near != WHITE).any(), (g.arc.source, g.arc.target)


def test_png_shows_the_marking_it_is_given():
    import io

    import numpy as np
    from PIL import Image

    from shared.tasknet.layout import layered_positions
    from shared.tasknet.pnml import read_pnml
    from shared.tasknet.raster import MARKED, WHITE, net_to_png

    net = read_pnml(PEG)
    after = net.fire(net.m0, net.transitions[0].id)
    image = Image.open(io.BytesIO(net_to_png(net, after, scale=1.0))).convert("RGB")
    pos = layered_positions(net)
    for i, p in enumerate(net.places):
        x, y = pos[p.id]
        assert image.getpixel((round(x + 10), round(y))) == (MARKED if after[i] else WHITE), p.id
    assert not np.array_equal(after, net.m0)
    with pytest.raises(ValueError, match="scale must be positive"):
        net_to_png(net, scale=0)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["check", "missing.pnml"], "missing.pnml: cannot read"),
        (["check", "README.md"], "unknown net file suffix '.md'"),
        (["check", "BAD"], "initialMarking must be a non-negative integer"),
        (["check", str(PEG), "--bound", "0"], "--bound must be at least 1"),
        (["show", str(PEG), "--svg", "/nonexistent-dir/x.svg"], "cannot write the picture"),
        (["show", str(PEG), "--png", "/nonexistent-dir/x.png"], "/nonexistent-dir/x.png: cannot write the picture"),
        (["show", str(PEG), "--png", "-"], "a PNG cannot go to the terminal"),
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
