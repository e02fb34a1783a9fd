"""The 3D page the console serves: viser's built client, with the transform gizmo's drag updates
sent at the console's rate instead of viser's fixed 20 per second.

viser 1.1.1's client sends a gizmo's drag updates through a message sender throttled to 50 ms
(``makeThrottledMessageSender(viewer, 50)`` in ``client/src/SceneTree.tsx``): whatever the
console and the GPU, the virtual arm could follow a drag at most 20 times a second, and a mouse
move waited up to 50 ms in the page before the console heard of it. The console answers a gizmo
event in about 1.2 ms (``benchmarks/bench_console.py``), so the page may send one per drawn frame.
(GUI inputs such as the joint sliders go through another 50 ms sender, left as viser builds it:
in this environment a slider drag reaches the console 4-5 times a second with either interval.)

viser ships its client as one ``index.html`` (``client/vite-plugin-compress-html.mts``): the
inline style and module script are one zstd frame, written into the loader script's ``data-p``
attribute in a base-88 alphabet, with ``data-ss`` and ``data-cs`` giving the style's and the
script's decompressed sizes. :func:`paced_page` decodes the frame, changes the interval
literal of each named sender (``SENDERS``: the gizmo's, in its case of the scene-node factory)
and encodes the page again; the loader and everything else are untouched. If an interval is not
found exactly once (another viser build), :func:`served_page` logs a warning and serves the page
unpaced.

Number boxes commit on Enter or on leaving the box, never per keystroke. viser's number inputs
(``add_number``, a slider's number box, vector fields: all Mantine ``NumberInput``) send their
value on every change, so typing ``-36`` into a joint's box sent ``-3`` first and the arm went
there. :data:`NUMBER_COMMIT_JS`, a script the served page runs before viser's, stops the
keystroke ``input`` events of those boxes in the capture phase at ``window``, before React's
listener on the page's root sees them: React keeps the last committed value, the box shows what
is typed. Enter, leaving the box or an arrow key with something typed replay the edit as one:
the committed text all selected (one keydown, which the box's number formatter reads its
selection from), replaced by the typed text in one ``input`` event (a plain ``change`` event
left the formatter diffing against a stale selection: from a box showing 0 it read no change
and nothing was sent); Escape puts the committed value back. The slider's track is a separate
control (pointer events): a drag still moves the joint as it goes.

The program list's clicks and keys (select, shift-select, arrows, Delete, undo/redo) are a second
script, :data:`server.program_keys_js.PROGRAM_KEYS_JS`, run the same way (:func:`with_page_scripts`).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import zstandard

from server.program_keys_js import PROGRAM_KEYS_JS

log = logging.getLogger(__name__)

#: The 88 characters of viser's encoding, in digit order: printable ASCII (0x21-0x7e) without
#: the six that need escaping in a double-quoted HTML attribute or a JavaScript string.
BASE88_ALPHABET = "".join(chr(c) for c in range(0x21, 0x7F) if chr(c) not in "\"&<>'`")
_DIGIT = np.full(128, -1, dtype=np.int64)
_DIGIT[np.frombuffer(BASE88_ALPHABET.encode(), dtype=np.uint8)] = np.arange(88)
_POWERS = 88 ** np.arange(4, -1, -1, dtype=np.int64)  # 5 digits, most significant first

# The senders, as minified: each pattern's second group is the interval (ms). Names differ
# between builds; the case label, the destructuring and the surrounding literals do not.
SENDERS: dict[str, re.Pattern[str]] = {
    # ``case`TransformControlsMessage`:{let{send:n,flush:r}=RL(t,50),...``
    "gizmo": re.compile(
        r"(case`TransformControlsMessage`:\{let\{send:[\w$]+,flush:[\w$]+\}=[\w$]+\([\w$]+,)(\d+)(\))"
    ),
}
_PAYLOAD = re.compile(r'data-p="([^"]*)"')

#: Number boxes commit on Enter, on leaving the box, or on an arrow key with text typed, never
#: per keystroke (see the module docstring). ``input`` events of a box are held back from React;
#: one ``change`` event commits the text typed since the last commit.
NUMBER_COMMIT_JS = """(() => {
  const BOX = ".mantine-NumberInput-input";
  const typed = new WeakSet();      // boxes holding text not committed yet
  const committed = new WeakMap();  // box -> its text at the last commit (for Escape)
  let passing = false;              // the commit's own input event is on its way
  const isBox = (el) => el instanceof HTMLInputElement && el.matches(BOX);
  const commit = (el) => {
    if (!typed.has(el)) return;
    typed.delete(el);
    // React's box (react-number-format) diffs each edit against the selection it saw at the last
    // keydown; after keystrokes it never saw, that diff is wrong (from a box at 0 it read no
    // change at all). So the commit replays the edit as one: the last committed text all
    // selected, then replaced by what was typed, in one input event.
    const text = el.value;
    const before = committed.has(el) ? committed.get(el) : "";
    const setValue = Object.getOwnPropertyDescriptor(HTMLInputElement.prototype, "value").set;
    setValue.call(el, before);
    el.setSelectionRange(0, before.length);
    el.dispatchEvent(new KeyboardEvent("keydown", { bubbles: true, key: "Unidentified" }));
    setValue.call(el, text);
    el.setSelectionRange(text.length, text.length);
    committed.set(el, text);
    passing = true;  // this one input event reaches React: the box's one edit
    try { el.dispatchEvent(new Event("input", { bubbles: true })); } finally { passing = false; }
  };
  window.addEventListener("focusin", (e) => { if (isBox(e.target)) committed.set(e.target, e.target.value); }, true);
  window.addEventListener("input", (e) => {
    if (!isBox(e.target) || passing) return;
    typed.add(e.target);
    e.stopImmediatePropagation();
  }, true);
  window.addEventListener("change", (e) => {
    if (isBox(e.target)) { typed.delete(e.target); committed.set(e.target, e.target.value); }
  }, true);
  window.addEventListener("keydown", (e) => {
    const el = e.target;
    if (!isBox(el)) return;
    if (e.key === "Enter") {
      commit(el);
    } else if (e.key === "Escape" && typed.has(el)) {
      typed.delete(el);
      el.value = committed.has(el) ? committed.get(el) : el.value;
      e.stopImmediatePropagation();
    } else if ((e.key === "ArrowUp" || e.key === "ArrowDown") && typed.has(el)) {
      e.preventDefault();
      e.stopImmediatePropagation();
      commit(el);
    }
  }, true);
  window.addEventListener("focusout", (e) => { if (isBox(e.target)) commit(e.target); }, true);
})();"""
_COMMIT_TAG = f'<script data-teleprog="number-commit">{NUMBER_COMMIT_JS}</script>'
_PROGRAM_KEYS_TAG = f'<script data-teleprog="program-keys">{PROGRAM_KEYS_JS}</script>'


class PagePatchError(ValueError):
    """viser's page is not laid out as this module expects (another viser build)."""


