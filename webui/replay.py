"""The replay page (``teleprog replay FILE``): a recorded session, read-only, on a timeline.

The 3D view shows what the console showed at the playhead: the virtual arm where the operator
had it, the remote arm as a ghost labelled with the age of the state it showed, the predicted
path of what was sent and not done, and (side by side) a submitted range as planned against the
robot's reported path with the largest gap between them. The panel holds the timeline (a slider
in seconds with a tick per event, Play / Pause, Previous event / Next event, speed), what
happened last, the sent list as it was then, the comparison of each range, and the folder's
other recordings to open. Every click is a call on ``server.replay.player.ReplayPlayer``; the
page draws each moment the player publishes.
"""

from __future__ import annotations

import html
import logging
import threading

import numpy as np
import viser

from server.recording.reader import list_recordings
from server.replay.player import SPEEDS, OpenedReplay, ReplayPlayer
from server.replay.timeline import Moment
from shared.cells.framing import cell_views
from shared.errors import InputError
from webui.ghost import RemoteGhost
from webui.monitor_panel import sent_markdown
from webui.overlays import PredictedPath
from webui.replay_overlay import SideBySide
from webui.scene import CellScene

log = logging.getLogger(__name__)

PANEL_WIDTH = 430
MAX_TICKS = 80  # event ticks on the timeline; more would be a smear
NO_RANGE = "(none)"


def _speed_label(speed: float) -> str:
    return f"{speed:g}x"


