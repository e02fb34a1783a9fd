"""Trial batches started from the running console (``POST /api/trials``): each runs on a thread
of its own, on the console's cell, and keeps its progress, its report and its plots until the
console stops. The runs never touch the console's own robot: every run is a session of its own
(virtual time only from the API: a batch costs seconds, and it runs in a spawned process of its
own, so the console's event loop and threads are left alone).
"""

from __future__ import annotations

import logging
import shutil
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, Field

from server.trials.runner import TrialRequest, broken_runs, execute_batch, prepare, report_of
from server.console.errors import ConflictError

log = logging.getLogger(__name__)
MAX_BATCHES = 32  # kept at once; the oldest finished one goes first
PLOTS = ("times.png", "success.png", "timeline.png")


class TrialBatchView(BaseModel):
    id: int
    state: Literal["running", "done", "failed"]
    request: TrialRequest
    cell: str
    runs_done: int
    runs_total: int
    started_at: float
    finished_at: float | None = None
    error: str | None = Field(None, description="why the batch could not run, or how many runs broke")
    table: list[str] = Field(default_factory=list, description="the summary as Markdown lines")
    summary: dict | None = Field(None, description="the report's summary, as teleprog trial --json prints it")
    plots: list[str] = Field(default_factory=list, description="names of the plots: GET /api/trials/{id}/plots/{name}")


@dataclass
class _Batch:
    id: int
    request: TrialRequest
    cell: str
    folder: Path
    runs_total: int
    started_at: float = field(default_factory=time.time)
    runs_done: int = 0
    state: str = "running"
    finished_at: float | None = None
    error: str | None = None
    table: list[str] = field(default_factory=list)
    summary: dict | None = None
    plots: list[str] = field(default_factory=list)

    def view(self) -> TrialBatchView:
        return TrialBatchView(id=self.id, state=self.state, request=self.request, cell=self.cell, runs_done=self.runs_done,
                              runs_total=self.runs_total, started_at=self.started_at, finished_at=self.finished_at,
                              error=self.error, table=list(self.table), summary=self.summary, plots=list(self.plots))


class TrialBatches:
    """The console's trial batches, by id (from 1)."""

    def __init__(self, cell: str | Path) -> None:
        self.cell = str(cell)
        self._lock = threading.Lock()
        self._batches: dict[int, _Batch] = {}
        self._next = 1

    def start(self, request: TrialRequest) -> TrialBatchView:
        """Check the request against the cell (an ``InputError`` names what is wrong) and start it."""
        folder = Path(tempfile.mkdtemp(prefix="teleprog-trials-"))
        try:
            prepared = prepare(request, self.cell, folder / "logs")
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        with self._lock:
            running = sum(b.state == "running" for b in self._batches.values())
            if running:
                shutil.rmtree(folder, ignore_errors=True)
                raise ConflictError("a trial batch is running: wait for it to finish (GET /api/trials/{id})")
            batch = _Batch(self._next, request, self.cell, folder, len(prepared.specs))
            self._next += 1
            self._batches[batch.id] = batch
            self._forget_old()
        threading.Thread(target=self._run, args=(batch, prepared), name=f"trial-batch-{batch.id}", daemon=True).start()
        return batch.view()

    def _run(self, batch: _Batch, prepared) -> None:
        def done(_result) -> None:
            with self._lock:
                batch.runs_done += 1

        try:
            results = execute_batch(prepared, on_done=done, isolated=True)
            report = report_of(prepared, results)
            written = report.write(batch.folder)
            broken = broken_runs(batch.request.kind, results)
            with self._lock:
                batch.table = report.lines
                batch.summary = report.report.model_dump(mode="json")["summary"]
                batch.plots = [p.name for p in written if p.name in PLOTS]
                batch.error = (f"{len(broken)} of {len(results)} run(s) broke; first: run {broken[0].index}: "
                               f"{broken[0].failure}") if broken else None
                batch.state = "done"
        except Exception as exc:  # noqa: BLE001 - a batch's failure is its state, never the console's
            log.exception("trial batch %d failed", batch.id)
            with self._lock:
                batch.state, batch.error = "failed", f"{type(exc).__name__}: {str(exc)[:300]}"
        finally:
            with self._lock:
                batch.finished_at = time.time()

    def _forget_old(self) -> None:
        while len(self._batches) > MAX_BATCHES:
            old = min((b for b in self._batches.values() if b.state != "running"), key=lambda b: b.id, default=None)
            if old is None:
                return
            shutil.rmtree(old.folder, ignore_errors=True)
            del self._batches[old.id]

    def view(self, batch_id: int) -> TrialBatchView | None:
        with self._lock:
            batch = self._batches.get(batch_id)
            return None if batch is None else batch.view()

    def plot(self, batch_id: int, name: str) -> bytes | None:
        with self._lock:
            batch = self._batches.get(batch_id)
            if batch is None or name not in batch.plots:
                return None
            path = batch.folder / name
        return path.read_bytes()

    def close(self) -> None:
        """The console stops: end a running batch's worker process and drop every batch's files."""
        import multiprocessing

        with self._lock:
            running = any(b.state == "running" for b in self._batches.values())
            for b in self._batches.values():
                shutil.rmtree(b.folder, ignore_errors=True)
        if running:
            for child in multiprocessing.active_children():  # the batch's spawned pool worker
                child.terminate()
