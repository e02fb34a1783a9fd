"""The CLI: machine-readable output, one-line errors, exit codes, no tracebacks."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from shared.robots.loader import load_robot


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "server.cli", *args], capture_output=True, text=True, timeout=120)


def test_fk_json_for_the_puma() -> None:
    out = run("kin", "fk", "--robot", "puma562", "--deg", "10", "-20", "30", "40", "50", "60", "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["unit"] == "m"
    expected = load_robot("puma562").fk(np.radians([10, -20, 30, 40, 50, 60]))
    np.testing.assert_allclose(data["position"], expected[:3, 3], atol=1e-12)
    np.testing.assert_allclose(data["rotation"], expected[:3, :3], atol=1e-12)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["kin", "fk", "--robot", "nobot", "--deg", "0"], "unknown robot 'nobot'"),
        (["kin", "fk", "--robot", "puma562", "--deg", "0", "0"], "6 joints, got 2"),
        (["kin", "fk", "--robot", "puma562", "--deg", "0", "0", "0", "0", "0", "999"], "outside its range"),
        (["kin", "ik", "--robot", "puma562", "--xyz", "5", "0", "0", "--rpy", "0", "0", "0"], "no inverse-kinematics solution"),
        (["kin", "ik", "--robot", "puma562", "--xyz", "0.5", "0", "0"], "--rpy"),
    ],
)
def test_errors_are_one_line_without_traceback(args: list[str], message: str) -> None:
    out = run(*args)
    assert out.returncode == 1
    assert message in out.stderr
    assert "Traceback" not in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_usage_errors_exit_2() -> None:
    out = run("kin", "fk", "--deg", "0")
    assert out.returncode == 2
    assert "--robot" in out.stderr


def test_ik_json_contains_the_configuration_it_came_from() -> None:
    q = [10.0, -30.0, 150.0, 20.0, 40.0, -30.0]
    fk = json.loads(run("kin", "fk", "--robot", "puma562", "--deg", *map(str, q), "--json").stdout)
    from shared.spatial import matrix_to_rpy

    rpy = np.degrees(matrix_to_rpy(np.array(fk["rotation"])))
    out = run("kin", "ik", "--robot", "puma562", "--xyz", *map(str, fk["position"]), "--rpy", *map(str, rpy), "--json")
    assert out.returncode == 0, out.stderr
    solutions = np.array(json.loads(out.stdout)["solutions"])
    assert np.min(np.max(np.abs(solutions - q), axis=1)) < 1e-4


@pytest.mark.parametrize(
    ("variable", "value", "args", "field"),
    [
        ("TELEPROG_SEDIMENTATION_N", "abc", ("up", "--sedimentation", "--port", "0"), "sedimentation_n"),
        ("TELEPROG_ROBOT_PORT", "xyz", ("robot", "--port", "0"), "port"),
    ],
)
def test_a_bad_setting_in_the_environment_is_one_line(variable, value, args, field, monkeypatch) -> None:
    monkeypatch.setenv(variable, value)
    out = run(*args)
    assert out.returncode == 1
    assert "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    line = lines[0]
    assert line.startswith("teleprog: error:") and field in line and repr(value) in line


def test_every_subcommand_prints_its_help() -> None:
    """Every command and sub-command's --help formats (a stray % in a help text used to end
    ``teleprog trial --help`` in a traceback)."""
    import argparse

    from server.cli import build_parser

    def walk(parser: argparse.ArgumentParser) -> int:
        parser.format_help()
        count = 1
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for child in action.choices.values():
                    count += walk(child)
        return count

    assert walk(build_parser()) > 20
