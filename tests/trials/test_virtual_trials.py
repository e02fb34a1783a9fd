"""The trials in virtual time (``--clock virtual``), their statistics, their executors, and the
agreement of a virtual run with the same seeded run on the real processes.

Virtual runs are the console's sender and planner, the delayed link and the telerobot in this
process on one clock, so a 3 s delay costs nothing here and the thesis's own figures can be
checked at the thesis's delay, to the issue's 15 %.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from robot_sim.settings import WorldSettings
from server.trials.batch import RunSpec, TrialWorld, open_executor, run_all, run_spec, world_seed
from server.trials.kind_results import summarize_kind
from server.trials.kinds import KIND_MODES, pieces, regime_schedule
from server.trials.programs import transfer_program
from server.trials.results import summarize
from server.trials.script import approach_script
from server.trials.stats import wilson_interval
from shared.cells.loader import DEFAULT_CELL
from shared.errors import InputError
from support import PROJECT_DIR

CELL = str(DEFAULT_CELL)
PROGRAM = transfer_program(CELL)
WORLD = TrialWorld()


def _spec(kind: str, mode: str, index: int, *, seed: int = 0, world: TrialWorld = WORLD, delay_ms: float = 3000.0,
          clock: str = "virtual", log_dir: str = "/tmp", schedule=None) -> RunSpec:
    return RunSpec(kind, mode, index, world.settings(world_seed(seed, index)), delay_ms, clock, log_dir,
                   program=PROGRAM, schedule=schedule)


def _cli(*args: str, timeout: float = 240) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "server.cli", "trial", *args], cwd=PROJECT_DIR,
                          capture_output=True, text=True, timeout=timeout)


# -- the approach trial at the thesis's 3 s ---------------------------------------------------------
def test_five_virtual_approach_runs_at_3_s_give_the_thesis_figures_within_15_percent() -> None:
    script = approach_script(CELL)
    specs = [RunSpec("approach", "both", i, WORLD.settings(world_seed(1, i)), 3000.0, "virtual", "/tmp", script=script)
             for i in range(5)]
    runs = [run_spec(s) for s in specs]
    summary = summarize(runs, delay_ms=3000.0, seed=1, cell=CELL, statements=4, clock="virtual")
    assert summary.runs_succeeded == 5
    d = 3.0
    # step by step: n x (2 x delay + mean statement time), each measured
    assert summary.step_by_step_total_s == pytest.approx(4 * (2 * d + summary.mean_statement_s), rel=0.15)
    # online: the virtual robot's time + one delay
    assert summary.online_total_s == pytest.approx(summary.virtual_s + d, rel=0.15)
    # the thesis's 7 s, 28 s and their ratio of 4
    assert summary.online_total_s == pytest.approx(7.0, rel=0.15)
    assert summary.step_by_step_total_s == pytest.approx(28.0, rel=0.15)
    assert summary.ratio == pytest.approx(4.0, rel=0.15)
    for run in runs:
        online = run.online.statements
        assert all(b.submitted_at < a.finished_at for a, b in zip(online, online[1:]))  # streamed, not waited for
        assert all(s.robot_run_s == pytest.approx(s.planned_s, abs=0.02) for s in online)  # the robot ran the plan


# -- real and virtual time agree -------------------------------------------------------------------
@pytest.mark.slow
def test_the_same_seeded_grasp_run_gives_the_same_statuses_and_robot_times_in_real_and_virtual_time(tmp_path) -> None:
    """What is deterministic agrees: the statuses, the plans and the robot's own run times (its
    servo clock, the same in both clocks to a servo period). The real run's wall-clock total is
    not compared with the virtual one: it holds the machine's load (21.7 s against 18.8 s on a
    busy machine); it is only bounded below by the robot's own time, which no load can break."""
    real = run_spec(_spec("grasp", "offline", 2, seed=4, delay_ms=300.0, clock="real", log_dir=str(tmp_path)))
    virtual = run_spec(_spec("grasp", "offline", 2, seed=4, delay_ms=300.0, clock="virtual"))
    assert real.success, real.failure
    assert virtual.success, virtual.failure
    assert [s.text for s in real.statements] == [s.text for s in virtual.statements]
    assert [s.status for s in real.statements] == [s.status for s in virtual.statements] == ["done"] * 4
    assert (real.reached, real.alarms) == (virtual.reached, virtual.alarms) == (True, 0)
    servo_s = 0.01
    for r, v in zip(real.statements, virtual.statements, strict=True):
        assert r.planned_s == pytest.approx(v.planned_s, abs=1e-6)  # the same planner
        assert r.robot_run_s == pytest.approx(v.robot_run_s, abs=servo_s + 1e-9)  # within a servo period
    assert virtual.statements[2].robot_run_s > 8.0  # the 85 mm descent at 10 mm/s until contact ran
    assert real.virtual_s == pytest.approx(virtual.virtual_s, abs=1e-6)
    robot_s = sum(r.robot_run_s for r in real.statements)
    assert robot_s == pytest.approx(sum(v.robot_run_s for v in virtual.statements), abs=len(real.statements) * servo_s + 1e-9)
    assert real.total_s >= robot_s  # the wall clock holds at least the robot's own time


