"""Every page shows who holds control and who asks for it (issue 41), and a page's click that
would change the session while another client holds control is refused with that holder named."""

from __future__ import annotations

import html

from server.console import Caller




def test_the_control_line_follows_requests_hand_overs_and_releases(built_console) -> None:
    session, page = built_console
    line = page.status.control_line
    assert line.content == "Control: **free**: this page may act"
    alice = session.control.request("alice")
    assert line.content == "Control: **alice** holds it; this page observes"
    # the page is an observer now: a click that changes the session is refused, naming the holder
    page.status.actions.run("regime override", lambda: session.modes.set_regime_override(None))
    assert "regime override refused: control is held by 'alice': this page can only observe" in page.status.notice.content
    bob = session.control.ask("bob")
    assert line.content.startswith("Control: **alice** holds it; this page observes · **bob** asks for it (passes at ")
    assert line.content.endswith(" unless alice refuses)")
    session.control.hand_over(Caller("alice", alice.token))
    assert line.content == "Control: **bob** holds it; this page observes"
    assert html.escape("control handed over by 'alice' to 'bob'") in page.status.board.log_html()
    session.control.release(Caller("bob", bob.token))
    assert line.content == "Control: **free**: this page may act"
