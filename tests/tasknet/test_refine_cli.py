"""``teleprog net refine`` as a person runs it: the §3.4.3 hole search from its data files."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

from shared.tasknet.jsonform import load_net

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "assets" / "tasks" / "hole_search.toml"


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "server.cli", "net", "refine", *args],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)


def test_the_hole_search_refines_t1_and_keeps_the_properties(tmp_path):
    out_net = tmp_path / "refined.pnml"
    out = run(str(SPEC), "--json", "--save", str(out_net))
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["ok"] is True and data["error"] is None
    (step,) = data["steps"]
    assert step["transition"] == "t1"
    assert [c["holds"] for c in step["check"]["conditions"]] == [True, True, True]
    assert step["preservation"]["quotient"] is True
    assert {p["name"]: p["preserved"] for p in step["preservation"]["properties"]} == {
        "bounded": True, "safe": True, "live": True}
    refined = data["refined"]
    assert "t1" not in refined["transition_ids"]
    assert all(t.startswith("t1.") for t in refined["transition_ids"] if t not in ("t2", "t3"))
    assert refined["bounded"] and refined["safe"] and refined["live"]
    saved = load_net(out_net)
    assert sorted(p.id for p in saved.places) == sorted(refined["place_ids"])
    assert len(saved.transitions) == refined["transitions"]


def test_the_text_report_names_each_condition():
    out = run(str(SPEC))
    assert out.returncode == 0, out.stderr
    for cond in ("(i): holds", "(ii): holds", "(iii): holds"):
        assert cond in out.stdout
    assert "live: upper True, refined True: preserved" in out.stdout


def test_a_subnet_that_breaks_condition_ii_is_refused_with_the_reason(tmp_path):
    for f in ("hole_search.toml", "peg_in_hole.pnml"):
        shutil.copy(ROOT / "assets" / "tasks" / f, tmp_path / f)
    text = (ROOT / "assets" / "tasks" / "hole_search.pnml").read_text()
    # A second initial token, on the inner place s2: the subnet no longer starts like t1 does.
    text = text.replace('<place id="s2">', '<place id="s2">\n<initialMarking><text>1</text></initialMarking>', 1)
    (tmp_path / "hole_search.pnml").write_text(text)
    out = run(str(tmp_path / "hole_search.toml"), "--json", "--save", str(tmp_path / "never.pnml"))
    assert out.returncode == 1
    data = json.loads(out.stdout)
    assert data["ok"] is False and data["refined"] is None
    conds = {c["condition"]: c["holds"] for c in data["steps"][0]["check"]["conditions"]}
    assert conds["ii"] is False
    assert "condition ii fails" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "never.pnml").exists()


def test_a_missing_spec_is_one_line_on_stderr(tmp_path):
    out = run(str(tmp_path / "nope.toml"))
    assert out.returncode != 0
    assert "nope.toml" in out.stderr and "Traceback" not in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1