def test_a_virtual_run_is_repeatable_alone_and_its_world_follows_seed_and_index() -> None:
    a = run_spec(_spec("insert", "supervised", 3, seed=5))
    b = run_spec(_spec("insert", "supervised", 3, seed=5))
    assert a == b
    assert a.world_seed == 5003
    other = run_spec(_spec("insert", "supervised", 4, seed=5))
    assert other.world_seed == 5004


# -- the worlds' differences decide the outcomes ---------------------------------------------------
def test_friction_decides_whether_extractions_stick_and_the_failures_say_so() -> None:
    """Dry steel (0.6) holds a peg that the closing fingers pressed on its wall (the plate lies
    off across them) past the extraction's 40 N; oiled (0.1), every peg comes out."""
    dry, oiled = TrialWorld(friction=0.6), TrialWorld(friction=0.1)
    runs = [run_spec(_spec("extract", "supervised", i, world=dry)) for i in range(4)]
    assert all(r.reached for r in runs)
    stuck = [r for r in runs if not r.success]
    assert stuck and all(r.alarms == 1 and "stuck" in r.failure for r in stuck)
    assert all(run_spec(_spec("extract", "supervised", i, world=oiled)).success for i in range(4))
    summary = summarize_kind("extract", ("supervised",), runs, clock="virtual", delay_ms=3000.0, seed=0, cell=CELL,
                             world=dry.model_dump())
    (mode,) = summary.modes
    assert mode.success_rate == (4 - len(stuck)) / 4 and mode.success_wilson95[0] < mode.success_rate
    assert mode.thesis_success_rate == 0.95


def test_an_insertion_whose_setup_failed_is_listed_but_left_out_of_the_rate() -> None:
    world = TrialWorld(friction=0.6)
    stuck = next(i for i in range(8) if not run_spec(_spec("extract", "supervised", i, world=world)).success)
    (run,) = [run_spec(_spec("insert", "supervised", stuck, world=world))]
    assert not run.reached and run.failure.startswith("setup: ") and "stuck" in run.failure
    summary = summarize_kind("insert", ("supervised",), [run], clock="virtual", delay_ms=3000.0, seed=0, cell=CELL,
                             world=world.model_dump())
    assert summary.modes[0].reached == 0 and summary.modes[0].success_rate is None


def test_pegs_far_off_the_model_make_grasps_fail_and_a_model_close_to_the_world_grasps_every_time() -> None:
    far = [run_spec(_spec("grasp", "offline", i, world=TrialWorld(object_offset_mm=20.0))) for i in range(6)]
    assert sum(r.success for r in far) <= 4  # the fingers reach 15 mm beyond the peg's side, the wrist gives 2.5 mm
    assert all("grasp failed" in r.failure for r in far if not r.success)
    near = [run_spec(_spec("grasp", "offline", i)) for i in range(6)]
    assert all(r.success for r in near)


