"""A campaign's results: one :class:`FaultRun` per run, and the summary ``teleprog trial faults``
prints (runs, faults by kind, caught / missed / false stops with Wilson intervals, stop latency
percentiles per kind, stopping distances, and every miss with the seed that replays it)."""

from __future__ import annotations

from collections import Counter, defaultdict
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from server.trials.faults.catalogue import LINK_KINDS, Fault
from server.trials.stats import wilson_interval

Outcome = Literal["caught", "missed", "absorbed", "false_stop", "clean", "hung"]


class FaultStatement(BaseModel):
    model_config = ConfigDict(frozen=True)

    text: str
    status: str
    reason: str | None = None
    robot_run_s: float | None = None


class FaultRun(BaseModel):
    """One run as the judge saw it; times in s after the program's first submit (virtual)."""

    seed: int = 0
    world_seed: int = 0
    fault: Fault
    outcome: Outcome
    why: str = ""
    injected_at_s: float | None = None
    note: str = ""
    onset_s: float | None = None
    onset_how: str = ""
    stop_s: float | None = None
    stop_state: str = ""
    latency_ms: float | None = None
    stop_distance_mm: float | None = None
    stop_time_ms: float | None = None
    peak_load_n: float = 0.0
    peak_load_on: str = ""
    max_off_path_mm: float = 0.0
    robot_reason: str | None = None  # why the robot stopped, as it said so (its first failure or halt from the stop on)
    program_s: float | None = None  # first submit to the last final report, or to the end of the run
    statements: list[FaultStatement] = Field(default_factory=list)
    halts: list[str] = Field(default_factory=list)


def _pct(values: list[float], q: float) -> float | None:
    return round(float(np.percentile(values, q)), 1) if values else None


def _interval(k: int, n: int) -> list[float] | None:
    iv = wilson_interval(k, n)
    return None if iv is None else [round(iv[0], 5), round(iv[1], 5)]


class KindRow(BaseModel):
    kind: str
    runs: int
    caught: int
    missed: int
    absorbed: int
    false_stops: int
    hung: int
    latency_ms: dict[str, float | None]
    stop_distance_mm: dict[str, float | None]


class FaultSummary(BaseModel):
    runs: int
    seed: int
    delay_ms: float
    jitter_ms: float
    drop_probability: float
    program: str
    mode: str
    world: dict[str, object]
    faults: dict[str, int]
    caught: int
    missed: int
    absorbed: int
    false_stops: int
    hung: int
    fault_free_runs: int
    fault_runs: int
    missed_rate_upper_95: float | None = Field(None, description="Wilson upper bound of misses per fault-injected run")
    false_stop_rate: float | None = None
    false_stop_interval: list[float] | None = None
    stop_latency_ms: dict[str, float | None] = Field(description="caught world and robot faults: the stop after the physical onset")
    link_stop_latency_ms: dict[str, float | None] = Field(
        description="caught link faults: the stop after the fault struck (the silence contract: heartbeat and silence limit)")
    by_kind: list[KindRow]
    misses: list[dict[str, object]]
    false_stop_runs: list[dict[str, object]]
    hung_runs: list[dict[str, object]]
    wall_s: float | None = None
    runs_per_hour: float | None = None


class FaultReport(BaseModel):
    summary: FaultSummary
    runs: list[FaultRun]


