"""Typed views of the console session: what the web page, the HTTP API and the event stream show.

Why a module of its own: the console's parts (``server.console``) produce these, the HTTP API
(``server.api``) returns them, the WebSocket ``/api/events`` streams them inside events
(``server.console.events``), and the viser panels (``webui``) read them; one definition each
keeps the four in step. Every value is SI (rad, m, s) unless the field name says otherwise
(``_deg``, ``_mm``). ``*_at`` fields are Unix wall-clock seconds (for display), ``*_s`` are
durations.
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from server.console.enums import DisplayMode, Regime, SentStatus
from shared.language.statements import Statement
from shared.robots.jog import JogResult
from shared.tasknet.cenet import ConditionEventModel

__all__ = [
    "VirtualState",
    "ArmView",
    "RefusalView",
    "StatementView",
    "ProgramView",
    "PreviewWarning",
    "PreviewView",
    "SentView",
    "SentListView",
    "LinkView",
    "RemoteArmView",
    "PredictedPathView",
    "CollisionView",
    "RegimeView",
    "SubmitReadiness",
    "PreviewAndSubmitView",
    "DivergenceView",
    "Caller",
    "ControlTakeover",
    "ControlView",
    "ControlGrant",
    "ControlAsk",
    "ControlAskGrant",
    "TerrainSensorsView",
    "TerrainView",
    "PlacementCandidateView",
    "PlacementView",
    "LocatedView",
    "SessionSnapshot",
    "matrix_list",
]



@dataclass(frozen=True)
class VirtualState:
    """The virtual arm's fast path (the 3D scene draws every change): joint vector (rad), the
    tool point's pose in the world, the last jog's outcome and a version that counts changes."""

    q: np.ndarray
    world_T_tcp: np.ndarray
    last_jog: JogResult | None = None
    version: int = 0


class _View(BaseModel):
    model_config = ConfigDict(frozen=True)


class ArmView(_View):
    """The virtual arm (what the operator commands)."""

    q: list[float] = Field(description="joint vector, rad")
    q_deg: list[float]
    world_T_tcp: list[list[float]] = Field(description="tool point pose in the world, 4x4, m")
    tool_xyz_mm: list[float]
    tool_rpy_deg: list[float]
    blocked: str | None = Field(None, description="why the last jog stopped, if it did")
    message: str = ""
    version: int
    held: str | None = Field(None, description="object the virtual gripper holds")
    object_poses: dict[str, list[list[float]]] = Field(
        default_factory=dict, description="world_T_object of objects moved away from the cell file"
    )


class RefusalView(_View):
    rule: str = Field(description="stable rule id, e.g. 'insert.action-at-end'")
    message: str
    index: int | None = Field(None, description="0-based entry the rule concerns (shown on that line), if any")


class StatementView(_View):
    index: int = Field(description="0-based place in the program")
    kind: str = Field(description="MOVE, DRIVE, ..., or EMPTY for the trailing empty statement")
    text: str = Field(description="the statement's text form (mm, deg)")
    statement: Statement | None = Field(None, description="JSON form (SI); None for the empty statement")
    added_by: Literal["console"] | None = Field(
        None, description="'console' for a line the console put in (a MODE the regime needs); None: the operator's"
    )
    added_reason: str | None = Field(None, description="why the console added the line (it can be deleted like any other)")
    action: str | None = Field(None, description="the task action this line serves, when a task-level command "
                               "(a goal, an action of the Task tab) put it in, e.g. grasp(PEG)")
    duration_s: float | None = Field(
        None, description="planned duration from the program's start, s; None: not planned (empty, a task, "
        "after a planning refusal, or the start is unknown)"
    )


class ProgramView(_View):
    """The program being edited (§4.3.6) and the generator's switch."""

    entries: list[StatementView] = Field(description="real statements then the trailing empty one")
    selected: int = Field(description="the cursor: where insert and modify act (one end of selected_range)")
    selected_range: tuple[int, int] | None = Field(
        None, description="selected entries (first, last), both included; first == last for one"
    )
    refusal: RefusalView | None = Field(
        None, description="the last refused edit, until the next edit or selection; shown on its line"
    )
    empty_index: int
    preview: tuple[int, int] | None = Field(None, description="range being previewed (start, stop)")
    can_undo: bool
    can_redo: bool
    undo_label: str | None = None
    redo_label: str | None = None
    auto_generate: bool
    start_q: list[float] = Field(description="where the program starts (rad): the predicted end of what was sent")
    start_source: Literal["model", "predicted", "telemetry"] = Field(
        description="model: the cell's home; predicted: end of submitted statements; telemetry: re-synced"
    )
    confirmed: tuple[int, int] | None = Field(
        None, description="range last previewed to its end with no warning (quasi regime's confirm)"
    )
    strict_editing: bool = Field(
        False, description="the thesis's editing rules (§4.3.6); false: free editing, any statement anywhere (the default)"
    )


