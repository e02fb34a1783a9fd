"""``teleprog replay`` in headless Chromium: a real session (telerobot, 200 ms link, console)
is recorded, then replayed; moving the timeline shows the ghost and the sent list as they were
at that moment, the step buttons go from event to event, Play runs to the end, and the page
opens another recording of the folder (a cut-off one says what was lost).

What the page should show is worked out from the file with the reader alone (the statuses'
times, the telemetry frames), not with the replay's own timeline."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from console_page import ConsolePage
from playwright.sync_api import Page
from support import PAGE_DPR, RunningConsole, record_three_statements, start_console, start_served, stop_process, wait_for

from server.recording import records
from server.recording.reader import read_recording

pytestmark = pytest.mark.browser

GHOST = re.compile(r"remote arm as of (\d+\.\d) s ago \((\w+)(?:, #(\d+))?\)")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One real session's recording: SPEED, a 10 degree DRIVE that takes most of a second, an EVENT."""
    tmp = tmp_path_factory.mktemp("recorded")
    folder = tmp / "recordings"
    console = start_console(tmp, "--delay-ms", "200", "--record", str(folder))
    try:
        record_three_statements(console)
        wait_for(lambda: console.call("GET", "/api/link")["telemetry_received_ago_s"] < 0.3, 10, 0.05, "telemetry")
    finally:
        stop_process(console.proc)
    [path] = sorted(folder.glob("*.mcap"))
    return path


@pytest.fixture(scope="module")
def replay(recorded: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningConsole]:
    data = recorded.read_bytes()
    (recorded.parent / "cut-off.mcap").write_bytes(data[: len(data) * 2 // 3])  # killed mid-session
    running = start_served(tmp_path_factory.mktemp("replay"), "replay", str(recorded), name="replay")
    yield running
    stop_process(running.proc)


def _open(page: Page, replay: RunningConsole) -> ConsolePage:
    ui = ConsolePage(page, replay)
    page.goto(f"{replay.url}/viser/?fixedDpr={PAGE_DPR}")
    page.get_by_role("button", name="Next event").wait_for(timeout=60_000)
    ui.dismiss_notices(wait=5.0)
    return ui


def _at(ui: ConsolePage, t_s: float) -> None:
    """Move the timeline to ``t_s`` (typed into the slider's box) and wait for the page to follow."""
    ui.set_number("Time (s)", round(t_s, 2))
    ui.text_appears(rf"t = {t_s:.2f} s of")


def _sent_list(ui: ConsolePage) -> str:
    text = ui.page.inner_text("body")
    start = text.index("Sent list then")
    return text[start: text.index("Planned against reported", start)]


def test_the_timeline_shows_the_ghost_and_the_sent_list_as_they_were(replay: RunningConsole, recorded: Path,
                                                                      page: Page) -> None:
    r = read_recording(recorded)
    start = r.start_ns
    statuses = [(m.log_time_ns, records.StatementStatus.model_validate(m.data)) for m in r.on(records.STATUS)]
    drive_running = next(t for t, s in statuses if s.text.startswith("DRIVE") and s.status == "running")
    drive_done = next(t for t, s in statuses if s.text.startswith("DRIVE") and s.status == "done")
    submitted = r.on(records.SUBMITTED)[0].log_time_ns
    assert drive_done - drive_running > 0.3e9  # the DRIVE ran long enough to be caught running
    ui = _open(page, replay)

    # before the submission: nothing sent, the ghost idle at the start
    _at(ui, (submitted - start) * 1e-9 - 0.1)
    assert "Nothing sent yet." in _sent_list(ui)
    ghost = GHOST.search(ui.page.inner_text("body"))
    assert ghost and ghost.group(2) == "idle", ui.page.inner_text("body")

    # mid-DRIVE: the sent list as it was, the ghost running #2 with the age it had then
    mid = (drive_running + drive_done) // 2
    _at(ui, (mid - start) * 1e-9)
    shown = _sent_list(ui)
    assert re.search(r"#1 SPEED 20 %: done", shown) and re.search(r"#2 DRIVE J1 TO \S+ deg: running", shown), shown
    assert re.search(r"#3 EVENT recorded: received", shown), shown
    ghost = wait_for(lambda: (g := GHOST.search(ui.page.inner_text("body"))) and g.group(2) == "running" and g,
                     10, 0.1, "the ghost running")
    assert ghost.group(3) == "2"
    t_page = start + round((mid - start) * 1e-9, 2) * 1e9  # the moment the page went to (its 10 ms steps)
    last_frame = max(m.log_time_ns for m in r.on(records.TELEMETRY) if m.log_time_ns <= t_page)
    link = [m for m in r.on("/events/link") if m.log_time_ns <= t_page][-1]
    expected_age = (t_page - last_frame) * 1e-9 + (link.data["link"]["delay_s"] or r.session.delay_s)
    assert abs(float(ghost.group(1)) - expected_age) <= 0.051, (ghost.group(0), expected_age)
    # the ghost label in the 3D view says the same as the panel's line
    assert len(GHOST.findall(ui.page.inner_text("body"))) >= 1

    # step back to the last event before: the DRIVE starting to run
    ui.click("Previous event")
    ui.text_appears(rf"t = {(drive_running - start) * 1e-9:.2f} s of")
    # the time line and the last-event line are two elements of the page, drawn one after the other
    ui.text_appears(r"last event \([\d.]+ s\): #2 DRIVE J1 TO \S+ deg: running")
    ui.click("Next event")
    ui.text_appears(rf"t = {(drive_done - start) * 1e-9:.2f} s of")

    # play to the end at 10x: everything done, the button back to Play
    ui.choose("Speed", "10x")
    ui.click("Play")
    ui.text_appears(rf"t = {r.duration_s:.2f} s of {r.duration_s:.2f} s", timeout=30)
    ui.page.get_by_role("button", name="Play").wait_for(timeout=10_000)
    assert len(re.findall(r": done", _sent_list(ui))) == 3
    # the side-by-side comparison names the largest gaps of the submitted range
    assert re.search(r"largest gap at the same time: [\d.]+ mm at [\d.]+ s", ui.page.inner_text("body"))
    assert re.search(r"largest time gap: #2 DRIVE", ui.page.inner_text("body"))


def test_the_page_opens_another_recording_and_says_what_a_cut_off_one_lost(replay: RunningConsole, recorded: Path,
                                                                           page: Page) -> None:
    listed = replay.call("GET", "/api/sessions")
    assert {s["name"] for s in listed["sessions"]} == {recorded.name, "cut-off.mcap"}
    ui = _open(page, replay)
    ui.page.get_by_text("Recordings", exact=True).click()
    ui.choose("Recording", "cut-off.mcap")
    ui.click("Open recording")
    ui.text_appears(r"Cut off: cut-off\.mcap was cut off", timeout=30)
    assert "cut-off.mcap" in replay.call("GET", "/api/replay")["file"]
    replay.call("POST", "/api/replay/open", {"name": recorded.name})  # leave it as it was