def decode_base88(text: str) -> bytes:
    """Bytes from viser's base-88 text: 5 digits per 4 bytes, big-endian; a last group of k
    digits holds k - 1 bytes."""
    if not text.isascii():
        bad = next(i for i, ch in enumerate(text) if not ch.isascii())
        raise PagePatchError(f"character {text[bad]!r} at {bad} is not in the base-88 alphabet")
    codes = np.frombuffer(text.encode("ascii"), dtype=np.uint8)
    digits = _DIGIT[codes]
    if (digits < 0).any():
        bad = int(np.flatnonzero(digits < 0)[0])
        raise PagePatchError(f"character {text[bad]!r} at {bad} is not in the base-88 alphabet")
    whole, rest = divmod(len(digits), 5)
    if rest == 1:
        raise PagePatchError("base-88 text ends in a group of one digit")
    values = digits[: whole * 5].reshape(whole, 5) @ _POWERS
    if (values >= 2**32).any():
        raise PagePatchError(f"base-88 group {int(np.argmax(values >= 2**32))} holds more than 4 bytes")
    out = values.astype(">u4").tobytes()
    if rest:
        value = 0
        for d in digits[whole * 5 :]:
            value = value * 88 + int(d)
        if value >= 256 ** (rest - 1):
            raise PagePatchError(f"the last base-88 group holds more than {rest - 1} bytes")
        out += value.to_bytes(rest - 1, "big")
    return out