def summarize(runs: list[FaultRun], *, seed: int, delay_ms: float, jitter_ms: float, drop_probability: float,
              program: str, mode: str, world: dict[str, object], wall_s: float | None = None) -> FaultSummary:
    count = Counter(r.outcome for r in runs)
    faulted = [r for r in runs if r.fault.kind != "none"]
    clean = [r for r in runs if r.fault.kind == "none"]
    false_clean = sum(r.outcome == "false_stop" for r in clean)
    latencies = [r.latency_ms for r in runs if r.outcome == "caught" and r.latency_ms is not None and r.fault.kind not in LINK_KINDS]
    link_latencies = [r.latency_ms for r in runs if r.outcome == "caught" and r.latency_ms is not None and r.fault.kind in LINK_KINDS]
    by: dict[str, list[FaultRun]] = defaultdict(list)
    for r in runs:
        by[r.fault.kind].append(r)
    rows = []
    for kind in sorted(by):
        rs = by[kind]
        lat = [r.latency_ms for r in rs if r.outcome == "caught" and r.latency_ms is not None]
        dist = [r.stop_distance_mm for r in rs if r.outcome == "caught" and r.stop_distance_mm is not None]
        c = Counter(r.outcome for r in rs)
        rows.append(KindRow(kind=kind, runs=len(rs), caught=c["caught"], missed=c["missed"], absorbed=c["absorbed"],
                            false_stops=c["false_stop"], hung=c["hung"],
                            latency_ms={"p50": _pct(lat, 50), "p99": _pct(lat, 99), "max": _pct(lat, 100)},
                            stop_distance_mm={"p50": _pct(dist, 50), "max": _pct(dist, 100)}))
    missed_faulted = sum(r.outcome == "missed" for r in faulted)
    upper = wilson_interval(missed_faulted, len(faulted))

    def brief(r: FaultRun) -> dict[str, object]:
        return {"seed": r.seed, "fault": r.fault.describe(), "why": r.why, "note": r.note}

    return FaultSummary(
        runs=len(runs), seed=seed, delay_ms=delay_ms, jitter_ms=jitter_ms, drop_probability=drop_probability,
        program=program, mode=mode, world=world, faults=dict(sorted(Counter(r.fault.kind for r in runs).items())),
        caught=count["caught"], missed=count["missed"], absorbed=count["absorbed"], false_stops=count["false_stop"],
        hung=count["hung"], fault_free_runs=len(clean), fault_runs=len(faulted),
        missed_rate_upper_95=None if upper is None else round(upper[1], 5),
        false_stop_rate=None if not clean else round(false_clean / len(clean), 5),
        false_stop_interval=_interval(false_clean, len(clean)),
        stop_latency_ms={"p50": _pct(latencies, 50), "p90": _pct(latencies, 90), "p99": _pct(latencies, 99),
                         "max": _pct(latencies, 100)},
        link_stop_latency_ms={"p50": _pct(link_latencies, 50), "p99": _pct(link_latencies, 99), "max": _pct(link_latencies, 100)},
        by_kind=rows,
        misses=[brief(r) for r in runs if r.outcome == "missed"],
        false_stop_runs=[brief(r) for r in runs if r.outcome == "false_stop"],
        hung_runs=[brief(r) for r in runs if r.outcome == "hung"],
        wall_s=None if wall_s is None else round(wall_s, 1),
        runs_per_hour=None if not wall_s else round(len(runs) * 3600.0 / wall_s),
    )


def table_lines(s: FaultSummary) -> list[str]:
    """The summary as a Markdown table, as the terminal shows it."""
    out = [f"fault campaign: {s.runs} runs ({s.fault_runs} with a fault, {s.fault_free_runs} without), seed {s.seed}, "
           f"{s.delay_ms:g} ms each way" + (f" +{s.jitter_ms:g} ms jitter" if s.jitter_ms else "")
           + (f", loss {s.drop_probability:g}" if s.drop_probability else "") + f", {s.program} ({s.mode})", "",
           "| fault | runs | caught | missed | absorbed | false stops | hung | latency p50 / p99 (ms) | stop distance p50 / max (mm) |",
           "|---|---|---|---|---|---|---|---|---|"]

    def fmt(v) -> str:
        return "-" if v is None else f"{v:g}"

    for r in s.by_kind:
        out.append(f"| {r.kind} | {r.runs} | {r.caught} | {r.missed} | {r.absorbed} | {r.false_stops} | {r.hung} | "
                   f"{fmt(r.latency_ms['p50'])} / {fmt(r.latency_ms['p99'])} | "
                   f"{fmt(r.stop_distance_mm['p50'])} / {fmt(r.stop_distance_mm['max'])} |")
    upper = "-" if s.missed_rate_upper_95 is None else f"{s.missed_rate_upper_95 * 100:.2g} %"
    fs = "-" if s.false_stop_rate is None else f"{s.false_stop_rate * 100:.2g} %"
    out += ["", f"caught {s.caught}, missed {s.missed} (95 % upper bound {upper} of fault runs), absorbed {s.absorbed}, "
                f"false stops {s.false_stops} ({fs} of fault-free runs), hung {s.hung}",
            f"stop latency after the physical onset (world and robot faults): p50 {fmt(s.stop_latency_ms['p50'])} ms, "
            f"p99 {fmt(s.stop_latency_ms['p99'])} ms, max {fmt(s.stop_latency_ms['max'])} ms; link faults (silence "
            f"contract): p50 {fmt(s.link_stop_latency_ms['p50'])} ms, max {fmt(s.link_stop_latency_ms['max'])} ms"]
    if s.wall_s:
        out.append(f"{s.wall_s:g} s wall, {s.runs_per_hour:g} runs an hour")
    for m in s.misses:
        out.append(f"MISSED seed {m['seed']}: {m['fault']}: {m['why']} (replay: teleprog trial faults --replay {m['seed']})")
    for m in s.hung_runs:
        out.append(f"HUNG seed {m['seed']}: {m['fault']}: {m['why']}")
    for m in s.false_stop_runs:
        out.append(f"FALSE STOP seed {m['seed']}: {m['fault']}: {m['why']}")
    return out