class PreviewWarning(_View):
    t: float = Field(description="preview time, s from the range's start")
    index: int = Field(description="program index of the statement playing")
    kind: Literal["collision", "joint_limit", "plan"]
    message: str
    bodies: tuple[str, str] | None = None


class PreviewView(_View):
    """The preview player (§4.3.7 task preview). ``q`` is where the virtual arm is drawn."""

    active: bool = False
    start: int = 0
    stop: int = 0
    playing: bool = False
    t: float = 0.0
    duration: float = 0.0
    rate: float = 1.0
    current: int | None = Field(None, description="program index of the statement at t")
    q: list[float] | None = None
    warnings: list[PreviewWarning] = Field(default_factory=list)
    colliding_now: bool = False
    triangles: dict[str, list[int]] = Field(default_factory=dict, description="interfering triangles at t, per body")
    refusal: str | None = Field(None, description="why planning stopped before the range's end")
    speed: float | Literal["instant"] = Field(
        1.0, description="preview speed: plan seconds per clock second, or 'instant' (checked at once, stands at the end)"
    )
    then_submit: bool = Field(False, description="a 'Preview and submit' waits for this preview's end to send the range")


class SentView(_View):
    id: int = Field(description="console-local id, from 1")
    number: int | None = Field(None, description="the robot's statement number, once it answered")
    text: str
    statement: Statement
    status: SentStatus
    reason: str | None = None
    submitted_at: float
    answered_at: float | None = None
    started_at: float | None = None
    finished_at: float | None = None
    run_s: float | None = Field(None, description="running -> final, on the console's clock")
    robot_run_s: float | None = Field(None, description="running -> final, on the robot's clock (its reports' robot_time)")
    before: bool = Field(False, description="sent before this console started: the robot listed it when this console connected")


class SentListView(_View):
    items: list[SentView]
    pending: int = Field(description="how many are not final yet")


class LinkView(_View):
    configured: bool = Field(description="whether the console has a robot URL at all")
    url: str | None = Field(None, description="the robot's (or link's) address: only to the holder of control, on GET /api/link")
    door: str | None = Field(None, description="why the robot refuses this console's connections (its credential), while it does")
    connected: bool = False
    delay_s: float | None = Field(None, description="measured one-way delay (half a round trip)")
    round_trip_s: float | None = None
    telemetry_received_ago_s: float | None = Field(None, description="since the last frame arrived here")
    telemetry_age_s: float | None = Field(None, description="age of the state the last frame shows (adds the delay)")
    reconnects: int = 0
    robot_state: str | None = Field(
        None, description="idle, running, stopped, fault, disconnected; None when telemetry is stale (never an old state)"
    )
    recovery_pending: list[str] = Field(default_factory=list, description="recovery commands not acknowledged yet")
    status: str = Field(
        "unconfigured",
        description="the command channel: unconfigured, down (no socket), connecting (no welcome yet), live, "
        "silent (nothing heard past the silence limit)",
    )
    heard_ago_s: float | None = Field(None, description="since anything last arrived on the command channel")
    silence_limit_s: float | None = Field(None, description="silence beyond the expected arrival that counts as silent")
    telemetry: str = Field("none", description="none (no frame yet), live or stale (no frame past the silence limit)")
    telemetry_frames: int | None = Field(
        None, description="telemetry frames the console has received from the robot since it started (None: no robot)"
    )
    halted: str | None = Field(None, description="why the robot stopped by itself, until a resume is acknowledged")
    errors: int = Field(0, description="errors caught while handling the robot's messages (the channels carried on)")
    last_error: str | None = None
    refused: str | None = Field(None, description="the robot's last refusal of a message or recovery command")
    buffer_full: str | None = Field(None, description="the robot's last BUFFER_FULL answer, until a later one is accepted")
    robot_session: str | None = Field(None, description="the robot's session id (changes when it restarts)")
    robot_restarts: int = Field(0, description="how often a new robot session began under this console")
    children: dict[str, str] = Field(
        default_factory=dict, description="processes teleprog up started and watches: name -> running / exited N, restarting"
    )
    problems: list[str] = Field(default_factory=list, description="what is wrong with the link now, one line each")


