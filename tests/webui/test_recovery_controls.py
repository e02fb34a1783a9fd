"""What the header and the Submit tab offer follows what the robot and the program are (issue
37's smaller points): Resume, Skip and Abort are on only when they can act on something, the
robot's answer to STOP goes once the robot leaves the hold, the sent list shows the newest first,
and Submit is off with nothing to submit."""

from __future__ import annotations

import time

import pytest

from server.console import LinkChanged, LinkView, SentListView, SentStatus, SentView
from shared.language.parser import parse_program
from webui.monitor_panel import sent_markdown




def _link(state: str | None, *, pending: list[str] | None = None, connected: bool = True) -> LinkView:
    return LinkView(configured=True, connected=connected, robot_state=state, status="live" if connected else "down",
                    recovery_pending=pending or [])


@pytest.mark.parametrize("state, on", [
    ("idle", set()), ("running", {"Skip", "Abort"}), ("stopped", {"Resume", "Skip", "Abort"}),
    ("fault", {"Resume", "Skip", "Abort"}), (None, set()),
])
def test_recovery_buttons_are_on_only_when_they_can_act(built_console, state, on) -> None:
    session, page = built_console
    session.bus.emit([LinkChanged(link=_link(state))])
    assert {name for name, button in page.status.recovery.items() if not button.disabled} == on
    session.bus.emit([LinkChanged(link=_link("stopped", connected=False))])  # a lost link: nothing to act on
    assert all(button.disabled for button in page.status.recovery.values())


def test_the_answer_to_stop_goes_once_the_robot_leaves_the_hold_even_to_idle(built_console) -> None:
    session, page = built_console
    header = page.stop
    header._sent_at = time.monotonic()  # noqa: SLF001 - a STOP left (press_stop needs a robot)
    session.bus.emit([LinkChanged(link=_link("idle", pending=["stop"]))])
    session.bus.emit([LinkChanged(link=_link("stopped"))])  # the robot's acknowledgement is back
    assert header.ack.content.startswith("**Robot confirmed STOP**")
    session.bus.emit([LinkChanged(link=_link("stopped"))])
    assert header.ack.content.startswith("**Robot confirmed STOP**")  # it stands while the robot holds
    session.bus.emit([LinkChanged(link=_link("idle"))])  # resumed with nothing to run
    assert header.ack.content == ""


def test_the_sent_list_shows_the_newest_first() -> None:
    statements = parse_program("DRIVE J1 TO 1 deg\nDRIVE J1 TO 2 deg\nDRIVE J1 TO 3 deg").statements
    items = [SentView(id=i + 1, number=i + 1, text=f"DRIVE J1 TO {i + 1} deg", statement=st, status=status, submitted_at=0.0)
             for i, (st, status) in enumerate(zip(statements, (SentStatus.DONE, SentStatus.RUNNING, SentStatus.RECEIVED)))]
    text = sent_markdown(SentListView(items=items, pending=2), now=1.0)
    lines = text.split("  \n")
    assert lines[0] == "3 sent, 2 pending"
    assert [line.split()[0] for line in lines[1:]] == ["#3", "#2", "#1"]  # what waits, what runs, what ran


def test_submit_is_off_with_nothing_to_submit(built_console) -> None:
    session, page = built_console
    assert session.program.view().empty_index == 0  # the session starts with an empty program
    page.monitor.show_program(session.program.view())  # what a connected page is sent
    assert page.monitor.submit.disabled and page.monitor.needs.button.disabled  # Submit range, Preview and submit
    page.monitor.show_program(session.program.insert(parse_program("DRIVE J1 TO 5 deg").statements[0]))
    assert not page.monitor.submit.disabled and not page.monitor.needs.button.disabled


def test_the_regime_menu_names_regimes_in_the_operators_words(built_console) -> None:
    """The menu offers ONLINE / OFFLINE / SINGLE STEP with their zones, never the API's raw values."""
    session, page = built_console
    options = list(page.status.regime.options)
    assert options == ["auto (by zone)", "ONLINE (free zone)", "OFFLINE (quasi-operation)", "SINGLE STEP (operation)"]
    from server.console import Regime

    session.modes.set_regime_override(Regime.QUASI)
    page.status.show_regime(session.modes.regime_view())
    assert page.status.regime.value == "OFFLINE (quasi-operation)"
    session.modes.set_regime_override(None)


def test_the_task_nets_labels_never_draw_smaller_than_11_px() -> None:
    """Scaled to a narrow panel, the net's 12 px labels shrank to about 6 px; it now keeps a
    minimum width at which they read at least 11 px and scrolls sideways past it."""
    import re

    from shared.paths import ASSETS_DIR
    from shared.tasknet.pnml import read_pnml
    from webui.task_panel import net_picture

    paths = sorted((ASSETS_DIR / "tasks").glob("*.pnml"))
    assert len(paths) >= 3
    for path in paths:
        net = read_pnml(path)
        html = net_picture(net, [])
        natural = float(re.search(r'viewBox="0 0 ([\d.]+) ', html).group(1))
        least = float(re.search(r'min-width:([\d.]+)px', html).group(1))
        assert 'font-size="12"' in html and least / natural * 12 >= 11 - 0.05, (path.name, least, natural)
        assert 'data-task-net style="width:100%;overflow:auto"' in html  # it scrolls past that
