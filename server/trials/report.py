"""The approach trial's results on the terminal (a Markdown table, so it pastes into a README)
and on disk: ``results.json`` (the ``--json`` document) and ``results.csv`` (one row per run and
mode)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from server.trials.kind_results import KindReport, KindSummary
from server.trials.results import ApproachReport, ApproachSummary

CSV_COLUMNS = (
    "run", "world_seed", "mode", "delay_ms", "one_way_delay_s", "statements", "virtual_s", "total_s",
    "reported_total_s", "robot_total_s", "mean_statement_s", "mean_submit_to_report_s", "lag_s",
    "statement_s", "success", "failure",
)


def _s(value: float | None, digits: int = 2) -> str:
    return "-" if value is None else f"{value:.{digits}f} s"


def _iqr(iqr: tuple[float, float] | None) -> str:
    return "-" if iqr is None else f"{iqr[0]:.2f}-{iqr[1]:.2f} s"


def table_lines(summary: ApproachSummary) -> list[str]:
    s, d = summary, summary.delay_ms / 1e3
    thesis = s.thesis
    lines = [
        f"approach trial ({s.clock} time): {s.runs_succeeded} of {s.runs_total} run(s) succeeded, delay {s.delay_ms:g} ms each way, "
        f"{s.statements} statements, virtual time {_s(s.virtual_s)}, mean statement time {_s(s.mean_statement_s)}",
        "",
        f"| mode | measured (median) | IQR | predicted | thesis ({thesis['delay_ms'] / 1e3:g} s delay) |",
        "|---|---|---|---|---|",
        f"| online | {_s(s.online_total_s)} | {_iqr(s.online_total_iqr_s)} | {_s(s.predicted_online_s)} = virtual "
        f"{_s(s.virtual_s)} + delay {d:.2f} s | {thesis['online_total_s']:g} s |",
        f"| step by step | {_s(s.step_by_step_total_s)} | {_iqr(s.step_by_step_total_iqr_s)} | "
        f"{_s(s.predicted_step_by_step_s)} = {s.statements} x (2 x {d:.2f} + {_s(s.mean_statement_s)}) | "
        f"{thesis['step_by_step_total_s']:g} s |",
        f"| ratio step by step / online | {'-' if s.ratio is None else f'{s.ratio:.2f}'} | | "
        f"{_ratio(s.predicted_step_by_step_s, s.predicted_online_s)} | {thesis['ratio']:.1f} |",
        "",
        f"online: the telerobot lags the virtual robot by {_s(s.online_lag_s)} at the last statement; "
        f"its last report arrives {_s(s.online_reported_total_s)} after the first submit",
    ]
    for r in s.runs:
        if r.success and r.online and r.step_by_step:
            lines.append(f"run {r.index} (world seed {r.world_seed}): online {_s(r.online.total_s)}, "
                         f"step by step {_s(r.step_by_step.total_s)}, one-way delay measured {_s(r.one_way_delay_s, 3)}")
        else:
            lines.append(f"run {r.index} (world seed {r.world_seed}): FAILED: {r.failure}")
    return lines


def _ratio(num: float | None, den: float | None) -> str:
    return "-" if not num or not den else f"{num / den:.2f}"


def write_results(report: ApproachReport, out: Path) -> list[Path]:
    """``out/results.json`` and ``out/results.csv`` (one row per run and mode); the paths written."""
    return _write(report, out, CSV_COLUMNS, _approach_rows(report))


def _approach_rows(report: ApproachReport):
    for run in report.summary.runs:
        modes = [m for m in (run.online, run.step_by_step) if m is not None]
        if not modes:
            yield {"run": run.index, "world_seed": run.world_seed, "mode": "", "delay_ms": run.delay_ms,
                   "success": False, "failure": run.failure}
        for m in modes:
            yield {
                "run": run.index, "world_seed": run.world_seed, "mode": m.mode, "delay_ms": run.delay_ms,
                "one_way_delay_s": run.one_way_delay_s, "statements": len(m.statements), "virtual_s": m.virtual_s,
                "total_s": m.total_s, "reported_total_s": m.reported_total_s, "robot_total_s": m.robot_total_s,
                "mean_statement_s": m.mean_statement_s, "mean_submit_to_report_s": m.mean_submit_to_report_s,
                "lag_s": m.lag_s, "statement_s": ";".join("" if t.statement_s is None else f"{t.statement_s:.4f}"
                                                          for t in m.statements),
                "success": m.success and run.success, "failure": m.failure or ("" if run.success else run.failure),
            }


def _write(report, out: Path, columns: tuple[str, ...], rows) -> list[Path]:
    """The ``--json`` document as ``out/results.json`` and ``rows`` as ``out/results.csv``."""
    out.mkdir(parents=True, exist_ok=True)
    json_path, csv_path = out / "results.json", out / "results.csv"
    json_path.write_text(json.dumps(report.model_dump(mode="json"), indent=1) + "\n", encoding="utf-8")
    with csv_path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    return [json_path, csv_path]

# -- the grasp, extract, insert and transfer trials ------------------------------------------------
KIND_CSV_COLUMNS = (
    "kind", "mode", "run", "world_seed", "clock", "delay_ms", "reached", "success", "total_s", "robot_total_s",
    "virtual_s", "alarms", "statements", "statement_s", "robot_run_s", "failure",
)


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.0f} %"


def world_line(world: dict[str, object]) -> str:
    physics = world.get("physics") if isinstance(world.get("physics"), dict) else {}
    friction = world.get("friction") if world.get("friction") is not None else physics.get("friction", "-")
    clearance = world.get("clearance_mm")
    fit = f"{clearance:g} mm" if isinstance(clearance, (int, float)) else "the cell's"
    return (f"world ({world.get('engine', 'mujoco')}): plate and holes off the model by up to "
            f"{world.get('object_offset_mm', 0):g} mm, force noise {world.get('force_noise_n', 0):g} N, grasp tilt "
            f"{world.get('grasp_tilt_deg', 0):g} deg, friction {friction}, clearance {fit}")


def kind_table_lines(summary: KindSummary) -> list[str]:
    s = summary
    lines = [
        f"{s.kind} trial ({s.clock} time): {len(s.runs)} run(s), delay {s.delay_ms:g} ms each way, seed {s.seed}",
        world_line(s.world),
        "",
        "| mode | runs | reached | succeeded | success (Wilson 95 %) | thesis | time, median (IQR) | alarms |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for m in s.modes:
        ci = "" if m.success_wilson95 is None else f" ({_pct(m.success_wilson95[0])}-{_pct(m.success_wilson95[1])})"
        lines.append(f"| {m.mode} | {m.runs} | {m.reached} | {m.succeeded} | {_pct(m.success_rate)}{ci} | "
                     f"{_pct(m.thesis_success_rate)} | {_s(m.total_s)} ({_iqr(m.total_iqr_s)}) | {m.alarms} |")
    for m in s.modes:
        for cause, count in sorted(m.failures.items(), key=lambda kv: -kv[1]):
            lines.append(f"{m.mode}: {count} x {cause}")
    return lines


def write_kind_results(report: KindReport, out: Path) -> list[Path]:
    """``out/results.json`` and ``out/results.csv`` (one row per run); the paths written."""
    return _write(report, out, KIND_CSV_COLUMNS, _kind_rows(report))


def _kind_rows(report: KindReport):
    for r in report.summary.runs:
        yield {
            "kind": r.kind, "mode": r.mode, "run": r.index, "world_seed": r.world_seed, "clock": r.clock,
            "delay_ms": r.delay_ms, "reached": r.reached, "success": r.success, "total_s": r.total_s,
            "robot_total_s": r.robot_total_s, "virtual_s": r.virtual_s, "alarms": r.alarms,
            "statements": len(r.statements),
            "statement_s": ";".join("" if t.statement_s is None else f"{t.statement_s:.4f}" for t in r.statements),
            "robot_run_s": ";".join("" if t.robot_run_s is None else f"{t.robot_run_s:.4f}" for t in r.statements),
            "failure": r.failure or "",
        }