# -- segmented composite control -------------------------------------------------------------------
def test_the_composite_mode_steps_the_contact_statements_and_lies_between_the_single_regimes() -> None:
    texts = PROGRAM.texts()
    schedule = regime_schedule(CELL, texts)
    by_text = dict(zip(texts, schedule, strict=True))
    assert by_text["TASK grasp(peg)"] == "operation"  # the fingers on the peg
    # (the held peg's resting contact with its hole is left out of the zone's distances, so the
    # extraction reads as the gripper's own zone: quasi-operation)
    assert by_text["TASK extract_peg(peg, HOLE1)"] in ("quasi", "operation")
    assert by_text[f"TASK insert_peg(peg, {PROGRAM.to_hole})"] == "operation"
    assert by_text[PROGRAM.texts("approach")[1]] != "operation"  # 70 mm above the peg
    _, plan = pieces("transfer", "composite", PROGRAM, schedule)
    assert sum(len(p.texts) for p in plan) == len(texts)
    assert all(len(p.texts) == 1 for p in plan if p.how == "step")
    times = {}
    for mode in KIND_MODES["transfer"]:
        run = run_spec(_spec("transfer", mode, 0, schedule=tuple(schedule)))
        assert run.success, (mode, run.failure)
        times[mode] = run.total_s
    # streaming everything is fastest and one step at a time slowest; composite steps only near contact
    assert times["free"] < times["composite"] < times["operation"]
    assert times["quasi"] < times["operation"]


# -- statistics --------------------------------------------------------------------------------------
@pytest.mark.parametrize("k, n, lo, hi", [
    (0, 20, 0.0, 0.1611), (20, 20, 0.8389, 1.0), (10, 20, 0.2993, 0.7007), (19, 20, 0.7639, 0.9911), (1, 1, 0.2065, 1.0),
])
def test_wilson_intervals_match_the_published_values(k, n, lo, hi) -> None:
    got = wilson_interval(k, n)
    assert got[0] == pytest.approx(lo, abs=5e-4) and got[1] == pytest.approx(hi, abs=5e-4)


def test_wilson_interval_refuses_impossible_counts_and_has_none_for_no_runs() -> None:
    assert wilson_interval(0, 0) is None
    with pytest.raises(ValueError):
        wilson_interval(3, 2)


# -- executors ---------------------------------------------------------------------------------------
def _table(results) -> dict:
    return summarize_kind("extract", ("supervised",), results, clock="virtual", delay_ms=3000.0, seed=7, cell=CELL,
                          world=WORLD.model_dump()).model_dump()


def test_local_processes_give_the_same_table_as_this_process() -> None:
    specs = [_spec("extract", "supervised", i, seed=7) for i in range(4)]
    with open_executor(1) as inline:
        here = run_all(specs, inline)
    with open_executor(2) as pool:
        there = run_all(specs, pool)
    assert _table(here) == _table(there)
    assert [r.index for r in there] == [0, 1, 2, 3]


@pytest.mark.slow
def test_a_dask_local_cluster_gives_the_same_table_as_the_local_executor() -> None:
    from distributed import LocalCluster

    specs = [_spec("extract", "supervised", i, seed=7) for i in range(4)]
    with open_executor(1) as inline:
        here = run_all(specs, inline)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      host="127.0.0.1") as cluster:
        with open_executor(scheduler=cluster.scheduler_address) as dask:
            there = run_all(specs, dask)
    assert _table(here) == _table(there)


