"""Typed events of the console session: a discriminated union on ``type`` (:data:`SessionEvent`).
A listener registered on the session's bus (``Session.subscribe_events``) receives each one after
the session's lock is released."""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field

from server.console.enums import DisplayMode
from server.console.views import (
    ArmView,
    CollisionView,
    ControlView,
    DivergenceView,
    LinkView,
    PlacementView,
    PredictedPathView,
    PreviewView,
    ProgramView,
    RegimeView,
    RemoteArmView,
    SubmitReadiness,
    SentListView,
    TaskView,
    TerrainView,
    _View,
)

__all__ = [
    "ArmChanged",
    "ProgramChanged",
    "PreviewChanged",
    "SentChanged",
    "LinkChanged",
    "RemoteArmChanged",
    "PredictedPathChanged",
    "CollisionChanged",
    "RegimeChanged",
    "DisplayModeChanged",
    "DivergenceChanged",
    "TerrainChanged",
    "PlacementChanged",
    "ControlChanged",
    "ReadinessChanged",
    "Notice",
    "ActionTaken",
    "RangeSubmitted",
    "TaskChanged",
    "WorkKind",
    "WorkProgress",
    "SessionEvent",
]



class ArmChanged(_View):
    type: Literal["arm"] = "arm"
    arm: ArmView


class ProgramChanged(_View):
    type: Literal["program"] = "program"
    program: ProgramView


class PreviewChanged(_View):
    type: Literal["preview"] = "preview"
    preview: PreviewView


class SentChanged(_View):
    type: Literal["sent"] = "sent"
    sent: SentListView


class LinkChanged(_View):
    type: Literal["link"] = "link"
    link: LinkView


class RemoteArmChanged(_View):
    type: Literal["remote"] = "remote"
    remote: RemoteArmView


class PredictedPathChanged(_View):
    type: Literal["predicted"] = "predicted"
    predicted: PredictedPathView


class CollisionChanged(_View):
    type: Literal["collision"] = "collision"
    collision: CollisionView


class RegimeChanged(_View):
    type: Literal["regime"] = "regime"
    regime: RegimeView


class DisplayModeChanged(_View):
    type: Literal["display"] = "display"
    display: DisplayMode


class DivergenceChanged(_View):
    type: Literal["divergence"] = "divergence"
    divergence: DivergenceView


class TerrainChanged(_View):
    type: Literal["terrain"] = "terrain"
    terrain: TerrainView


class PlacementChanged(_View):
    type: Literal["placement"] = "placement"
    placement: PlacementView | None


class ControlChanged(_View):
    type: Literal["control"] = "control"
    control: ControlView


class ReadinessChanged(_View):
    """What Submit needs for the whole program changed (regime, program, confirmation, preview,
    the sent list)."""

    type: Literal["readiness"] = "readiness"
    readiness: SubmitReadiness


class Notice(_View):
    """A sentence for the operator: a refused operation, a rejected communication, a warning."""

    type: Literal["notice"] = "notice"
    level: Literal["info", "warning", "error"]
    message: str
    rule: str | None = None


class ActionTaken(_View):
    """The operator asked for a recovery or a re-sync (what the robot answered comes as a
    ``Notice`` and in the link view)."""

    type: Literal["action"] = "action"
    action: Literal["stop", "resume", "skip", "abort", "back_away", "resync"]
    client: str | None = Field(None, description="the caller's label; None: the page")
    detail: str = ""


class RangeSubmitted(_View):
    """A range left for the robot, with the console's plan of it (what it predicts the robot does)."""

    type: Literal["submitted"] = "submitted"
    ids: list[int] = Field(description="console-local ids of the statements sent (SentView.id)")
    texts: list[str]
    start_q: list[float] | None = Field(None, description="where the plan starts, rad; None when the start is unknown")
    plan_t: list[float] = Field(default_factory=list, description="plan times from the range's start, s")
    plan_q: list[list[float]] = Field(default_factory=list, description="joint vector at each plan time, rad")
    statement_starts: list[float] = Field(default_factory=list, description="plan time each statement starts, s")
    statement_ends: list[float] = Field(default_factory=list)
    complete: bool = Field(False, description="the plan covers the whole range (no refusal, no task whose end only the robot knows)")


class TaskChanged(_View):
    """The task panel's state changed: an action recognised, a marking moved, a deviation."""

    type: Literal["task"] = "task"
    task: TaskView


WorkKind = Literal["load", "task_play"]


class WorkProgress(_View):
    """Long work under way off the console's loop (``server.console.work``): a program file's
    load, the task monitor's replay of a range. Published once it has run 0.3 s, then at most
    every 0.2 s, and once more with ``finished`` when it ends."""

    type: Literal["work"] = "work"
    id: int = Field(description="one run of the work: its events share it")
    work: WorkKind
    what: str = Field(description="what it does, for a person (\"loading big.tp\")")
    phase: str = Field(description="the step it is in (load: parse, check, plan, format)")
    fraction: float = Field(ge=0.0, le=1.0, description="how much of it is done")
    elapsed_s: float = Field(ge=0.0)
    finished: bool = False


SessionEvent = Annotated[
    Union[
        ArmChanged, ProgramChanged, PreviewChanged, SentChanged, LinkChanged, RemoteArmChanged,
        PredictedPathChanged, CollisionChanged, RegimeChanged, DisplayModeChanged, DivergenceChanged,
        ControlChanged, TerrainChanged, PlacementChanged, ReadinessChanged, Notice, ActionTaken,
        RangeSubmitted, TaskChanged, WorkProgress,
    ],
    Field(discriminator="type"),
]
