"""A net's numbers are bounded (issue 36): a marking, capacity or weight of 10**40 (which raised
OverflowError on the way into int64 arrays) is refused in one line naming the file and the field,
in the JSON form, in PNML and on the command line; the bound itself is taken."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from shared.errors import FileFormatError, InputError
from shared.tasknet.jsonform import load_net, net_from_json
from shared.tasknet.pnml import PTNET_TYPE
from shared.tasknet.ptnet import MAX_TOKENS

ROOT = Path(__file__).resolve().parents[2]
HUGE = 10**40


def json_net(initial: int = 1, weight: int = 1, capacity: int | None = None) -> str:
    place = {"id": "p", "initial": initial} | ({"capacity": capacity} if capacity is not None else {})
    return json.dumps({"id": "n", "places": [place, {"id": "q"}], "transitions": [{"id": "t"}],
                       "arcs": [{"source": "p", "target": "t", "weight": weight}, {"source": "t", "target": "q"}]})


def pnml_net(initial: str = "1", inscription: str = "1", capacity: str | None = None) -> str:
    tool = (f'<toolspecific tool="teleprog" version="1"><info capacity="{capacity}"/></toolspecific>'
            if capacity is not None else "")
    return (f'<pnml><net id="n" type="{PTNET_TYPE}"><page id="g">'
            f'<place id="p"><initialMarking><text>{initial}</text></initialMarking>{tool}</place>'
            '<place id="q"/><transition id="t"/>'
            f'<arc id="a" source="p" target="t"><inscription><text>{inscription}</text></inscription></arc>'
            '<arc id="b" source="t" target="q"/></page></net></pnml>')


@pytest.mark.parametrize("fields, where", [
    ({"initial": HUGE}, "places.0.initial"),
    ({"weight": HUGE}, "arcs.0.weight"),
    ({"capacity": HUGE, "initial": 1}, "places.0.capacity"),
    ({"initial": MAX_TOKENS + 1}, "places.0.initial"),
])
def test_a_json_net_with_a_number_past_the_bound_names_the_field(fields: dict, where: str) -> None:
    with pytest.raises(FileFormatError, match=rf"^net\.json: {where}: .*{MAX_TOKENS}"):
        net_from_json(json_net(**fields), "net.json")


def test_a_json_net_with_a_number_of_thousands_of_digits_is_refused_in_one_line() -> None:
    text = json_net().replace('"initial": 1', '"initial": ' + "9" * 5000)
    with pytest.raises(FileFormatError, match=r"^net\.json: not a net: a number has too many digits$"):
        net_from_json(text, "net.json")


@pytest.mark.parametrize("fields, says", [
    ({"initial": str(HUGE)}, "initialMarking 1000000000000000000000000000000000000000"),
    ({"inscription": str(HUGE)}, "inscription 1000000000000000000000000000000000000000"),
    ({"capacity": str(HUGE)}, "capacity 1000000000000000000000000000000000000000"),
    ({"initial": "9" * 100_000}, "initialMarking 9999"),
])
def test_a_pnml_net_with_a_number_past_the_bound_names_the_element(tmp_path: Path, fields: dict, says: str) -> None:
    path = tmp_path / "net.pnml"
    path.write_text(pnml_net(**fields))
    with pytest.raises(FileFormatError, match=r"net\.pnml: <(place|arc) id='(p|a)'>: ") as exc:
        load_net(path)
    assert says in str(exc.value) and f"above the bound of {MAX_TOKENS} tokens" in str(exc.value)
    assert len(str(exc.value)) < 300  # a long number is not echoed whole


def test_the_bound_itself_is_a_net_and_fires_exactly() -> None:
    net = net_from_json(json_net(initial=MAX_TOKENS, weight=MAX_TOKENS, capacity=MAX_TOKENS))
    after = net.fire(net.m0, "t")
    assert net.marking_dict(after) == {"q": 1}


def test_a_marking_given_by_place_is_bounded_too() -> None:
    net = net_from_json(json_net())
    with pytest.raises(InputError, match=f"at most {MAX_TOKENS} tokens"):
        net.marking({"p": HUGE})
    assert net.marking({"p": MAX_TOKENS}).tolist() == [MAX_TOKENS, 0]


@pytest.mark.parametrize("suffix, text", [(".json", json_net(initial=HUGE)), (".pnml", pnml_net(inscription=str(HUGE)))])
def test_teleprog_net_refuses_a_huge_number_in_one_line(tmp_path: Path, suffix: str, text: str) -> None:
    path = tmp_path / f"huge{suffix}"
    path.write_text(text)
    for command in ("check", "show"):
        out = subprocess.run([sys.executable, "-m", "server.cli", "net", command, str(path)], capture_output=True,
                             text=True, timeout=120, cwd=ROOT)
        assert out.returncode == 1 and "OverflowError" not in out.stderr
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"teleprog: error: {path}: ") and str(MAX_TOKENS) in lines[0], out.stderr
