"""Correcting a virtual object from a camera image (thesis §4.2.3): the operator reads the pixels
of the object's feature points off the remote camera's image, in the order the cell file lists
them, and the session locates the object from them (``session.locator.locate_object``)."""

from __future__ import annotations

import re

import viser

from server.console import Session
from shared.errors import InputError
from webui.actions import Actions


def parse_pixels(text: str) -> list[tuple[float, float]]:
    """``"u v; u v; ..."`` (commas allowed) as pixel pairs; ``InputError`` saying which is bad."""
    pairs = []
    for k, chunk in enumerate(c for c in text.split(";") if c.strip()):
        parts = [p for p in re.split(r"[,\s]+", chunk.strip()) if p]
        try:
            u, v = (float(p) for p in parts)
        except ValueError:
            raise InputError(f"image point {k + 1} {chunk.strip()!r}: write two numbers, u v") from None
        pairs.append((u, v))
    return pairs


class LocatePanel:
    def __init__(self, server: viser.ViserServer, session: Session, actions: Actions) -> None:
        self.session = session
        self.actions = actions
        cell = session.cell
        names = [o.name for o in cell.objects if len(o.keypoints) >= 4]
        gui = server.gui
        with gui.add_folder("Correct an object from a camera image", expand_by_default=False):
            self.object = gui.add_dropdown("Object", names, initial_value=names[0])
            self.camera = gui.add_dropdown("Camera", list(cell.cameras), initial_value=next(iter(cell.cameras)))
            self.pixels = gui.add_text("Image points (u v; ...)", "",
                                       hint="pixels of the object's feature points, in the cell file's order")
            self.go = gui.add_button("Correct pose from image", icon=viser.Icon.CAMERA)
            self.go.on_click(self._on_go)

    @staticmethod
    def wanted(session: Session) -> bool:
        cell = session.cell
        return bool(cell.cameras) and any(len(o.keypoints) >= 4 for o in cell.objects)

    def _on_go(self, _event: viser.GuiEvent) -> None:
        text, name, camera = self.pixels.value, self.object.value, self.camera.value
        self.actions.run(f"locate {name}", lambda: self.session.locator.locate_object(name, camera, parse_pixels(text)))