def encode_base88(data: bytes) -> str:
    """The inverse of :func:`decode_base88`."""
    whole, rest = divmod(len(data), 4)
    values = np.frombuffer(data[: whole * 4], dtype=">u4").astype(np.int64)
    digits = (values[:, None] // _POWERS) % 88
    alphabet = np.frombuffer(BASE88_ALPHABET.encode(), dtype=np.uint8)
    text = alphabet[digits].tobytes().decode("ascii")
    if rest:
        value = int.from_bytes(data[whole * 4 :], "big")
        tail = []
        for _ in range(rest + 1):
            value, d = divmod(value, 88)
            tail.append(BASE88_ALPHABET[d])
        text += "".join(reversed(tail))
    return text


@dataclass(frozen=True)
class PageBundle:
    """The style sheet and the module script packed in viser's page."""

    style: str
    script: str


def _size_attribute(html: str, name: str) -> int:
    found = re.search(rf'data-{name}="(\d+)"', html)
    if found is None:
        raise PagePatchError(f"the page has no data-{name} attribute")
    return int(found.group(1))


def unpack(html: str) -> PageBundle:
    """The style and script packed in ``html`` (viser's ``index.html``)."""
    payload = _PAYLOAD.findall(html)
    if len(payload) != 1:
        raise PagePatchError(f"expected one data-p attribute in the page, found {len(payload)}")
    style_size, script_size = _size_attribute(html, "ss"), _size_attribute(html, "cs")
    raw = zstandard.ZstdDecompressor().decompress(decode_base88(payload[0]), max_output_size=style_size + script_size)
    if len(raw) != style_size + script_size:
        raise PagePatchError(f"the packed frame holds {len(raw)} bytes, data-ss + data-cs say {style_size + script_size}")
    return PageBundle(raw[:style_size].decode("utf-8"), raw[style_size:].decode("utf-8"))


def pack(html: str, bundle: PageBundle) -> str:
    """``html`` with its packed style and script replaced by ``bundle``'s."""
    style, script = bundle.style.encode("utf-8"), bundle.script.encode("utf-8")
    # level 9: 0.05 s at start-up; the page grows about 7% over viser's level-19 frame (0.8 s)
    frame = zstandard.ZstdCompressor(level=9).compress(style + script)
    html = _PAYLOAD.sub(lambda _: f'data-p="{encode_base88(frame)}"', html, count=1)
    html = re.sub(r'data-ss="\d+"', f'data-ss="{len(style)}"', html, count=1)
    return re.sub(r'data-cs="\d+"', f'data-cs="{len(script)}"', html, count=1)


def read_send_intervals_ms(html: str) -> dict[str, int]:
    """The interval (ms) of each of ``SENDERS`` in ``html``'s page."""
    script = unpack(html).script
    out = {}
    for name, pattern in SENDERS.items():
        found = pattern.findall(script)
        if len(found) != 1:
            raise PagePatchError(f"expected one {name} sender in the page's script, found {len(found)}")
        out[name] = int(found[0][1])
    return out


def paced_page(html: str, intervals_ms: Mapping[str, int]) -> str:
    """``html`` (viser's page) with each named sender (``SENDERS``) sending at most every so many ms."""
    for name, interval in intervals_ms.items():
        if name not in SENDERS:
            raise ValueError(f"no sender named {name!r}; known: {', '.join(SENDERS)}")
        if not 1 <= interval <= 1000:
            raise ValueError(f"{name} send interval must be 1-1000 ms, got {interval}")
    bundle = unpack(html)
    script = bundle.script
    for name, interval in intervals_ms.items():
        script, count = SENDERS[name].subn(lambda m, ms=interval: f"{m.group(1)}{ms}{m.group(3)}", script)
        if count != 1:
            raise PagePatchError(f"expected one {name} sender in the page's script, found {count}")
    return pack(html, PageBundle(bundle.style, script))


def with_number_commit(html: str) -> str:
    """``html`` with :data:`NUMBER_COMMIT_JS` run first thing in its head (before viser's script)."""
    return _in_head(html, _COMMIT_TAG, "the number-commit script")


def with_page_scripts(html: str) -> str:
    """``html`` with the console's scripts run first thing in its head (before viser's):
    :data:`NUMBER_COMMIT_JS`, then the program list's clicks and keys (``PROGRAM_KEYS_JS``)."""
    return _in_head(html, _COMMIT_TAG + _PROGRAM_KEYS_TAG, "the console's scripts")


def _in_head(html: str, tags: str, what: str) -> str:
    head = re.search(r"<head[^>]*>", html)
    if head is None:
        raise PagePatchError(f"the page has no <head> to put {what} in")
    return html[: head.end()] + tags + html[head.end() :]


def served_page(html: str, intervals_ms: Mapping[str, int] | None = None) -> str:
    """The page to serve: ``html`` with number boxes that commit on Enter or leaving the box,
    paced by ``intervals_ms`` (unpaced when that is empty or the page cannot be paced: logged)."""
    if intervals_ms:
        try:
            html = paced_page(html, intervals_ms)
        except (PagePatchError, zstandard.ZstdError, UnicodeDecodeError) as exc:
            log.warning("serving viser's page unpaced: drags stay at viser's own 20 updates a second (%s)", exc)
    return with_page_scripts(html)
