"""The whole operator console in one call: ``build_console(server, session)``.

Creates the scene, the ghost and overlays, and the panels, and routes the session's typed
events to them. Layout, docked right: a header panel on top that never scrolls away (STOP, the
robot's state, the STOP acknowledgement, back away, then the status bar: recovery, link, regime,
display mode, divergence, notices), and below it the control panel with tabs Drive, Program,
Preview, Submit, and Task where the cell has a task model. What the 3D view shows depends on the display mode (thesis 4.3.7):

* teleprogramming: the virtual arm where the operator drives it, the remote arm as a ghost
  with its age, the predicted path of sent statements, red triangles while driving;
* task preview: the virtual arm where the preview player stands, red triangles of that pose;
* telepresence: the arm drawn solid where telemetry reports it and objects where the robot
  reports them (the held one moves with the remote gripper); no ghost, no gizmo.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass

import numpy as np
import viser

from server.console import (
    ArmChanged,
    ArmView,
    CollisionChanged,
    CollisionView,
    ControlChanged,
    DisplayMode,
    DisplayModeChanged,
    DivergenceChanged,
    LinkChanged,
    Notice,
    PlacementChanged,
    PredictedPathChanged,
    PreviewChanged,
    PreviewView,
    ProgramChanged,
    ReadinessChanged,
    RegimeChanged,
    RemoteArmChanged,
    RemoteArmView,
    SentChanged,
    Session,
    TerrainChanged,
)
from server.console.events import TaskChanged, WorkProgress
from server.trials.service import TrialBatches
from shared.cells.framing import cell_views
from webui.actions import Actions
from webui.camera_presets import CameraPresets
from webui.ghost import RemoteGhost
from webui.legend import Legend
from webui.locate_panel import LocatePanel
from webui.monitor_panel import MonitorPanel
from webui.notice_log import NoticeBoard
from webui.overlays import CollisionOverlay, PredictedPath
from webui.panels import DrivePanel
from webui.preview_panel import PreviewPanel
from webui.program_panel import ProgramPanel
from webui.regime_banner import RegimeBanner
from webui.scene import CellScene
from webui.status_bar import StatusBar
from webui.task_panel import TaskPanel
from webui.stop_header import StopHeader
from webui.trials_panel import TrialsPanel
from webui.stream_indicator import StreamIndicator
from webui.terrain_overlay import TerrainOverlay
from webui.terrain_panel import TerrainPanel

log = logging.getLogger(__name__)

PANEL_WIDTH = 430
# The camera the console opened with before it framed the work (shared.cells.framing): looking at
# the tool from the front (-y), world x left to right. Kept for tests that grab the gizmo at a
# known place on the canvas (they open the page with this camera in viser's URL parameters).
CAMERA_OFFSET = (0.0, -1.1, 0.3)  # m, from the tool at start
TERRAIN_CAMERA_OFFSET = (0.35, -0.7, 0.35)  # m: a rover's arm is small; look down on it and the ground


@dataclass
class Console:
    """Handles of everything ``build_console`` made (tests and the app may reach in)."""

    server: viser.ViserServer
    session: Session
    scene: CellScene
    ghost: RemoteGhost
    path: PredictedPath
    collision: CollisionOverlay
    status: StatusBar
    drive: DrivePanel
    program: ProgramPanel
    preview: PreviewPanel
    monitor: MonitorPanel
    terrain: TerrainPanel | None = None
    terrain_overlay: TerrainOverlay | None = None
    stop: StopHeader | None = None
    banner: RegimeBanner | None = None
    stream: StreamIndicator | None = None
    task: TaskPanel | None = None
    views: CameraPresets | None = None

    def __post_init__(self) -> None:
        self._lock = threading.Lock()  # events arrive on several threads; draw one at a time
        # The 3D scene is drawn only while a page is connected: a headless session (API
        # clients, trials, the telerobot's telemetry with nobody looking) would otherwise pay
        # forward kinematics and viser's message building on every jog and telemetry frame. A
        # skipped drawing marks the scene stale; the next page to connect gets it redrawn.
        self._stale = False
        self._connecting = False
        self.server.on_client_connect(self.on_page_connect)
        self._mode = DisplayMode.TELEPROGRAMMING
        self._arm: ArmView | None = None
        self._remote: RemoteArmView | None = None
        self._preview = PreviewView()
        self._collision: CollisionView | None = None
        self._program = None  # the newest ProgramView
        self._program_pending = False  # it changed while no page watched: shown when one connects
        self._link_text = ""
        self._terrain_view = None

    # -- routing ------------------------------------------------------------------------------
    def on_event(self, event) -> None:
        with self._lock:
            self._route(event)

    def _route(self, event) -> None:
        if isinstance(event, ArmChanged):
            self._arm = event.arm
            if self.views is not None:  # where the tool is; the cameras of the pages that follow it
                self.views.follow(event.arm.world_T_tcp)
            if self._watched():  # the panel's numbers and the gizmo's place: for a page to see
                self.drive.show_arm(event.arm)
            self._draw_arm()
        elif isinstance(event, CollisionChanged):
            self._collision = event.collision
            if self._watched():  # the panel's collision line: drawn on connect otherwise
                self.drive.show_collision(event.collision)
            self._draw_collision()
        elif isinstance(event, ProgramChanged):
            # a long program's list is costly to build: with no page, only the first (the panels
            # exist from the start) and then the newest when a page connects
            first, self._program = self._program is None, event.program
            if self._watched() or first:
                self._show_program(event.program)
                self._program_pending = False
            else:
                self._program_pending = True
        elif isinstance(event, PreviewChanged):
            self._preview = event.preview
            self.preview.show(event.preview)
            self.monitor.needs.show_preview(event.preview)
            self._draw_arm()
            self._draw_collision()
            self._draw_terrain()
        elif isinstance(event, SentChanged):
            self.monitor.show(event.sent)
            if self.stream is not None:
                self.stream.show_sent(event.sent)
        elif isinstance(event, LinkChanged):
            self.status.show_link(event.link)
            if self.stop is not None:
                self.stop.show_link(event.link)
            self._draw_ghost()  # the age grows between frames
            self.monitor.tick()
        elif isinstance(event, RemoteArmChanged):
            self._remote = event.remote
            self._draw_ghost()
            if self._mode is DisplayMode.TELEPRESENCE:
                self._draw_arm()
        elif isinstance(event, PredictedPathChanged):
            pts = np.asarray(event.predicted.points, dtype=float)
            self.path.show(pts if len(pts) else None)
        elif isinstance(event, RegimeChanged):
            self.status.show_regime(event.regime)
            if self.banner is not None:
                self.banner.show_regime(event.regime)
        elif isinstance(event, ReadinessChanged):
            self.monitor.needs.show(event.readiness)
            if self.banner is not None:
                self.banner.show_streaming(event.readiness.streams)
            if self.stream is not None:
                self.stream.show_readiness(event.readiness)
        elif isinstance(event, DisplayModeChanged):
            self._mode = event.display
            self.status.show_mode(event.display)
            self._draw_arm()
            self._draw_ghost()
            self._draw_collision()
            self._draw_terrain()
        elif isinstance(event, DivergenceChanged):
            self.status.show_divergence(event.divergence)
        elif isinstance(event, ControlChanged):
            self.status.show_control(event.control)
        elif isinstance(event, TerrainChanged):
            self._terrain_view = event.terrain
            if self.terrain is not None:
                self.terrain.show(event.terrain)
            self._draw_terrain()
        elif isinstance(event, PlacementChanged):
            if self.terrain is not None:
                self.terrain.show_placement(event.placement)
                self.terrain_overlay.show_target(event.placement)
        elif isinstance(event, TaskChanged):
            if self.task is not None:
                self.task.show(event.task)
        elif isinstance(event, WorkProgress):
            self.status.show_work(event)
        elif isinstance(event, Notice):
            if self.stop is not None:
                self.stop.show_notice(event)
            self.status.show_notice_event(event)

    # -- drawing by display mode --------------------------------------------------------------
    def _show_program(self, program) -> None:
        self.drive.show_program(program)
        self.program.show(program)
        self.preview.show_program(program)
        self.monitor.show_program(program)
        if self.task is not None:
            self.task.sync_commands()  # the action buttons follow the program's end
        if self.banner is not None:
            self.banner.show_auto_generate(program.auto_generate)

    def _watched(self) -> bool:
        """Is a page connected? If not, remember the scene needs drawing when one is."""
        if self._connecting or self.server.get_clients():
            return True
        self._stale = True
        return False

    def on_page_connect(self, _client=None) -> None:
        """Draw what was skipped while no page was connected (viser calls this per new page)."""
        with self._lock:
            if not self._stale:
                return
            self._stale = False
            self._connecting = True  # draw now, whether or not viser lists the page yet
            try:
                if self._arm is not None:
                    self.drive.show_arm(self._arm)
                if self._collision is not None:
                    self.drive.show_collision(self._collision)
                if self._program_pending and self._program is not None:
                    self._show_program(self._program)
                    self._program_pending = False
                self._draw_arm()
                self._draw_ghost()
                self._draw_collision()
            finally:
                self._connecting = False

    def _draw_arm(self) -> None:
        if not self._watched():
            return
        mode = self._mode
        if self._preview.active and self._preview.q is not None:
            self.scene.show_arm(np.asarray(self._preview.q))
        elif mode is DisplayMode.TELEPRESENCE and self._remote is not None:
            self.scene.show_arm(np.asarray(self._remote.q))
            self.scene.show_objects(self._remote_objects())
        elif self._arm is not None:
            self.scene.show_arm(np.asarray(self._arm.q))
            self.scene.show_objects({k: np.asarray(v) for k, v in self._arm.object_poses.items()})
        self.drive.gizmo.visible = mode is DisplayMode.TELEPROGRAMMING  # on the tool, or a ring on the chosen joint

    def _remote_objects(self) -> dict[str, np.ndarray]:
        poses = self._remote.object_poses if self._remote is not None else {}
        return {k: np.asarray(v) for k, v in poses.items()}

    def _draw_terrain(self) -> None:
        """Clearance segment, sensors and red triangles belong to the virtual arm: hidden while
        the arm drawn is another (a preview pose, the remote arm in telepresence)."""
        if self.terrain_overlay is None:
            return
        own_arm = not self._preview.active and self._mode is not DisplayMode.TELEPRESENCE
        self.terrain_overlay.show(self._terrain_view, visible=own_arm)

    def _draw_ghost(self) -> None:
        if not self._watched():
            return
        remote = self._remote
        if remote is None or self._mode is DisplayMode.TELEPRESENCE:
            self.ghost.hide()
            return
        self.ghost.show(np.asarray(remote.q), remote.age_s, remote.state)

    def _draw_collision(self) -> None:
        if not self._watched():
            return
        if self._preview.active:
            pv = self._preview
            warning = ""
            if pv.colliding_now:
                warning = "preview pose collides"
                if pv.current is not None:
                    warning += f" (statement {pv.current + 1})"
            self.collision.show(pv.triangles, warning)
            return
        view = self._collision
        if view is None or self._mode is DisplayMode.TELEPRESENCE:
            self.collision.show({}, "")
            return
        warning = ", ".join(f"{a} / {b}" for a, b in view.pairs[:3]) if view.colliding else ""
        self.collision.show(view.triangles, warning)


def build_console(server: viser.ViserServer, session: Session, trials: TrialBatches | None = None) -> Console:
    """Create the scene and every panel for ``session`` on ``server`` and keep them in step
    with the session's events. Call once, after the session exists and before clients load."""
    server.gui.configure_theme(show_share_button=False, control_width="large")
    server.gui.set_panel_label("teleprog console")
    offers = session.offers()
    scene = CellScene(server, session.cell)
    ghost = RemoteGhost(server, session.robot, session.cell.world_T_base)
    path = PredictedPath(server)
    collision = CollisionOverlay(server, scene.body_meshes, scene.body_nodes, scene.tcp_node)
    holder: dict[str, StatusBar] = {}
    board = NoticeBoard(on_change=lambda: holder["status"].render_notices() if "status" in holder else None)
    actions = Actions(lambda level, message, rule: holder["status"].show_notice(level, message, rule), board=board)
    # the header: a panel of its own docked above the control panel, so STOP never scrolls away
    header = server.gui.add_panel()
    with header.add_tab("Robot", viser.Icon.ROBOT):
        stop = StopHeader(server, session, actions)
        banner = RegimeBanner(server, robot=session.dispatch.connected)  # the regime, in colour, under STOP
        status = holder["status"] = StatusBar(server, session, actions, board=board)
    tabs = server.gui.add_tab_group()
    with tabs.add_tab("Drive", viser.Icon.HAND_MOVE):
        # the camera: a view that frames the cell's work, presets per page (shared.cells.framing)
        views = CameraPresets(server, cell_views(session.cell))
        views.set_initial()
        drive = DrivePanel(server, session, scene, actions)
        stream = StreamIndicator(server.gui)  # while a drag runs on the robot, it says so here
        stream.watch(drive.gizmo)
        Legend(server, session.robot)
        if LocatePanel.wanted(session):
            LocatePanel(server, session, actions)
    with tabs.add_tab("Program", viser.Icon.LIST_NUMBERS):
        program = ProgramPanel(server, session, actions)
    with tabs.add_tab("Preview", viser.Icon.EYE):
        preview = PreviewPanel(server, session, actions)
    with tabs.add_tab("Submit", viser.Icon.SEND):
        monitor = MonitorPanel(server, session, actions)
        if trials is not None:  # headless experiments on a virtual clock (the same batches as /api/trials)
            with server.gui.add_folder("Trials (virtual time)", expand_by_default=False):
                TrialsPanel(server, trials, actions)
    task = None
    if session.task.available:
        with tabs.add_tab("Task", viser.Icon.SITEMAP):
            task = TaskPanel(server, session, actions)
    terrain = overlay = None
    if offers.terrain:
        with tabs.add_tab("Terrain", viser.Icon.MOUNTAIN):
            terrain = TerrainPanel(server, session, actions)
        overlay = TerrainOverlay(server)
    console = Console(server, session, scene, ghost, path, collision, status, drive, program, preview, monitor,
                      terrain, overlay, stop, banner, stream, task, views)
    # first picture from the session's current state, then follow its events
    snap = session.snapshot()
    for event in (
        ArmChanged(arm=snap.arm), CollisionChanged(collision=snap.collision), ProgramChanged(program=snap.program),
        PreviewChanged(preview=snap.preview), SentChanged(sent=snap.sent), LinkChanged(link=snap.link),
        PredictedPathChanged(predicted=snap.predicted), RegimeChanged(regime=snap.regime),
        DisplayModeChanged(display=snap.display), DivergenceChanged(divergence=snap.divergence),
        ReadinessChanged(readiness=snap.readiness),
    ):
        console.on_event(event)
    if snap.remote is not None:
        console.on_event(RemoteArmChanged(remote=snap.remote))
    if task is not None:
        console.on_event(TaskChanged(task=session.task.view()))
    if terrain is not None:
        console.on_event(TerrainChanged(terrain=session.terrain.view()))
        console.on_event(PlacementChanged(placement=session.terrain.placement_view()))
    session.subscribe_events(console.on_event)
    try:
        server.gui.main_panel.dock_right()
        server.gui.main_panel.set_width(PANEL_WIDTH)
        header.dock_above(server.gui.main_panel)
    except Exception:  # noqa: BLE001 - placement is cosmetic; never fail the console for it
        log.exception("could not dock the control panel")
    return console