class ReplayPage:
    """Everything the page shows, rebuilt when another recording is opened."""

    def __init__(self, server: viser.ViserServer, player: ReplayPlayer) -> None:
        self.server = server
        self.player = player
        self._lock = threading.RLock()  # a reopen rebuilds and draws under it
        self._syncing = False
        self.build(player.opened)
        player.on_moment(self.show)
        player.on_open(self._reopened)

    # -- building -------------------------------------------------------------------------------
    def build(self, opened: OpenedReplay) -> None:
        server, timeline, cell = self.server, opened.timeline, opened.cell
        server.gui.configure_theme(show_share_button=False, control_width="large")
        server.gui.set_panel_label("teleprog replay (read-only)")
        front = cell_views(cell).front  # the console's default camera: the cell's work (shared.cells.framing)
        server.initial_camera.look_at = tuple(front.look_at)
        server.initial_camera.position = tuple(front.position)
        self.scene = CellScene(server, cell)
        self.ghost = RemoteGhost(server, cell.robot, cell.world_T_base)
        self.path = PredictedPath(server)
        self.side = SideBySide(server)
        gui = server.gui
        r = opened.recording
        about = f"**Replay** (read-only): `{html.escape(opened.path.name)}`  \ncell {cell.name}, {timeline.duration_s:.1f} s"
        self.about = gui.add_markdown(about)
        label = "Damaged" if r.damage else "Being written" if r.writing else "Cut off" if not r.complete else "Note"
        self.problem = gui.add_markdown(f"**{label}:** {html.escape(r.problem, quote=False)}" if r.problem else "", visible=bool(r.problem))
        ticks = [round((m.t_ns - timeline.start) * 1e-9, 2) for m in timeline.marks][:MAX_TICKS]
        duration = max(round(timeline.duration_s, 2), 0.01)
        self.time = gui.add_slider("Time (s)", min=0.0, max=duration, step=0.01, initial_value=0.0,
                                   marks=tuple(sorted(set(ticks))) or None)
        self.time.on_update(self._on_time)
        self.previous = gui.add_button("Previous event", icon=viser.Icon.PLAYER_TRACK_PREV)
        self.play = gui.add_button("Play", icon=viser.Icon.PLAYER_PLAY)
        self.next = gui.add_button("Next event", icon=viser.Icon.PLAYER_TRACK_NEXT)
        self.previous.on_click(lambda _e: self.player.step(-1))
        self.next.on_click(lambda _e: self.player.step(1))
        self.play.on_click(self._on_play)
        self.speed = gui.add_dropdown("Speed", [_speed_label(s) for s in SPEEDS], initial_value=_speed_label(1.0))
        self.speed.on_update(self._on_speed)
        self.now = gui.add_markdown("")
        with gui.add_folder("Sent list then"):
            self.sent = gui.add_markdown("Nothing sent yet.")
        with gui.add_folder("Planned against reported"):
            names = [NO_RANGE] + [f"Range {c.index + 1}" for c in opened.comparisons]
            self.range = gui.add_dropdown("Submitted range", names, initial_value=names[1] if len(names) > 1 else NO_RANGE)
            self.range.on_update(lambda _e: self._draw_range())
            self.compare = gui.add_markdown("")
        with gui.add_folder("Recordings", expand_by_default=False):
            found = [info.name for info in list_recordings(self.player.folder)] or [opened.path.name]
            self.recordings = gui.add_dropdown("Recording", found, initial_value=opened.path.name if opened.path.name in found else found[0])
            self.open_button = gui.add_button("Open recording")
            self.open_button.on_click(self._on_open)
            self.open_result = gui.add_markdown("")
        self._opened = opened
        self._draw_range()
        try:
            gui.main_panel.dock_right()
            gui.main_panel.set_width(PANEL_WIDTH)
        except Exception:  # noqa: BLE001 - placement is cosmetic
            log.exception("could not dock the replay panel")
        self.show(self.player.moment())

    def _reopened(self, opened: OpenedReplay) -> None:
        with self._lock:
            self.server.scene.reset()
            self.server.gui.reset()
            self.build(opened)

    # -- clicks -> calls ------------------------------------------------------------------------
    def _on_time(self, event: viser.GuiEvent) -> None:
        if event.client is None or self._syncing:
            return  # our own drawing of the playhead
        self.player.seek(float(event.target.value), pause=True)

    def _on_play(self, _event: viser.GuiEvent) -> None:
        if self.player.playing:
            self.player.pause()
        else:
            self.player.play()

    def _on_speed(self, event: viser.GuiEvent) -> None:
        if event.client is None:
            return
        self.player.set_speed(float(self.speed.value.rstrip("x")))

    def _on_open(self, _event: viser.GuiEvent) -> None:
        try:
            self.player.open(self.recordings.value)
        except InputError as exc:
            self.open_result.content = f"**Cannot open:** {html.escape(str(exc))}"

    # -- drawing ---------------------------------------------------------------------------------
    def _draw_range(self) -> None:
        wanted = self.range.value
        comparison = next((c for c in self._opened.comparisons if f"Range {c.index + 1}" == wanted), None)
        self.side.show(comparison)
        self.compare.content = "  \n".join(comparison.lines()) if comparison is not None else (
            "No range was submitted." if not self._opened.comparisons else "Choose a range to draw its plan and its run.")

    def show(self, m: Moment) -> None:
        """Draw the moment ``m`` (the player's thread, or a click's)."""
        with self._lock:
            self._syncing = True
            try:
                self.time.value = round(m.t_s, 2)
            finally:
                self._syncing = False
            if m.virtual_q is not None:
                self.scene.show_arm(np.asarray(m.virtual_q))
            self.scene.show_objects({k: np.asarray(v) for k, v in m.object_poses.items()})
            if m.remote_q is not None:
                what = m.remote_state or ""
                if m.remote_statement:
                    what += f", #{m.remote_statement}"
                self.ghost.show(np.asarray(m.remote_q), m.remote_age_s, what)
            else:
                self.ghost.hide()
            self.path.show(np.asarray(m.predicted) if len(m.predicted) else None)
            self.play.label = "Pause" if self.player.playing else "Play"
            self.play.icon = viser.Icon.PLAYER_PAUSE if self.player.playing else viser.Icon.PLAYER_PLAY
            duration = self._opened.timeline.duration_s
            lines = [f"**t = {m.t_s:.2f} s** of {duration:.2f} s"
                     + (f", regime {m.regime}" if m.regime else "") + (f", link {m.link_status}" if m.link_status else "")]
            if m.last_mark is not None:
                at = (m.last_mark.t_ns - self._opened.timeline.start) * 1e-9
                lines.append(f"last event ({at:.2f} s): {html.escape(m.last_mark.text)}")
            if m.remote_q is not None:
                lines.append(f"ghost: {html.escape(self.ghost.label.text)}")
            else:
                lines.append("ghost: no telemetry yet")
            if m.dropped:
                lines.append(f"the recorder had dropped {m.dropped} messages by then")
            self.now.content = "  \n".join(lines)
            self.sent.content = sent_markdown(m.sent, m.t_ns * 1e-9) if m.sent is not None else "Nothing sent yet."


def build_replay_page(server: viser.ViserServer, player: ReplayPlayer) -> ReplayPage:
    """The replay page for ``player`` on ``server`` (call once, before clients load)."""
    return ReplayPage(server, player)