class RemoteArmView(_View):
    """The remote arm as the newest telemetry shows it (drawn as a ghost)."""

    q: list[float]
    world_T_tcp: list[list[float]]
    age_s: float | None
    state: str
    statement: int = Field(description="number of the statement running, 0 when none")
    gripper: float
    force_n: list[float]
    held: str | None = Field(None, description="object the robot holds (from its finished grasp/release tasks)")
    object_poses: dict[str, list[list[float]]] = Field(
        default_factory=dict, description="world_T_object of objects the robot's state moves (the held one follows its tool)"
    )


class PredictedPathView(_View):
    """Where the submitted-not-done statements will take the arm (tool points in the world)."""

    points: list[list[float]] = Field(default_factory=list, description="world tool points, m")
    numbers: list[int] = Field(default_factory=list, description="robot numbers of the statements it covers")
    end_q: list[float] | None = None


class CollisionView(_View):
    """Collision report and control zone of the virtual arm (or of the preview pose)."""

    colliding: bool
    pairs: list[tuple[str, str]] = Field(default_factory=list)
    triangles: dict[str, list[int]] = Field(default_factory=dict, description="interfering triangle ids per body")
    min_distance: float | None = Field(None, description="m, from the tool to the nearest object or the ground")
    nearest: tuple[str, str] | None = Field(
        None, description="the tool body and the object (or ground) nearest it; never two links of the arm")
    zone: Regime = Field(description="control zone from tool-object distances")
    zone_object: str | None = None
    zone_distance: float | None = None
    joint_limit: str | None = Field(None, description="a joint at or past its range")


class RegimeView(_View):
    regime: Regime
    zone: Regime
    override: Regime | None = None


class SubmitReadiness(_View):
    """What Submit needs for a range now, in the regime's words, before the operator clicks:
    computed from the same checks ``Dispatch.submit`` applies (``Dispatch.refusal``), so the page
    and a refusal cannot disagree."""

    regime: Regime
    start: int = Field(description="first statement, 0-based")
    stop: int = Field(description="one past the last")
    ready: bool = Field(description="Submit would send this range now")
    needs: str = Field(description="the regime's condition for this range, in words")
    state: str = Field(description="where the range stands against it: 'ready to send 1-5' or what is missing")
    blocker: str | None = Field(None, description="the sentence Submit would refuse with now")
    confirmed: tuple[int, int] | None = Field(None, description="range previewed to its end without warnings")
    streams: bool = Field(
        False, description="generated statements go to the robot as they are made (free regime, generation on, a robot)"
    )
    line: str = Field(description="the one line the Submit tab shows")


class PreviewAndSubmitView(_View):
    """The answer to "Preview and submit": the preview as it stands, and what was sent if the
    range already reached its end without warnings (an instant preview sends at once)."""

    preview: PreviewView
    submitted: bool = False
    sent: SentListView | None = None
    message: str = ""


class DivergenceView(_View):
    diverged: bool = False
    joint_error: float = Field(0.0, description="largest joint difference, rad")
    tool_error: float = Field(0.0, description="tool point distance, m")
    object_error: float = Field(0.0, description="largest distance between an object as reported and as modelled, m")
    object: str | None = Field(None, description="the object that differs most (or is held on one side only)")
    threshold_joint: float
    threshold_tool: float
    checked: bool = Field(False, description="the robot was at rest with nothing pending when compared")
    message: str = ""


