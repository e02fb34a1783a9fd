"""A console killed with SIGKILL while its robot runs a program, and started again (issue 36):
before anybody resumes, the new console's sent list shows what ran, what runs and what the robot
holds, under the robot's numbers; Resume runs exactly what it shows, and the next submission is
numbered after the old ones (the kept identity goes on from the robot's counters, never taken
for a repeat of the dead process's first communication). Real robot, link and console processes."""

from __future__ import annotations

import signal

from support import ServerProcess, start_console, stop_process, wait_for

PROGRAM = [f"DRIVE J1 TO {angle} deg WITH SPEED 5 %" for angle in (6, 0, 6, 0, 6, 0, 6, 0, 6, 0)]


def _sent(console) -> list[dict]:
    return console.call("GET", "/api/sent")["items"]


def test_a_console_killed_mid_program_shows_what_ran_runs_and_is_held_when_it_starts_again(tmp_path) -> None:
    robot = ServerProcess(tmp_path, "robot", "--seed", "2").start()
    link = ServerProcess(tmp_path, "link", "--robot", robot.url, "--delay-ms", "200").start()
    record = tmp_path / "recordings"  # the console's identity is kept here, across its restart
    first = start_console(tmp_path, "--robot-url", link.url, "--record", str(record), name="first")
    second = None
    try:
        wait_for(lambda: first.api("GET", "/api/link").json()["status"] == "live", timeout=60, what="a live link")
        first.call("PUT", "/api/regime", {"regime": "free"})
        first.api("POST", "/api/program/upload?filename=ten.tp", content="\n".join(PROGRAM).encode())
        first.call("POST", "/api/submit", {"start": 0, "stop": len(PROGRAM)})
        wait_for(lambda: [s["status"] for s in _sent(first)][:3] == ["done"] * 3, timeout=120, what="three statements done")
        first.proc.send_signal(signal.SIGKILL)  # no goodbye: the robot hears silence
        first.proc.wait()
        halted = wait_for(lambda: robot.health()["halted"] and robot.health(), timeout=30, what="the robot's silence halt")
        running, queued = halted["current"], halted["queued"]
        assert halted["numbered"] == len(PROGRAM) and queued >= 1

        second = start_console(tmp_path, "--robot-url", link.url, "--record", str(record), name="second")
        items = wait_for(lambda: len(s := _sent(second)) == len(PROGRAM) and s, timeout=60, what="the robot's account")
        assert [s["number"] for s in items] == list(range(1, len(PROGRAM) + 1))
        assert [s["text"] for s in items] == PROGRAM and all(s["before"] for s in items)
        held_from = len(PROGRAM) - queued + 1  # the queued ones are the last, in order
        for s in items:
            expected = ("running" if s["number"] == running else "received" if s["number"] >= held_from else "done")
            assert s["status"] == expected, (s, running, queued)
        assert second.call("GET", "/api/link")["halted"]  # it says the robot holds by itself
        assert robot.health()["current"] == running and robot.health()["queued"] == queued  # nothing moved on

        second.call("POST", "/api/robot/resume")
        wait_for(lambda: all(s["status"] == "done" for s in _sent(second)), timeout=120, what="every statement done")
        assert robot.health()["numbered"] == len(PROGRAM)  # Resume ran what was shown; nothing was sent again

        second.call("PUT", "/api/regime", {"regime": "free"})
        second.api("POST", "/api/program/upload?filename=one.tp", content=b"DRIVE J1 TO 3 deg\n")
        second.call("POST", "/api/submit", {"start": 0, "stop": 1})
        new = wait_for(lambda: (s := _sent(second)[-1])["status"] == "done" and s, timeout=60, what="the new statement done")
        assert new["number"] == len(PROGRAM) + 1 and not new["before"]
        assert robot.health()["numbered"] == len(PROGRAM) + 1
    finally:
        for console in (first, second):
            if console is not None:
                stop_process(console.proc)
        link.stop()
        robot.stop()

