"""``webui.ghost.RemoteGhost`` on a real viser server: a repeated telemetry pose is not drawn
again (no forward kinematics, no node updates), while a new pose, a new label text and a show
after a hide are."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from server.viser_host import start_viser
from shared.robots.loader import load_robot
from webui.ghost import RemoteGhost


class CountingRobot:
    """The robot, counting the forward-kinematics calls the ghost makes."""

    def __init__(self, robot) -> None:
        self._robot = robot
        self.calls = 0

    def __getattr__(self, name: str):
        return getattr(self._robot, name)

    def link_poses(self, q, data=None):
        self.calls += 1
        return self._robot.link_poses(q, data)


@pytest.fixture
def ghost() -> Iterator[tuple[RemoteGhost, CountingRobot]]:
    server = start_viser()
    robot = CountingRobot(load_robot("puma562"))
    try:
        yield RemoteGhost(server, robot, np.eye(4)), robot
    finally:
        server.stop()


def test_a_repeated_pose_is_not_drawn_again_but_its_label_follows(ghost) -> None:
    g, robot = ghost
    q = np.radians([10.0, -20.0, 30.0, 0.0, 15.0, 0.0])
    g.show(q, 0.2, "idle")
    assert robot.calls == 1 and g.visible
    first = np.array(g._links[-1].position)
    g.show(q.copy(), 0.24, "idle")  # the same label text ("0.2 s ago"): nothing to send
    assert robot.calls == 1
    g.show(q.copy(), 0.9, "idle")
    assert robot.calls == 1 and g.label.text == "remote arm as of 0.9 s ago (idle)"
    moved = q + np.radians([5.0, 0, 0, 0, 0, 0])
    g.show(moved, 0.1, "moving")
    assert robot.calls == 2
    assert not np.allclose(np.array(g._links[-1].position), first)
    assert g.label.text == "remote arm as of 0.1 s ago (moving)"


def test_a_show_after_a_hide_draws_again(ghost) -> None:
    g, robot = ghost
    q = np.zeros(6)
    g.show(q, 0.1)
    g.hide()
    assert not g.visible and not g._links[1].visible
    g.show(q, 0.1)
    assert robot.calls == 2 and g.visible and g._links[1].visible and g.label.visible
    g.show(None, None)
    assert not g.visible
