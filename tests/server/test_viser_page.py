"""The page the console serves: viser's packed client decoded, the gizmo's send interval changed,
packed again (``server.viser_page``), checked on the installed viser's own page."""

from __future__ import annotations

import gzip
import json
import logging
import os
import re

import pytest

from server.viser_host import CLIENT_BUILD_DIR
from server.viser_page import (
    BASE88_ALPHABET,
    PageBundle,
    PagePatchError,
    decode_base88,
    encode_base88,
    paced_page,
    pack,
    read_send_intervals_ms,
    served_page,
    unpack,
    with_number_commit,
    with_page_scripts,
)


@pytest.fixture(scope="module")
def viser_html() -> str:
    return (CLIENT_BUILD_DIR / "index.html").read_text("utf-8")


def test_base88_matches_the_loaders_alphabet_and_data(viser_html: str) -> None:
    # the loader script in viser's page spells its alphabet out, and carries a gzipped WASM
    # decoder in base-88 written by viser's own encoder (its length leaves a short last group)
    loader_alphabet = json.loads(re.search(r"const A=(\"(?:[^\"\\\\]|\\\\.)*\")", viser_html).group(1))
    assert loader_alphabet == BASE88_ALPHABET
    wasm_text = json.loads(re.search(r"const gzWasm=(\"[^\"]*\")", viser_html).group(1))
    assert len(wasm_text) % 5 != 0
    assert gzip.decompress(decode_base88(wasm_text))[:4] == b"\x00asm"
    assert encode_base88(decode_base88(wasm_text)) == wasm_text


def test_base88_matches_the_loaders_arithmetic() -> None:
    assert len(BASE88_ALPHABET) == 88 and not set("\"&<>'`") & set(BASE88_ALPHABET)
    assert encode_base88(b"\x00\x00\x00\x00") == "!!!!!"
    # 0xFFFFFFFF = 4294967295: its five base-88 digits, most significant first
    value, digits = 0xFFFFFFFF, []
    for _ in range(5):
        value, d = divmod(value, 88)
        digits.append(BASE88_ALPHABET[d])
    assert encode_base88(b"\xff" * 4) == "".join(reversed(digits))
    # a last group of k bytes takes k + 1 digits
    assert [len(encode_base88(bytes(n))) for n in range(1, 9)] == [2, 3, 4, 5, 7, 8, 9, 10]


@pytest.mark.parametrize("size", [0, 1, 2, 3, 4, 5, 7, 8, 1001])
def test_base88_round_trip(size: int) -> None:
    data = os.urandom(size)
    assert decode_base88(encode_base88(data)) == data


def test_bad_base88_text_is_refused() -> None:
    with pytest.raises(PagePatchError, match="not in the base-88 alphabet"):
        decode_base88("!!!!<")
    with pytest.raises(PagePatchError, match="group of one digit"):
        decode_base88("!!!!!!")
    with pytest.raises(PagePatchError, match="not in the base-88 alphabet"):
        decode_base88("!!!\u00e9!")
    largest = BASE88_ALPHABET[-1]
    with pytest.raises(PagePatchError, match="more than 4 bytes"):
        decode_base88(largest * 5)
    with pytest.raises(PagePatchError, match="more than 1 bytes"):
        decode_base88(largest * 2)


def test_viser_page_unpacks_and_packs_back(viser_html: str) -> None:
    bundle = unpack(viser_html)
    assert "TransformControlsMessage" in bundle.script and bundle.style.strip()
    assert unpack(pack(viser_html, bundle)) == bundle
    assert read_send_intervals_ms(viser_html) == {"gizmo": 50}  # viser 1.1.1's own


def test_paced_page_changes_only_the_gizmo_interval(viser_html: str) -> None:
    paced = paced_page(viser_html, {"gizmo": 10})
    assert read_send_intervals_ms(paced) == {"gizmo": 10}
    before, after = unpack(viser_html), unpack(paced)
    assert after.style == before.style
    # the scripts differ in one place: that sender's interval, just after its anchor
    a, b = before.script, after.script
    start = next(i for i, (x, y) in enumerate(zip(a, b, strict=False)) if x != y)
    assert (a[start : start + 2], b[start : start + 2]) == ("50", "10") and a[start + 2 :] == b[start + 2 :]
    assert a.rfind("case`TransformControlsMessage`", 0, start) > start - 80
    # the page around the packed frame (the loader, the decoder) is untouched
    head, tail = viser_html.split('data-p="', 1)[0], viser_html.rsplit('data-cs="', 1)[1].split('"', 1)[1]
    assert paced.startswith(head) and paced.endswith(tail)


def test_bad_intervals_and_foreign_pages_are_refused(viser_html: str, caplog) -> None:
    with pytest.raises(ValueError, match="1-1000 ms"):
        paced_page(viser_html, {"gizmo": 0})
    with pytest.raises(ValueError, match="no sender named 'camera'"):
        paced_page(viser_html, {"camera": 10})
    bundle = unpack(viser_html)
    no_gizmo = pack(viser_html, PageBundle(bundle.style, bundle.script.replace("TransformControlsMessage", "Renamed")))
    with pytest.raises(PagePatchError, match="one gizmo sender in the page's script, found 0"):
        paced_page(no_gizmo, {"gizmo": 10})
    with caplog.at_level(logging.WARNING, logger="server.viser_page"):
        assert served_page(no_gizmo, {"gizmo": 10}) == with_page_scripts(no_gizmo)
    assert "viser's own 20 updates a second" in caplog.text
    assert served_page(viser_html, {}) == with_page_scripts(viser_html)
    with pytest.raises(PagePatchError, match="data-p"):
        unpack("<html></html>")


def test_served_page_runs_the_number_commit_script_before_viser(viser_html: str) -> None:
    served = served_page(viser_html, {"gizmo": 10})
    gate, loader = served.index('data-teleprog="number-commit"'), served.index('data-p="')
    assert gate < loader  # its listeners are on window before React's root listens
    assert gate < served.index('data-teleprog="program-keys"') < loader
    assert read_send_intervals_ms(served) == {"gizmo": 10}
    with pytest.raises(PagePatchError, match="<head>"):
        with_number_commit("<html><body></body></html>")
