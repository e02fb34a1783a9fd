"""The Trials folder at the foot of the Submit tab (thesis §4.6, issue 19): pick a trial, its runs
and its delay, start it, watch a progress bar, and read the table and the plots when it is done.
A folder, not a tab of its own: a sixth tab wraps the tab strip onto a second row.

The batch is the console's (``server.trials.service.TrialBatches``, what ``POST /api/trials``
starts): this module turns the clicks into its calls and shows its view; a small thread polls
the running batch twice a second, as the API's clients do.
"""

from __future__ import annotations

import html
import io
import logging
import threading
import time

import numpy as np
import viser

from server.trials.runner import TrialRequest
from server.trials.service import TrialBatches, TrialBatchView
from shared.errors import InputError
from webui.actions import Actions

log = logging.getLogger(__name__)
KINDS = ("approach", "grasp", "extract", "insert", "transfer")
MAX_RUNS = 20
POLL_S = 0.5


def batch_html(view: TrialBatchView | None) -> str:
    """The tab's block for a batch: state, progress, the table (Markdown rows as an HTML table)."""
    if view is None:
        return '<div data-trial-state="none" style="opacity:.7">No trial run yet.</div>'
    head = (f'<div data-trial-state="{view.state}" data-trial-id="{view.id}" style="font-size:13px">'
            f"<b>{html.escape(view.request.kind)}</b> trial, {view.request.runs} run(s) per mode, "
            f"{view.request.delay_ms:g} ms each way, virtual time: {view.state} "
            f"({view.runs_done}/{view.runs_total})")
    parts = [head]
    if view.error:
        parts.append(f'<div data-trial-error style="color:#c62828">{html.escape(view.error)}</div>')
    rows = [line for line in view.table if line.startswith("|") and not line.startswith("|---")]
    if rows:
        cells = [[c.strip() for c in row.strip("|").split("|")] for row in rows]
        header = "".join(f"<th>{html.escape(c)}</th>" for c in cells[0])
        body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in cells[1:])
        parts.append(f'<table data-trial-table style="border-collapse:collapse;font-size:12px"><tr>{header}</tr>{body}</table>')
    notes = [line for line in view.table if line and not line.startswith("|")]
    parts += [f'<div style="opacity:.8;font-size:12px">{html.escape(n)}</div>' for n in notes[1:]]
    parts.append("</div>")
    return "".join(parts)


class TrialsPanel:
    """The Trials folder's widgets, added where the caller's GUI context is."""

    def __init__(self, server: viser.ViserServer, batches: TrialBatches, actions: Actions) -> None:
        self.server, self.batches, self.actions = server, batches, actions
        gui = server.gui
        self.kind = gui.add_dropdown("Trial kind", KINDS, initial_value="approach")
        self.runs = gui.add_number("Runs per mode", 3, min=1, max=MAX_RUNS, step=1)
        self.delay = gui.add_number("Trial delay (ms)", 3000.0, min=0.0, max=60_000.0, step=100.0)
        self.start = gui.add_button("Start trial", icon=viser.Icon.PLAYER_PLAY)
        self.progress = gui.add_progress_bar(0.0, animated=False)
        self.view_html = gui.add_html(batch_html(None))
        self.plots_folder = gui.add_folder("Plots")
        self.images: list = []
        self._batch: int | None = None
        self.start.on_click(lambda _: self._start())

    def _start(self) -> None:
        def start() -> TrialBatchView:
            try:
                request = TrialRequest(kind=self.kind.value, runs=int(self.runs.value), delay_ms=float(self.delay.value),
                                       clock="virtual")
            except ValueError as exc:
                raise InputError(f"trial: {exc}") from None
            return self.batches.start(request)

        view = self.actions.run("start the trial", start)
        if view is None:
            return
        self._batch = view.id
        self._show(view)
        threading.Thread(target=self._follow, args=(view.id,), name=f"trials-tab-{view.id}", daemon=True).start()

    def _follow(self, batch_id: int) -> None:
        while True:
            time.sleep(POLL_S)
            view = self.batches.view(batch_id)
            if view is None or self._batch != batch_id:
                return
            self._show(view)
            if view.state != "running":
                self._show_plots(view)
                return

    def _show(self, view: TrialBatchView) -> None:
        self.progress.value = 100.0 * view.runs_done / max(1, view.runs_total)
        self.start.disabled = view.state == "running"
        self.view_html.content = batch_html(view)

    def _show_plots(self, view: TrialBatchView) -> None:
        from PIL import Image

        for image in self.images:
            image.remove()
        self.images = []
        for name in view.plots:
            data = self.batches.plot(view.id, name)
            if data is None:
                continue
            pixels = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))
            with self.plots_folder:
                self.images.append(self.server.gui.add_image(pixels, label=name, format="png"))
