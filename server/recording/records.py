"""What a session recording holds: one MCAP channel per topic, JSON-encoded, each with a schema.

Times: every message's MCAP ``log_time`` is the console's wall clock (Unix ns) when the console
knew the fact; the robot's own clock stays in the payload (``Telemetry.robot_time``). Units are SI.

Topics (``TOPICS`` maps each to its schema name):

* ``/session``: ``SessionStart``, once, first: cell, robot, settings of the recording.
* ``/virtual/arm``: ``VirtualArm``, every change of the virtual arm (the drag's full rate).
* ``/remote/telemetry``: ``Telemetry``, every frame the robot streams (50 Hz).
* ``/tf``: foxglove.FrameTransforms, every link of the virtual arm (``virtual/...``) on each of
  its changes and of the remote arm (``remote/...``) on each telemetry frame.
* ``/scene``: foxglove.SceneUpdate, the cell's objects and both arms' link meshes at the start,
  the objects again when one moves.
* ``/predicted/path``: foxglove.PosesInFrame, the tool path of what was sent and is not done.
* ``/log``: foxglove.Log, statements submitted and every status, notices.
* ``/program``: the program view after each change (generated or edited: ``ProgramView.undo_label``
  names the change).
* ``/statements/submitted``: ``RangeSubmitted``, a submitted range with the console's plan of it.
* ``/statements/status``: ``StatementStatus``, one per status a sent statement reaches.
* ``/sent``: the sent list after each change (what the console showed).
* ``/events/<type>``: every other session event as the console published it
  (``server.console.events``: regime, collision, divergence, link, control, notice, action, ...),
  except two thinned streams that repeat what is elsewhere: ``/events/arm`` only when more than
  the pose changes (``/virtual/arm`` has every pose), ``/events/collision`` on every change of
  the report with its distances alone at most 10 Hz, the last one always.
* ``/recording/dropped``: ``Dropped``, when the writer could not keep up and dropped messages.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

SCHEMA_PREFIX = "teleprog."

SESSION = "/session"
VIRTUAL_ARM = "/virtual/arm"
TELEMETRY = "/remote/telemetry"
TF = "/tf"
SCENE = "/scene"
PREDICTED_PATH = "/predicted/path"
LOG = "/log"
PROGRAM = "/program"
SUBMITTED = "/statements/submitted"
STATUS = "/statements/status"
SENT = "/sent"
EVENTS = "/events/"
DROPPED = "/recording/dropped"

TOPICS: dict[str, str] = {
    SESSION: "teleprog.SessionStart",
    VIRTUAL_ARM: "teleprog.VirtualArm",
    TELEMETRY: "teleprog.Telemetry",
    TF: "foxglove.FrameTransforms",
    SCENE: "foxglove.SceneUpdate",
    PREDICTED_PATH: "foxglove.PosesInFrame",
    LOG: "foxglove.Log",
    PROGRAM: "teleprog.ProgramView",
    SUBMITTED: "teleprog.RangeSubmitted",
    STATUS: "teleprog.StatementStatus",
    SENT: "teleprog.SentListView",
    DROPPED: "teleprog.Dropped",
}
"""Fixed topics and their schema names; ``/events/<type>`` topics use ``teleprog.Event.<type>``."""

VIRTUAL_PREFIX = "virtual"
REMOTE_PREFIX = "remote"
"""Frame-name prefixes of the two arms in ``/tf`` and ``/scene``."""


def event_topic(event_type: str) -> str:
    return EVENTS + event_type


def event_schema(event_type: str) -> str:
    return f"{SCHEMA_PREFIX}Event.{event_type}"


class _Record(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class SessionStart(_Record):
    """The recording's first message: what was recorded and where."""

    format: int = Field(1, description="version of this recording layout")
    cell: str = Field(description="the cell's name")
    cell_file: str = Field(description="the cell file the console loaded (absolute, or relative to the project)")
    robot: str
    dof: int
    started_at: float = Field(description="Unix s, the console's clock")
    robot_url: str | None = None
    delay_s: float | None = Field(None, description="the link's configured one-way delay, when the console started it")
    console_version: str = ""


class VirtualArm(_Record):
    q: list[float] = Field(description="joint vector, rad")
    world_T_tool: list[list[float]] = Field(description="tool point in the world, 4x4, m")
    version: int


class Telemetry(_Record):
    """One telemetry frame as the robot sent it (its clock in ``robot_time``)."""

    robot_time: float = Field(description="the robot's clock, s")
    frame: int
    state: str
    mode: str
    statement: int = Field(description="number of the statement running, 0 when none")
    q: list[float]
    base_p_tool: list[float] = Field(description="tool point in the robot's base frame, m")
    base_rpy_tool: list[float] = Field(description="fixed-axis XYZ roll-pitch-yaw, rad")
    gripper: float = Field(description="opening, m")
    wrench: list[float] = Field(description="force (N) then torque (N m) at the tool")


class PlannedPath(_Record):
    """The console's plan of a submitted range: joint samples at plan times from the range's start."""

    t: list[float] = Field(description="s from the range's start")
    q: list[list[float]] = Field(description="rad, one row per time")
    world_p_tool: list[list[float]] = Field(description="the tool point at each time, world m")
    statement_starts: list[float] = Field(description="plan time each statement starts, s")
    statement_ends: list[float]
    complete: bool = Field(description="the plan covers the whole range (no refusal, no task whose end only the robot knows)")


class RangeSubmitted(_Record):
    """A range the console handed to the link, with what it predicted."""

    ids: list[int] = Field(description="console-local ids of the statements (SentView.id)")
    texts: list[str]
    start_q: list[float] | None = Field(None, description="where the console planned from; None when it did not know")
    plan: PlannedPath | None = None


class StatementStatus(_Record):
    """One status a sent statement reached (``number``: the robot's, once it answered)."""

    id: int
    number: int | None
    text: str
    status: str
    final: bool
    reason: str | None = None
    submitted_at: float
    answered_at: float | None = None
    started_at: float | None = None
    finished_at: float | None = None


class Dropped(_Record):
    count: int = Field(description="messages dropped since the last report (the writer fell behind)")
    total: int
