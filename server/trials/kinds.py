"""The grasp, extract/insert and combined trials of thesis §4.6 on the peg transfer
(``server.trials.programs``), each run a fresh session in real or virtual time.

| kind | mode | what is timed and judged (after the untimed setup) |
|---|---|---|
| grasp | offline | approach and grasp programmed offline, previewed, sent as one block |
| extract | supervised | the robot's extraction task, sent alone once the grasp is done |
| insert | supervised | force mode and the robot's insertion task, once the peg hangs over the target |
| transfer | composite | the whole transfer, each statement sent as the regime of its control zone says |
| transfer | free / quasi / operation | the whole transfer under that one regime, for comparison |

How a statement is sent follows the regimes of segmented composite control (§4.2.1):

- **stream** (free regime, online): sent as soon as the virtual robot finishes it;
- **block** (quasi-operation regime, offline): the piece is programmed on the virtual robot, then
  previewed and sent whole;
- **step** (operation regime, single step): sent once every earlier statement's final report is back.

The composite mode takes each statement's regime from the control zone of the virtual arm where
the statement ends (``regime_schedule``: the console's planner and zone classification on the
model), and consecutive statements of one regime form one piece. The operator's own time is the
virtual robot's: a statement is ready when its planned duration has passed after the previous one
was ready (or sent, when the operator had to wait).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from robot_sim.settings import WorldSettings
from server.trials.drivers import Clock, Driver, SentRecord
from server.trials.kind_results import KindRun
from server.trials.open import open_driver
from server.trials.programs import TransferProgram
from server.trials.results import StatementTiming
from server.trials.session import TrialError

Kind = Literal["grasp", "extract", "insert", "transfer"]
How = Literal["stream", "block", "step"]
KIND_MODES: dict[str, tuple[str, ...]] = {
    "grasp": ("offline",),
    "extract": ("supervised",),
    "insert": ("supervised",),
    "transfer": ("composite", "free", "quasi", "operation"),
}
REGIME_HOW: dict[str, How] = {"free": "stream", "quasi": "block", "operation": "step"}
WAIT_S = 120.0  # beyond the link's round trip and the planned time, how long a wait may last


@dataclass(frozen=True)
class Piece:
    texts: tuple[str, ...]
    how: How


def regime_schedule(cell_path: str | Path, texts: Sequence[str]) -> list[str]:
    """The regime of each statement: the control zone of the virtual arm where it ends, the
    objects following the generated grasps and releases (the console's planner and zones)."""
    from server.trials.virtual_clock import VirtualDriver

    planner = VirtualDriver(cell_path, WorldSettings(), 0.0)  # its console side only: nothing is sent
    out = []
    for text in texts:
        planner.generate([text])
        out.append(planner.zone())
    return out


def pieces(kind: str, mode: str, program: TransferProgram, schedule: Sequence[str] | None = None
           ) -> tuple[list[Piece], list[Piece]]:
    """The untimed setup and the trial's own pieces for ``kind`` in ``mode``."""
    t = program.texts
    if kind == "grasp":
        return [], [Piece(tuple(t("approach", "grasp")), "block")]
    if kind == "extract":
        return [Piece(tuple(t("approach", "grasp")), "block")], [Piece(tuple(t("extract")), "step")]
    if kind == "insert":
        setup = [Piece(tuple(t("approach", "grasp")), "block"), Piece(tuple(t("extract")), "step"),
                 Piece(tuple(t("carry")), "block")]
        return setup, [Piece(tuple(t("insert")), "step")]
    if kind != "transfer":
        raise TrialError(f"unknown trial kind {kind!r}; kinds: approach, {', '.join(KIND_MODES)}")
    texts = t()
    if mode == "free":
        return [], [Piece(tuple(texts), "stream")]
    if mode == "quasi":
        return [], [Piece(tuple(texts), "block")]
    if mode == "operation":
        return [], [Piece((text,), "step") for text in texts]
    if mode != "composite":
        raise TrialError(f"unknown mode {mode!r} for the transfer trial; modes: {', '.join(KIND_MODES['transfer'])}")
    return [], composite_pieces(texts, schedule)


def composite_pieces(texts: Sequence[str], schedule: Sequence[str] | None) -> list[Piece]:
    """Segmented composite control: each statement sent as the regime of the zone it ends in
    says, consecutive statements of one regime (but step) as one piece."""
    if schedule is None or len(schedule) != len(texts):
        raise TrialError("the composite mode needs the regime of every statement (regime_schedule)")
    out: list[Piece] = []
    for text, regime in zip(texts, schedule, strict=True):
        how = REGIME_HOW[regime]
        if out and out[-1].how == how and how != "step":
            out[-1] = Piece(out[-1].texts + (text,), how)
        else:
            out.append(Piece((text,), how))
    return out


def execute(driver: Driver, plan: Sequence[Piece], delay_s: float) -> list[SentRecord]:
    """Send the pieces as their regimes say; stop at the first statement that does not end done
    (the robot then holds and waits for the operator). Returns every record sent."""
    records: list[SentRecord] = []
    ready = driver.now()  # when the operator has the next statement ready
    timeout = 2 * delay_s + WAIT_S

    def failed() -> bool:
        return any(r.final and r.status != "done" for r in records)

    for piece in plan:
        if piece.how == "block":
            planned = driver.generate(list(piece.texts))
            ready = max(ready, driver.now()) + sum(planned)
            driver.wait_until(ready)
            records += driver.send(previewed=True)
            continue
        for text in piece.texts:
            (planned,) = driver.generate([text])
            ready = max(ready, driver.now()) + planned
            if piece.how == "step" and records:
                driver.finals(records, timeout)
                if failed():
                    return records
            driver.wait_until(ready)
            records += driver.send()
        if failed():
            return records
    if records:
        driver.finals(records, timeout + sum(r.planned_s for r in records) * 10)
    return records


def _rows(records: list[SentRecord], one_way_s: float) -> list[StatementTiming]:
    rows = []
    for i, s in enumerate(records):
        fin = s.finished_at
        robot_done = fin - one_way_s if fin is not None else None
        rows.append(StatementTiming(
            index=i, text=s.text, planned_s=s.planned_s, status=s.status, reason=s.reason,
            submitted_at=s.submitted_at, finished_at=fin, statement_s=None if fin is None else fin - s.submitted_at,
            run_s=s.run_s, robot_run_s=s.robot_run_s, robot_done_at=robot_done,
            lag_s=None if robot_done is None else robot_done - s.submitted_at,
        ))
    return rows


def _failure(records: list[SentRecord], expected: int) -> str | None:
    bad = next((r for r in records if r.status != "done"), None)
    if bad is not None:
        return f"{bad.text}: {bad.status}: {bad.reason or 'no reason given'}"
    if len(records) < expected:
        return f"only {len(records)} of {expected} statements were sent"
    return None


def run_one(kind: str, mode: str, program: TransferProgram, *, index: int, world: WorldSettings, delay_ms: float,
            clock: Clock, log_dir: Path, schedule: Sequence[str] | None = None) -> KindRun:
    """One run of ``kind`` in ``mode``: a fresh session, the untimed setup, the timed trial."""
    setup, trial = pieces(kind, mode, program, schedule)
    expected = sum(len(p.texts) for p in trial)
    base = dict(kind=kind, mode=mode, index=index, world_seed=world.seed, delay_ms=delay_ms, clock=clock)
    delay_s = delay_ms / 1e3
    try:
        with open_driver(clock, cell=program.cell, delay_ms=delay_ms, world=world,
                         log_path=log_dir / f"{kind}-{mode}-run{index}.log") as driver:
            before = execute(driver, setup, delay_s)
            setup_failure = _failure(before, sum(len(p.texts) for p in setup))
            if setup_failure is not None:
                return KindRun(**base, reached=False, success=False, failure=f"setup: {setup_failure}",
                               alarms=sum(r.status == "failed" for r in before))
            started = driver.now()  # the operator starts on the trial's first statement
            records = execute(driver, trial, delay_s)
            one_way = driver.one_way_delay_s()
    except TrialError as exc:
        return KindRun(**base, reached=False, success=False, failure=str(exc))
    rows = _rows(records, one_way)
    failure = _failure(records, expected)
    last = max((r for r in rows if r.finished_at is not None), key=lambda r: r.finished_at, default=None)
    return KindRun(
        **base, reached=True, success=failure is None, failure=failure, statements=rows,
        virtual_s=sum(r.planned_s for r in rows),
        total_s=None if last is None else round(last.finished_at - started, 4),
        robot_total_s=None if last is None else round(last.robot_done_at - started, 4),
        alarms=sum(r.status == "failed" for r in rows), one_way_delay_s=one_way,
    )
