"""The particle-sedimentation view: ``build_sedimentation_view(server, runner)``.

Draws what ``server.sedimentation.runner.SedimentationRunner`` publishes; it computes nothing itself.
The cube ``[0, L]^3`` is drawn as a unit wireframe cube centred on the origin (L changes with N
and the density; a fixed on-screen size keeps the camera useful), bodies as one point cloud
whose point size is the true sphere diameter (never below a visible minimum, so large N reads
as a cloud), and the bodies in at least one overlapping pair again as a second, red, slightly
larger cloud on top. Two clouds instead of per-point colours: each picture then carries 6 bytes
per body (float16 positions) instead of 9, and the red cloud only K bodies.

Panel: method and scene-kind dropdowns, N and density number inputs, a SPEED slider, a
pause/resume button, and a status line (method, detection FPS, pairs, frame).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field

import numpy as np
import viser

from server.sedimentation.runner import (
    MAX_DENSITY,
    MAX_SPEED,
    MIN_BODIES,
    MIN_DENSITY,
    SedimentationRunner,
    SedimentationSettings,
    SedimentationSnapshot,
)
from shared.errors import TeleprogError

log = logging.getLogger(__name__)

ROOT = "/sedimentation"
BODY_COLOUR = (95, 135, 200)
CONTACT_COLOUR = (225, 35, 35)
CUBE_COLOUR = (120, 120, 120)
MIN_POINT_SIZE = 0.004  # unit-cube lengths: about 2 px across at the initial camera distance
CONTACT_SCALE = 1.5  # red points drawn this much larger than the body points
#: After the operator touches a control, pictures do not overwrite the controls for this long
#: (pictures lag the settings by up to a drawing period; typing "500" sends 5, 50, 500).
GUI_QUIET_S = 1.5


def cube_edges() -> np.ndarray:
    """The 12 edges of the unit cube centred on the origin, (12, 2, 3)."""
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if np.sum(corners[a] != corners[b]) == 1]
    return np.array([[corners[a], corners[b]] for a, b in edges])


def status_text(snap: SedimentationSnapshot) -> str:
    """The status line: what runs, how fast it detects, what it found."""
    s = snap.settings
    fps = f"{snap.fps:,.0f}" if snap.fps >= 10 else f"{snap.fps:.1f}"
    state = " · **paused**" if s.paused else ""
    return (
        f"**Method** {s.method} · **FPS** {fps} · **pairs** {snap.n_pairs:,} · **frame** {snap.frame:,}{state}  \n"
        f"N {s.n:,} · L {snap.size:,.1f} · SPEED {s.speed:g} · {s.kind} · {snap.steps_per_s:.0f} frames/s simulated"
    )


@dataclass
class SedimentationView:
    """Handles of the scene and panel (tests may reach in)."""

    server: viser.ViserServer
    runner: SedimentationRunner
    bodies: viser.PointCloudHandle
    contacts: viser.PointCloudHandle
    status: viser.GuiMarkdownHandle
    notice: viser.GuiMarkdownHandle
    method: viser.GuiDropdownHandle
    kind: viser.GuiDropdownHandle
    n: viser.GuiNumberHandle
    speed: viser.GuiSliderHandle
    density: viser.GuiNumberHandle
    pause: viser.GuiButtonHandle
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _touched: float = 0.0
    _shown: SedimentationSettings | None = None  # the settings the controls show

    # -- pictures ------------------------------------------------------------------------------
    def draw(self, snap: SedimentationSnapshot) -> None:
        """Show one published picture (runner's drawing thread)."""
        with self._lock:
            view_p = (snap.centres / snap.size - 0.5).astype(np.float16)
            diameter = 2.0 * float(snap.radii.max(initial=1.0)) / snap.size
            size = max(diameter, MIN_POINT_SIZE)
            with self.server.atomic():
                self.bodies.points = view_p
                self.bodies.point_size = size
                hit = view_p[snap.colliding]
                if hit.shape[0]:
                    self.contacts.points = hit
                    self.contacts.point_size = size * CONTACT_SCALE
                    self.contacts.visible = True
                else:
                    self.contacts.visible = False
            self.status.content = status_text(snap)
            if self.runner.settings != self._shown and time.monotonic() - self._touched > GUI_QUIET_S:
                self._show_settings()

    def _show_settings(self) -> None:
        """Controls follow changes made elsewhere (the API, another browser): the runner's
        current settings, not the picture's, which may be a drawing period old. Only when
        they changed: a refused number stays in its box (with the notice) until corrected."""
        s = self._shown = self.runner.settings
        self.notice.visible = False
        self.method.value = s.method
        self.kind.value = s.kind
        self.n.value = s.n
        self.speed.value = s.speed
        self.density.value = s.density
        self.pause.label = "Resume" if s.paused else "Pause"

    # -- operator input ------------------------------------------------------------------------
    def apply(self, **change: object) -> None:
        """Send one control's value to the runner; on refusal show why and put it back."""
        self._touched = time.monotonic()
        try:
            state = self.runner.update(**change)
        except TeleprogError as exc:
            self.notice.content = f"**Refused:** {exc}"
            self.notice.visible = True
            # a refused choice goes back to what runs; a refused number stays for correcting
            # (typing "1500" passes through "1", which is refused, on its way)
            s = self.runner.settings
            if "method" in change:
                self.method.value = s.method
            if "kind" in change:
                self.kind.value = s.kind
            return
        self._shown = self.runner.settings
        self.notice.visible = False
        self.pause.label = "Resume" if state.paused else "Pause"


def build_sedimentation_view(server: viser.ViserServer, runner: SedimentationRunner) -> SedimentationView:
    """Create the scene and panel on ``server`` and draw every picture ``runner`` publishes."""
    server.gui.configure_theme(show_share_button=False)
    server.gui.set_panel_label("teleprog sedimentation")
    server.initial_camera.position = (1.25, -1.55, 0.95)
    server.initial_camera.look_at = (0.0, 0.0, -0.05)
    server.scene.add_line_segments(f"{ROOT}/cube", cube_edges(), CUBE_COLOUR, thickness=2.0, thickness_units="screen")
    snap = runner.latest()
    view_p = (snap.centres / snap.size - 0.5).astype(np.float16)
    bodies = server.scene.add_point_cloud(
        f"{ROOT}/bodies", view_p, BODY_COLOUR, point_size=MIN_POINT_SIZE, point_shape="circle"
    )
    contacts = server.scene.add_point_cloud(
        f"{ROOT}/contacts", view_p[:1], CONTACT_COLOUR, point_size=MIN_POINT_SIZE, point_shape="circle", visible=False
    )
    s = runner.settings
    server.gui.add_markdown("**Particle sedimentation** (thesis ch. 5): spheres of radius 1 in a cube; "
                            "red bodies overlap another. FPS counts detection time only.")
    status = server.gui.add_markdown(status_text(snap))
    notice = server.gui.add_markdown("", visible=False)
    state = runner.state()
    method = server.gui.add_dropdown("Method", state.methods, initial_value=s.method,
                                     hint="broadphase method finding the overlapping pairs")
    kind = server.gui.add_dropdown("Scene", state.kinds, initial_value=s.kind,
                                   hint="uniform suspension, Gaussian clusters, or a sediment layer on the floor")
    n = server.gui.add_number("N (bodies)", s.n, min=MIN_BODIES, max=runner.max_n, step=1,
                              hint="number of spheres; the cube side follows from the density")
    speed = server.gui.add_slider("SPEED", min=0.0, max=MAX_SPEED, step=0.1, initial_value=s.speed,
                                  hint="distance each body moves per frame (sphere radius 1)")
    density = server.gui.add_number("Density", s.density, min=MIN_DENSITY, max=MAX_DENSITY, step=0.0001,
                                    hint="bodies per unit volume, N / L^3 (thesis: 0.0005)")
    pause = server.gui.add_button("Resume" if s.paused else "Pause", icon=viser.Icon.PLAYER_PAUSE)
    view = SedimentationView(server, runner, bodies, contacts, status, notice, method, kind, n, speed, density, pause)
    view._shown = s

    def follow(handle, key: str) -> None:
        def changed(event: viser.GuiEvent) -> None:
            if event.client is None:
                return  # set from Python (following the runner, or putting a refused value back)
            view.apply(**{key: handle.value})

        handle.on_update(changed)

    for handle, key in ((method, "method"), (kind, "kind"), (n, "n"), (speed, "speed"), (density, "density")):
        follow(handle, key)

    def toggle(_) -> None:
        view._touched = time.monotonic()
        state = runner.toggle_pause()
        pause.label = "Resume" if state.paused else "Pause"

    pause.on_click(toggle)
    view.draw(snap)
    runner.subscribe(view.draw)
    return view
