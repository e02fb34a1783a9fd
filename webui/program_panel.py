"""The programming panel (thesis 4.3.6): the program as a list with its selection, automatic
generation on/off, free or strict (thesis) editing, a statement added or edited by hand, delete,
undo/redo, save and load.

The panel decides nothing: each control calls the session, whose editor applies the rules; a
refusal comes back as a sentence, shown in the status bar and under the line it concerns (the
rule's id only in that line's tooltip). The list is an HTML block (``webui.program_list``; viser has no list widget) whose
lines the page's script turns into clicks and keys on the program's API (click, shift-click,
arrows, Delete, Ctrl+Z); a dropdown selects an entry too.
"""

from __future__ import annotations

import logging

import viser

from server.console import ProgramView, Session, StatementView
from webui.actions import Actions
from webui.program_list import MARK, program_html

log = logging.getLogger(__name__)

__all__ = ["MARK", "ProgramPanel", "entry_label"]

FREE_HINT = "edit the selected statement (any kind, anywhere), then Replace; the rest is re-planned"
STRICT_HINT = "edit WITH / UNTIL (any action) or the parameters (last action only), then Replace"


def entry_label(entry: StatementView) -> str:
    """How an entry reads in the selector: its number (from 1, as the operator counts) and text."""
    text = "(empty)" if entry.kind == "EMPTY" else entry.text
    return f"{entry.index + 1}: {text}"


class ProgramPanel:
    """Controls of the program editor; redrawn from ``ProgramView`` events."""

    def __init__(self, server: viser.ViserServer, session: Session, actions: Actions) -> None:
        self.server = server
        self.session = session
        self.actions = actions
        gui = server.gui
        self.auto = gui.add_checkbox("Automatic generation", initial_value=True,
                                     hint="turn driving motion into statements as you drive")
        self.auto.on_update(self._on_auto)
        self.strict = gui.add_checkbox(
            "Strict editing (thesis rules)", initial_value=False,
            hint="off (the default): delete, replace, move or insert any statement, the rest re-planned and checked; "
                 "on: the thesis's rules (§4.3.6), where only the last motion may change",
        )
        self.strict.on_update(self._on_strict)
        self.listing = gui.add_html("")
        self.selector = gui.add_dropdown("Selected", ["1: (empty)"], initial_value="1: (empty)")
        self.selector.on_update(self._on_select)
        self.new_text = gui.add_text("New statement", "", hint="e.g. DRAW TO (0, -80, 160) mm IN WORK")
        self.insert = gui.add_button("Insert before selection", icon=viser.Icon.ROW_INSERT_TOP)
        self.insert.on_click(lambda _: self.actions.run("insert", lambda: self.session.program.insert(self.new_text.value)))
        self.edit_text = gui.add_text("Selected text", "", hint=FREE_HINT)
        self.edits = gui.add_button_group("Edit", ("Replace", "Clear WITH/UNTIL", "Delete"))
        self.edits.on_click(self._on_edit)
        self.history = gui.add_button_group("History", ("Undo", "Redo"))
        self.history.on_click(self._on_history)
        self.history_line = gui.add_markdown("")
        self.files = gui.add_button("Save program (download)", icon=viser.Icon.DOWNLOAD)
        self.files.on_click(self._on_save)
        self.upload = gui.add_upload_button("Load program file", icon=viser.Icon.UPLOAD, hint=".tp text or .json")
        self.upload.on_upload(self._on_load)
        self._options: list[str] = []
        self._view: ProgramView | None = None
        self._setting = False

    # -- clicks -------------------------------------------------------------------------------
    def _on_auto(self, event: viser.GuiEvent) -> None:
        if self._setting or event.client is None:
            return
        on = bool(self.auto.value)
        self.actions.run("automatic generation", lambda: self.session.program.set_auto_generate(on))

    def _on_strict(self, event: viser.GuiEvent) -> None:
        if self._setting or event.client is None:
            return
        on = bool(self.strict.value)
        self.actions.run("editing mode", lambda: self.session.program.set_strict_editing(on))

    def _on_select(self, event: viser.GuiEvent) -> None:
        if self._setting or event.client is None:
            return
        try:
            index = self._options.index(self.selector.value)
        except ValueError:
            return
        self.actions.run("select", lambda: self.session.program.select(index))

    def _on_edit(self, event: viser.GuiEvent) -> None:  # Delete: the selected range
        choice = event.target.value
        if choice == "Replace":
            text = self.edit_text.value
            self.actions.run("modify", lambda: self.session.program.modify(text))
        elif choice == "Clear WITH/UNTIL":
            self.actions.run("clear WITH/UNTIL", lambda: self.session.program.modify_conditions(speed=None, until=None))
        else:
            self.actions.run("delete", self.session.program.delete)

    def _on_history(self, event: viser.GuiEvent) -> None:
        choice = event.target.value
        self.actions.run(choice.lower(), self.session.program.undo if choice == "Undo" else self.session.program.redo)

    def _on_save(self, event: viser.GuiEvent) -> None:
        content = self.actions.run("save", lambda: self.session.program.save("text"))
        if content is not None and event.client is not None:
            event.client.send_file_download("program.tp", content.encode("utf-8"), save_immediately=True)

    def _on_load(self, event: viser.GuiEvent) -> None:
        upload = self.upload.value
        try:
            text = upload.content.decode("utf-8")
        except UnicodeDecodeError:
            self.actions.show_notice("error", f"load refused: {upload.name} is not UTF-8 text", None)
            return
        self.actions.run("load", lambda: self.session.program.load(text, upload.name))

    # -- session events -----------------------------------------------------------------------
    def show(self, view: ProgramView) -> None:
        self._view = view
        self.listing.content = program_html(view)
        options = [entry_label(e) for e in view.entries]
        selected = options[view.selected]
        entry = view.entries[view.selected]
        self._setting = True
        try:
            if options != self._options:
                self.selector.options = options
                self._options = options
            if self.selector.value != selected:
                self.selector.value = selected
            if self.auto.value != view.auto_generate:
                self.auto.value = view.auto_generate
            if self.strict.value != view.strict_editing:
                self.strict.value = view.strict_editing
                self.edit_text.hint = STRICT_HINT if view.strict_editing else FREE_HINT
            self.edit_text.value = "" if entry.kind == "EMPTY" else entry.text
        finally:
            self._setting = False
        undo = f"Undo: {view.undo_label}" if view.can_undo else "Undo: nothing"
        redo = f"Redo: {view.redo_label}" if view.can_redo else "Redo: nothing"
        self.history_line.content = f"{undo} · {redo}"

