"""The console page in headless Chromium: the arm in its cell, driven with the mouse."""

from __future__ import annotations

import numpy as np
import pytest

from support import wait_for

pytestmark = pytest.mark.browser




def test_slider_drag_moves_the_joint(console, page, tmp_path) -> None:
    before = console.api("GET", "/api/state").json()["q_deg"]
    page.goto(console.url + "/")
    page.wait_for_selector("canvas", timeout=30_000)
    label = page.get_by_text("J1", exact=True).first
    label.wait_for(timeout=30_000)
    # the joint sliders are the page's sliders in joint order: drag J1's thumb with the mouse
    thumbs = page.locator("[role='slider']")
    assert thumbs.count() == 6
    thumb = thumbs.nth(0)
    assert float(thumb.get_attribute("aria-valuenow")) == pytest.approx(before[0], abs=0.1)
    box = thumb.bounding_box()
    assert box is not None
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 40, y, steps=8)
    page.mouse.up()
    after = wait_for(lambda: (s := console.api("GET", "/api/state").json()["q_deg"]) and abs(s[0] - before[0]) > 1.0 and s)
    assert after[0] > before[0]  # dragged to the right: a larger angle
    np.testing.assert_allclose(after[1:], before[1:], atol=1e-9)  # only J1 turned
    page.screenshot(path=str(tmp_path / "console.png"))


def test_page_shows_the_cell(console, page) -> None:
    page.goto(console.url + "/")
    page.wait_for_selector("canvas", timeout=30_000)
    for text in ("Drive", "Moving part", "J6"):
        page.get_by_text(text, exact=True).first.wait_for(timeout=30_000)
    health = console.api("GET", "/api/health").json()
    assert health == {"status": "ok", "cell": "peg_in_hole", "robot": "puma562"}
