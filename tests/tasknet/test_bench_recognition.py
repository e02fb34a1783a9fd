"""``teleprog bench recognition`` as a user runs it: a small run of the benchmark that recognition
keeps up with driving (the figures are recorded in ``benchmarks/README.md``)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def bench(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "server.cli", "bench", "recognition", *args],
                          capture_output=True, text=True, timeout=240, cwd=ROOT)


def test_bench_recognition_json_small_run() -> None:
    proc = bench("--repeat", "1", "--check-samples", "60", "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["actions"] == ["grasp(PEG)", "part(PEG,HOLE1)", "mate(PEG,HOLE2)", "release(PEG)"]
    assert doc["samples"] > 1000 and doc["check_samples"] == 60
    assert doc["recognition_us"]["n"] == doc["samples"] and doc["collision_check_us"]["n"] == 60
    for part in ("recognition_us", "full_evaluation_us", "collision_check_us"):
        assert 0 < doc[part]["median"] <= doc[part]["p99"]
    # the context restriction of §3.5.3: most samples ask for fewer atoms than the task space has
    assert doc["atoms_checked"]["median"] < doc["atoms_checked"]["all"] == 7
    assert 0 < doc["pairs_checked"]["mean"] < doc["pairs_checked"]["all"]
    # and most samples keep the last truth: no face moved far enough to cross the tolerance
    assert 0 < doc["samples_measured"] < doc["samples"] / 2
    assert doc["recognition_rate_hz"]["median"] > 60


def test_bench_recognition_fails_when_nothing_is_recognised(tmp_path: Path) -> None:
    program = tmp_path / "approach.tp"
    program.write_text("SPEED 50 %\nMOVES TO (0, -80, 160) mm (180, 0, 0) deg IN WORK\n")
    proc = bench("--program", str(program), "--repeat", "1", "--json")
    assert proc.returncode == 1
    assert proc.stdout == ""
    assert "no action was recognised" in proc.stderr
