"""The program as an HTML list: one line per entry with its number, text and planned duration,
the selected range highlighted, the cursor marked, and a refusal drawn on the line it concerns
(its sentence in plain words; the rule's id only in the tooltip and ``data-rule``).

Only drawing: each line carries ``data-stmt-index`` and the list ``data-program-list`` and
``data-program-api``, which the page's script (``server.program_keys_js``) turns into calls on the
program's HTTP API for clicks and keys. Text reads as the markdown list did before
(``▶ 2: DRAW ...``), so what the page shows stays searchable.
"""

from __future__ import annotations

from html import escape

from server.console import ProgramView, StatementView
from server.program_keys_js import PROGRAM_API

MARK = "▶"
HINT = ("Click a line to select it, shift-click for a range; ↑ ↓ move (shift extends), Alt+↑ ↓ move the statements, "
        "Delete, Ctrl+Z / Ctrl+Shift+Z")

_LIST_STYLE = "user-select:none;cursor:default;font-size:0.85em;line-height:1.5;outline:none"
_LINE_STYLE = "display:flex;gap:0.4em;align-items:baseline;padding:1px 4px;border-left:3px solid transparent;cursor:pointer"
_SELECTED_BG = "background:rgba(34,139,230,0.18)"
_REFUSED_BORDER = "border-left-color:#e03131"
_REFUSAL_STYLE = "color:#e03131;padding:0 4px 2px 1.9em;font-size:0.95em"
_START = {"model": "cell home", "predicted": "end of sent statements", "telemetry": "re-synced from robot"}


def duration_text(entry: StatementView) -> str:
    """The planned duration as a person reads it: ``1.2 s``; empty when it is not known."""
    if entry.kind == "EMPTY":
        return ""
    if entry.duration_s is None:
        return "task" if entry.kind == "TASK" else "–"
    return f"{entry.duration_s:.1f} s"


def _line(entry: StatementView, view: ProgramView, selected: bool, refused: bool) -> str:
    cursor = entry.index == view.selected
    number = f"<b>{entry.index + 1}:</b>" if cursor else f"{entry.index + 1}:"
    text = "<i>(empty statement)</i>" if entry.kind == "EMPTY" else f"<code>{escape(entry.text)}</code>"
    if entry.added_by == "console":
        text += (f' <i data-added-by="console" style="opacity:0.8">(added by the console: '
                 f"{escape(entry.added_reason or 'the regime needs it')}; delete it to go without)</i>")
    lead = f"{MARK} {number}" if cursor else number
    style = _LINE_STYLE + (";" + _SELECTED_BG if selected else "") + (";" + _REFUSED_BORDER if refused else "")
    attrs = f'data-stmt-index="{entry.index}" data-selected="{str(selected).lower()}"'
    if cursor:
        attrs += ' data-cursor="true"'
    if refused:
        attrs += ' data-refused="true"'
    duration = f'<span data-duration style="margin-left:auto;opacity:0.7;white-space:nowrap">{duration_text(entry)}</span>'
    return f'<div {attrs} style="{style}"><span>{lead} {text}</span>{duration}</div>'


def _refusal(view: ProgramView) -> str:
    """The refusal's sentence in plain words; its rule id only in the tooltip and ``data-rule``."""
    refusal = view.refusal
    assert refusal is not None
    where = f' data-refusal-for="{refusal.index}"' if refusal.index is not None else ' data-refusal-for="program"'
    rule = escape(refusal.rule, quote=True)
    message = refusal.message[:1].upper() + refusal.message[1:]
    return (f'<div{where} data-rule="{rule}" title="rule {rule}" style="{_REFUSAL_STYLE}">'
            f"✖ {escape(message)}</div>")


def program_html(view: ProgramView) -> str:
    """The program list for ``gui.add_html``."""
    first, last = view.selected_range if view.selected_range is not None else (view.selected, view.selected)
    refusal = view.refusal
    on_line = refusal is not None and refusal.index is not None and 0 <= refusal.index < len(view.entries)
    parts = [f'<div data-program-list data-program-api="{PROGRAM_API}" style="{_LIST_STYLE}">']
    if refusal is not None and not on_line:
        parts.append(_refusal(view))
    for entry in view.entries:
        refused = on_line and refusal.index == entry.index
        parts.append(_line(entry, view, first <= entry.index <= last, refused))
        if refused:
            parts.append(_refusal(view))
    parts.append("</div>")
    known = [e.duration_s for e in view.entries if e.duration_s is not None]
    total = f"; planned {sum(known):.1f} s" if known else ""
    footer = f"Starts from: {_START.get(view.start_source, view.start_source)}{total}"
    footer += " · strict editing (thesis rules)" if view.strict_editing else " · free editing"
    last_real = min(last, view.empty_index - 1)
    if first < last_real:
        footer += f" · statements {first + 1}-{last_real + 1} selected"
    if view.preview is not None:
        footer += f"<br>Previewing statements {view.preview[0] + 1}-{view.preview[1]}: only selection is allowed"
    parts.append(f'<div style="font-size:0.8em;opacity:0.75;padding:4px">{footer}<br>{escape(HINT)}</div>')
    return "".join(parts)
