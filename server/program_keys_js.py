"""The program list's mouse and keys: a script the served page runs (``server.viser_page``).

viser has no list widget: the Program tab draws the program as one HTML block
(``webui.program_panel``), one element per entry carrying ``data-stmt-index``, inside an element
carrying ``data-program-list`` and ``data-program-api`` (where the program's HTTP API is). This
script only maps input to calls on that API; every rule stays in the editor, and the page redraws
from the session's events like any other change:

* a click on a line selects it (``POST select {index}``); a shift-click extends the selection
  from its anchor to that line (``extend: true``);
* while the list is the last thing clicked, or the mouse is over it: ArrowUp / ArrowDown move the
  selection (``POST move {by, extend}``, shift extends; at either end it stays), Alt+ArrowUp /
  Alt+ArrowDown move the selected statements (``POST move-statements {by}``), Delete or Backspace deletes the selected
  range (``POST delete``), Ctrl+Z undoes (``POST undo``), Ctrl+Shift+Z and Ctrl+Y redo
  (``POST redo``; Cmd on a Mac). Keys typed into a text or number box are never taken; a click on
  a line takes the focus from a box clicked before, so the keys after it go to the list.

Keys the list takes are stopped in the capture phase at ``window``, before viser's own handlers
(the camera's arrow keys) see them. Calls go one at a time, in order. A refused call needs nothing here: the session shows the
refusal on its line and in the status bar.
"""

from __future__ import annotations

#: Where the program's endpoints live (``server.api.program``), as the list's ``data-program-api``.
PROGRAM_API = "/api/program"

PROGRAM_KEYS_JS = """(() => {
  const LIST = "[data-program-list]";
  let clicked = false;  // the last mouse press was on the list
  let hovered = false;  // the mouse is over the list
  const list = () => document.querySelector(LIST);
  const inList = (el) => el instanceof Element && el.closest(LIST) !== null;
  let queue = Promise.resolve();  // one call at a time, in the order of the keys and clicks
  const call = (path, body) => {
    const el = list();
    if (!el) return;
    const url = el.dataset.programApi + path;
    queue = queue.then(() => fetch(url, {
      method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body || {}),
    })).catch((err) => console.warn("program list: " + path + " failed", err));
  };
  const typing = (el) => el instanceof HTMLElement && (el.isContentEditable ||
    el.matches("input:not([type='checkbox']):not([type='radio']):not([type='button']), textarea, select, [role='textbox'], [role='combobox']"));
  window.addEventListener("mousedown", (e) => {
    clicked = inList(e.target);
    if (!clicked || e.button !== 0) return;
    const line = e.target.closest("[data-stmt-index]");
    if (line === null) return;
    e.preventDefault();  // a shift-click selects lines, not the page's text
    // preventing the default also keeps the focus where it was: a text box or a tick box clicked
    // before would keep the keys meant for the list, so it lets go of them here
    const focused = document.activeElement;
    if (focused instanceof HTMLElement && focused !== document.body && !inList(focused)) focused.blur();
    call("/select", { index: Number(line.dataset.stmtIndex), extend: e.shiftKey });
  }, true);
  window.addEventListener("mouseover", (e) => { hovered = inList(e.target); }, true);
  window.addEventListener("keydown", (e) => {
    if (!(clicked || hovered) || typing(e.target) || list() === null) return;
    const ctrl = e.ctrlKey || e.metaKey;
    const key = e.key.length === 1 ? e.key.toLowerCase() : e.key;
    let path = null, body = null;
    if (!ctrl && !e.altKey && (key === "ArrowDown" || key === "ArrowUp")) {
      path = "/move"; body = { by: key === "ArrowDown" ? 1 : -1, extend: e.shiftKey };
    } else if (!ctrl && e.altKey && !e.shiftKey && (key === "ArrowDown" || key === "ArrowUp")) {
      path = "/move-statements"; body = { by: key === "ArrowDown" ? 1 : -1 };
    } else if (!ctrl && !e.altKey && (key === "Delete" || key === "Backspace")) {
      path = "/delete";
    } else if (ctrl && !e.altKey && key === "z") {
      path = e.shiftKey ? "/redo" : "/undo";
    } else if (ctrl && !e.altKey && !e.shiftKey && key === "y") {
      path = "/redo";
    }
    if (path === null) return;
    e.preventDefault();
    e.stopImmediatePropagation();
    call(path, body);
  }, true);
})();"""