# -- the CLI ------------------------------------------------------------------------------------------
def test_the_cli_runs_a_virtual_batch_and_writes_the_table_and_the_plots(tmp_path) -> None:
    out = tmp_path / "extract"
    done = _cli("extract", "--clock", "virtual", "--runs", "3", "--seed", "2", "--friction", "0.45",
                "--json", "--out", str(out))
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)["summary"]
    assert summary["kind"] == "extract" and summary["clock"] == "virtual" and summary["world"]["friction"] == 0.45
    world = summary["world"]
    assert world["engine"] == "mujoco" and world["physics"]["timestep_ms"] > 0 and world["grasp_tilt_deg"] == 0.0
    assert not any("probability" in key for key in world)  # no setting gives a chance of success
    (mode,) = summary["modes"]
    assert mode["runs"] == 3 and mode["reached"] == 3 and 0 <= mode["succeeded"] <= 3
    assert [r["world_seed"] for r in summary["runs"]] == [2000, 2001, 2002]
    assert json.loads((out / "results.json").read_text())["summary"] == summary
    assert len((out / "results.csv").read_text().strip().splitlines()) == 4
    for png in ("times.png", "success.png"):
        data = (out / png).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000


def test_the_cli_prints_the_table_with_the_thesis_figure() -> None:
    done = _cli("grasp", "--clock", "virtual", "--runs", "2", "--delay-ms", "500")
    assert done.returncode == 0, done.stderr
    assert "| offline | 2 | 2 | 2 | 100 %" in done.stdout and "| 100 % |" in done.stdout
    assert "grasp trial (virtual time)" in done.stdout


@pytest.mark.parametrize("args, says", [
    (["transfer", "--mode", "sideways", "--clock", "virtual"], "--mode sideways: the transfer trial's modes are"),
    (["extract", "--friction", "-1"], "--friction:"),
    (["insert", "--clearance-mm", "-0.01"], "--clearance-mm:"),
    (["insert", "--stick-probability", "0.5"], "unrecognized arguments: --stick-probability"),
    (["grasp", "--workers", "0"], "--workers must be between 1 and"),
    (["grasp", "--scheduler", "localhost:8786"], "--scheduler must be a Dask scheduler address"),
    (["insert", "--cell", "assets/cells/puma562_empty.toml"], "no movable box-shaped object"),
])
def test_bad_trial_options_are_one_line_on_stderr(args, says) -> None:
    done = _cli(*args, timeout=60)
    assert done.returncode != 0
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0] and "Traceback" not in done.stderr, done.stderr


def test_the_transfer_program_for_the_shipped_cell_is_the_shipped_peg_transfer() -> None:
    from shared.language.parser import parse_program, parse_statement
    from shared.paths import ASSETS_DIR

    shipped = [s for s in parse_program((ASSETS_DIR / "programs" / "peg_transfer.tp").read_text()).statements
               if s.kind != "EVENT"]
    assert [parse_statement(t) for t in PROGRAM.texts()] == shipped
    assert (PROGRAM.peg, PROGRAM.from_hole, PROGRAM.to_hole) == ("peg", "HOLE1", "HOLE2")


def test_a_cell_without_a_peg_in_a_hole_is_refused_by_name() -> None:
    with pytest.raises(InputError, match="no movable box-shaped object"):
        transfer_program(PROJECT_DIR / "assets" / "cells" / "puma562_empty.toml")
    with pytest.raises(InputError, match="no movable box-shaped object named 'bolt'"):
        transfer_program(CELL, peg="bolt")


def test_the_world_settings_reach_the_real_telerobot_through_its_environment() -> None:
    from server.trials.session import world_environment

    env = world_environment(WorldSettings(seed=12, object_offset=0.002, grasp_tilt=0.01, friction=0.5))
    assert env["TELEPROG_ROBOT_WORLD__SEED"] == "12" and env["TELEPROG_ROBOT_WORLD__ENGINE"] == "physics"
    assert float(env["TELEPROG_ROBOT_WORLD__OBJECT_OFFSET"]) == 0.002
    assert float(env["TELEPROG_ROBOT_WORLD__GRASP_TILT"]) == 0.01 and float(env["TELEPROG_ROBOT_WORLD__FRICTION"]) == 0.5
    assert "TELEPROG_ROBOT_WORLD__CLEARANCE" not in env  # unset: the cell's own
    from robot_sim.settings import RobotSettings
    import os
    from unittest import mock

    with mock.patch.dict(os.environ, env):
        assert RobotSettings().world == WorldSettings(seed=12, object_offset=0.002, grasp_tilt=0.01, friction=0.5)
