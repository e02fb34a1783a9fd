"""What a console part needs of a part downstream of it, as typed views (``Protocol``s).

The console's data flows one way: the virtual arm feeds the program, the program the preview,
the preview and the program the dispatch, the dispatch the remote mirror, and the link's status
and recovery read them all. A part imports the parts upstream of it and nothing downstream: where
it must reach downstream (the arm asks whether a preview runs; the program streams what the arm
generates in the free regime; the dispatch hands telemetry to the mirror), it holds one of these
views, which the session fills in when it wires the parts. So no two parts import each other
(``tests/server/test_console_imports.py`` keeps the import graph free of circles), and each view
names exactly what crosses against the flow.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from server.console.program_start import ProgramStart
    from server.console.views import Caller, LinkView, ProgramView, SentListView, TerrainView, VirtualState
    from shared.language.statements import Statement
    from shared.program.editor import Editor
    from shared.program.generator import Generated, JogMode
    from shared.terrain.ground import GroundContact
    from shared.wire.messages import StatusReport
    from shared.wire.telemetry import TelemetryFrame


class StrokeTaker(Protocol):
    """The program, as the virtual arm feeds it (``ProgramDesk``)."""

    @property
    def editor(self) -> Editor: ...

    start: ProgramStart

    def sample_stroke(self, before: VirtualState, after: VirtualState, mode: JogMode,
                      frame: str | None = None) -> list[Generated]: ...

    def take_generated(self, statements: list[Generated]) -> None: ...

    def end_stroke(self, *, client: Caller | str | None = None) -> ProgramView: ...


class PreviewRun(Protocol):
    """Whether a preview runs and what it says of the program's path (``Previewer``)."""

    def running_range(self) -> tuple[int, int] | None: ...

    def hazard(self) -> str | None: ...

    def path_not_clear(self, start: int, stop: int) -> dict[int, str]: ...


class Submitter(Protocol):
    """The dispatch, as the program streams to it in the free regime (``Dispatch``)."""

    @property
    def connected(self) -> bool: ...

    def submit(self, start: int, stop: int, *, client: Caller | str | None = None) -> SentListView: ...


class GroundContacts(Protocol):
    """The terrain tools, as the virtual arm tells them of its ground contact (``TerrainTools``)."""

    def take_contact(self, contact: GroundContact) -> TerrainView: ...


class RemoteSink(Protocol):
    """The remote mirror, as the dispatch hands it the robot's frames and reports (``RemoteMirror``)."""

    @property
    def telemetry(self) -> TelemetryFrame | None: ...

    def gate_frame(self, frame: TelemetryFrame) -> bool: ...

    def take_frame(self, frame: TelemetryFrame) -> None: ...

    def take_report(self, done: Statement | None, report: StatusReport) -> None: ...

    def refresh_predicted(self) -> None: ...

    def check_divergence(self) -> None: ...


class LinkRead(Protocol):
    """The link's status, as the dispatch and the remote mirror read it (``LinkStatus``)."""

    def view(self, *, address: bool = False) -> LinkView: ...

    def telemetry_age_s(self) -> float | None: ...


class PendingRecoveries(Protocol):
    """The recovery commands the robot has not yet acknowledged (``Recovery``)."""

    @property
    def pending(self) -> Mapping[int, str]: ...