@dataclass(frozen=True)
class Caller:
    """Who makes a call: the name it declares (``X-Teleprog-Client``; ``None``: the page served by
    this console) and the control token it presents (``X-Teleprog-Token``; ``None``: none).
    Only the token proves anything; the name is a label for people."""

    name: str | None = None
    token: str | None = dataclass_field(default=None, repr=False)


class ControlTakeover(_View):
    """The last explicit take-over of the control lock, so the former holder can see it."""

    by: str = Field(description="label of the client that took control")
    former: str = Field(description="label of the client that held it until then")
    at: float = Field(description="when, Unix s")


class ControlAsk(_View):
    """A pending request for control: the holder hands over or refuses; if it says nothing, control
    passes to the asker at ``passes_at``."""

    by: str = Field(description="label of the client that asked")
    at: float = Field(description="when it asked, Unix s")
    passes_at: float = Field(description="when control passes to it unless the holder refuses first, Unix s")


class ControlView(_View):
    """Who holds the control lock (a label, never the token), a pending request and the last take-over."""

    holder: str | None = Field(None, description="the holder's X-Teleprog-Client name; null: nobody holds control")
    since: float | None = Field(None, description="Unix s")
    last_takeover: ControlTakeover | None = None
    asked: ControlAsk | None = Field(None, description="a request for control waiting on the holder")


class ControlGrant(ControlView):
    """The answer to the caller that now holds control: the view and its token (never published)."""

    token: str = Field(description="present it as the X-Teleprog-Token header on every call that changes state, and to release")


class ControlAskGrant(ControlView):
    """The answer to a client that asked for control: the view and the token that becomes the
    holder's once control passes to it (handed over, or the holder silent past ``asked.passes_at``);
    until then it changes nothing. Asking while nobody holds control takes it at once."""

    token: str = Field(description="the X-Teleprog-Token to present once the view's holder is this client")


class TerrainSensorsView(_View):
    """The virtual sensors of seed 004 at the arm's pose: segment ends A -> B (world, m), whether
    the ray from A through B meets the ground within the sensor's length."""

    starts: list[list[float]] = Field(default_factory=list, description="sensor ends A, world m")
    ends: list[list[float]] = Field(default_factory=list, description="sensor ends B, world m")
    collides: list[bool] = Field(default_factory=list)


class TerrainView(_View):
    """Arm against terrain at the virtual arm's pose (terrain cells only): the exact minimum
    distance with its witness segment, the virtual-sensor distance, and on contact the terrain
    triangles touching the arm (world corners, for painting them red)."""

    distance: float = Field(description="exact minimum distance arm-terrain, m (<= 0: contact)")
    in_collision: bool
    shape: str = Field("", description="arm shape holding the nearest point")
    world_p_arm: list[float] = Field(description="witness point on the arm, m")
    world_p_terrain: list[float] = Field(description="witness point on the terrain, m")
    head_distance: float = Field(description="the instrument head's distance to the ground, m")
    sensor_distance: float | None = Field(None, description="smallest sensor clearance d_RS, m (None: no reading)")
    sensor_collision: bool = False
    contact_corners: list[list[list[float]]] = Field(default_factory=list, description="touching triangles, world m")
    sensors: TerrainSensorsView | None = Field(None, description="present while the sensors are shown")


class PlacementCandidateView(_View):
    q: list[float] = Field(description="final joint vector, rad")
    q_deg: list[float]
    standoff: float = Field(description="point C's height above the target along the normal, m")
    clearance: float = Field(description="smallest distance of the arm without its head, m")
    head_clearance: float = Field(description="the instrument head's distance, m")
    tilt_deg: float = Field(description="angle between the head's axis and the surface normal")
    approach: bool = Field(description="an approach pose along the normal was found")


class PlacementView(_View):
    """Instrument placement at a picked terrain point (seed 004): every safe configuration, best
    first, and the statements that get there."""

    world_p_target: list[float]
    world_n_surface: list[float]
    candidates: list[PlacementCandidateView] = Field(default_factory=list)
    rejected: dict[str, int] = Field(default_factory=dict, description="configurations refused, by reason")
    program: list[str] = Field(default_factory=list, description="statement text of the best placement")
    message: str = ""


class LocatedView(_View):
    """A virtual object's pose corrected from a camera image (thesis §4.2.3)."""

    object: str
    camera: str
    world_T_object: list[list[float]]
    residual_px: float = Field(description="RMS reprojection error of the feature points, pixels")
    moved: float = Field(description="how far the object's origin moved, m")


class SessionSnapshot(_View):
    """Everything at once (``GET /api/session``)."""

    cell: str
    robot: str
    dof: int
    arm: ArmView
    program: ProgramView
    preview: PreviewView
    sent: SentListView
    link: LinkView
    remote: RemoteArmView | None
    predicted: PredictedPathView
    collision: CollisionView
    regime: RegimeView
    display: DisplayMode
    divergence: DivergenceView
    control: ControlView
    readiness: SubmitReadiness | None = Field(None, description="what Submit needs for the whole program now")


def matrix_list(a: np.ndarray) -> list[list[float]]:
    """A pose matrix as the nested lists a view holds."""
    return np.asarray(a, dtype=float).tolist()


# -- the task panel (server.console.task_monitor) -------------------------------------------------
class RuleView(_View):
    """One STRIPS F-rule of the task space, as written in its task file."""

    name: str
    params: list[str]
    pre: list[str]
    delete: list[str]
    add: list[str]


class ActionView(_View):
    action: str = Field(description="ground action, e.g. part(PEG,HOLE1)")
    t: float | None = Field(None, description="console clock (s) when it was recognised")
    statement: int | None = Field(None, description="robot statement number (robot side) it happened in")


class DeviationView(_View):
    """A robot report the task net does not allow."""

    kind: Literal["missing", "state", "markings"] = Field(
        description="missing: a statement ended without the action it should make; state: the robot's cell "
                    "contradicts its marking; markings: with the robot at rest, the virtual marking is not the robot's")
    expected: str | None = Field(None, description="the transition (action) that was expected")
    statement: int | None = None
    status: str | None = Field(None, description="the statement's final status, for a missing action")
    message: str
    observed: dict[str, bool] = Field(default_factory=dict, description="the atoms as the robot's cell shows them")
    robot_marking: list[str] = Field(default_factory=list)
    at: float = Field(description="Unix time")


class TaskView(_View):
    """The task net of the cell with the virtual and the robot's markings (thesis 3.5)."""

    available: bool = Field(description="whether the cell has a task file (assets/tasks/<cell>.toml)")
    error: str | None = None
    task: str | None = None
    description: str = ""
    rules: list[RuleView] = Field(default_factory=list)
    atoms: list[str] = Field(default_factory=list, description="the task space's places (ground atoms)")
    virtual_marking: list[str] = Field(default_factory=list, description="atoms true in the virtual cell's marking")
    robot_marking: list[str] = Field(default_factory=list, description="atoms true in the robot's marking")
    virtual_actions: list[ActionView] = Field(default_factory=list)
    robot_actions: list[ActionView] = Field(default_factory=list)
    enabled: list[str] = Field(default_factory=list, description="actions enabled at the virtual marking")
    net: ConditionEventModel | None = Field(None, description="the task net generated from the virtual actions (3.5.5)")
    space_net: ConditionEventModel | None = Field(
        None, description="the whole task space as a net: a place per atom, a transition per ground action (marking: the cell as loaded)")
    preview_active: bool = Field(False, description="a preview is shown: preview_actions/preview_marking follow its player")
    preview_actions: list[ActionView] = Field(
        default_factory=list, description="actions the previewed range makes up to the player's time (statement: program number)")
    preview_marking: list[str] = Field(default_factory=list, description="atoms true where the preview player stands")
    deviations: list[DeviationView] = Field(default_factory=list)
    version: int = 0
