"""The telerobot's settings: the process (``RobotSettings``), its world (``WorldSettings``) and its
executor (``ExecutorSettings``). Pydantic only, so ``teleprog robot`` reads its settings and
listens before it imports the collision and motion code (``robot_sim.service``)."""

from __future__ import annotations

from typing import Literal

from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, SecretStr
from pydantic_settings import BaseSettings, SettingsConfigDict

from shared.language import bounds
from shared.paths import DEFAULT_CELL, USER_CACHE_DIR, CacheDir
from shared.wire.liveness import DEFAULT_SILENCE_LIMIT_S, HEARTBEAT_INTERVAL_S
from shared.wire.telemetry import FRAME_RATE_HZ


class WorldSettings(BaseModel):
    """How the real world departs from the model, and how it feels. Defaults run the peg task.

    ``engine``: ``physics`` (MuJoCo contact physics, ``robot_sim.physics``; the default) or
    ``kinematic`` (the analytic stand-in, kept for unit tests that need its speed). No setting
    gives a chance of success: on physics a peg sticks, jams or slips when the contact makes it."""

    model_config = ConfigDict(extra="forbid")

    engine: Literal["physics", "kinematic"] = "physics"
    seed: int = 0
    object_offset: float = Field(0.0005, ge=0.0, description="max xy offset of movable objects and holes (m)")
    force_noise: float = Field(0.05, ge=0.0, description="std of force-sensor noise (N)")
    contact_stiffness: float = Field(2.0e5, gt=0.0, description="N per m of commanded penetration")
    chamfer: float = Field(0.0015, gt=0.0, description="lateral capture radius of a hole mouth (m)")
    grasp_tilt: float = Field(0.0, ge=-0.5, le=0.5, description="tilt (rad) the peg settles at in the fingers once clear of its hole (physics)")
    friction: float | None = Field(None, ge=0.0, le=10.0, description="sliding friction of the cell's contacts; None: the cell's [physics] value")
    clearance: float | None = Field(None, ge=0.0, le=0.005, description="fit of the peg in its hole (m); None: the cell's geometry")
    object_mass_factor: float = Field(1.0, gt=0.0, le=100.0,
                                      description="the movable objects' true mass against the model's (physics; the robot tares for the model's)")
    grasp_tolerance: float = Field(0.004, gt=0.0, description="gripper-to-grasp-point distance that still grasps (m)")
    hole_depth: float = Field(0.030, gt=0.0, description="depth of every hole feature (m)")


class ExecutorSettings(BaseModel):
    """Servo rate and the safety thresholds of the executor."""

    servo_rate: float = Field(100.0, gt=0.0, description="joint servo rate (Hz)")
    contact_limit: float = Field(15.0, gt=0.0, description="force (N) that counts as unplanned contact in position mode")
    max_force: float = Field(80.0, gt=0.0, description="force (N) that stops any motion, guarded or not")
    touch_force: float = Field(3.0, gt=0.0, description="force (N) a task's guarded descent stops at")
    extract_limit: float = Field(40.0, gt=0.0, description="pull (N) at which extraction gives up: the peg is stuck")
    task_speed: float = Field(0.2, ge=bounds.MIN_SPEED_FRACTION, le=1.0, description="speed of task motions (fraction of maximum)")
    search_pitch: float = Field(0.001, gt=0.0, description="spacing of the turns of the physics' spiral search (m)")
    search_speed: float = Field(0.01, gt=0.0, le=0.1, description="sliding speed of the physics' spiral search (m/s)")
    force_gain: float = Field(0.0005, gt=0.0, description="the search's force loop: vertical speed per newton of force error (m/s/N)")
    search_step: float = Field(0.0005, gt=0.0, description="spacing of the hole-search spiral (m)")
    search_radius: float = Field(0.004, gt=0.0, description="how far from the first contact the search goes (m)")
    interference_zones: bool = Field(True, description="route joint moves round the arm's interference zones (seed 001)")
    collision_checks: bool = Field(True, description="stop on any contact of the arm with the cell (collision core)")
    gripper_time: float = Field(0.4, gt=0.0, le=5.0, description="time the fingers get to close or open (s, physics)")
    guarded_speed: float = Field(0.01, ge=bounds.MIN_LINEAR_SPEED_M_S, le=0.1,
                                 description="speed of a task's guarded moves towards contact (m/s, physics)")
    press_force: float = Field(12.0, gt=0.0, description="push (N) with which an insertion presses a peg onto a chamfer or edge (physics)")
    press_settle: float = Field(0.15, ge=0.0, le=2.0, description="time the compliance gets to slide a pressed peg in (s, physics)")
    seat_force: float = Field(25.0, gt=0.0, description="push (N) with which an insertion that stopped short tries to seat its peg (physics)")
    seat_tolerance: float = Field(0.002, gt=0.0, description="how far above the hole's floor a peg still counts as seated (m)")
    jam_time: float = Field(0.5, gt=0.0, description="time without progress under the seating push after which a peg is jammed (s)")
    compliance_speed: float = Field(0.0005, ge=0.0, description="compliance: sideways speed of the tool per newton across its axis (m/s/N)")
    compliance_turn: float = Field(0.0, ge=0.0, description="compliance: turning speed of the tool per newton metre about the axes across it (rad/s/(N m))")
    compliance_range: float = Field(0.004, ge=0.0, description="compliance: how far the tool may give way from its planned path (m)")
    compliance_tilt: float = Field(0.06, ge=0.0, description="compliance: how far the tool may turn from its planned path (rad)")
    following_error: float = Field(0.004, gt=0.0, le=0.1,
                                   description="the flange this far (m) from where the joint servo is commanded stops the arm (physics): a joint drags, or something holds the arm")
    max_queue: int = Field(5000, ge=1, description="statements the buffer holds; a communication that would overflow it is refused")


class RobotSettings(BaseSettings):
    """The telerobot process: defaults that run, then ``TELEPROG_ROBOT_*`` variables, then flags."""

    model_config = SettingsConfigDict(env_prefix="TELEPROG_ROBOT_", env_nested_delimiter="__")

    host: str = "127.0.0.1"
    port: int = 8766
    cell: str = str(DEFAULT_CELL)
    telemetry_rate: float = FRAME_RATE_HZ
    heartbeat_s: float = Field(HEARTBEAT_INTERVAL_S, gt=0.0, le=60.0, description="interval of the robot's heartbeats (s)")
    silence_limit_s: float = Field(
        DEFAULT_SILENCE_LIMIT_S, gt=0.0, le=3600.0,
        description="silence from the console beyond the heartbeat interval at which the robot stops (s)",
    )
    cache_dir: CacheDir = Field(
        USER_CACHE_DIR, description="folder of the collision-model cache (teleprog up passes its own; empty: none)"
    )
    listen_first: bool = Field(
        False,
        description="listen before loading the cell and building the core; /health says core_ready "
        "(teleprog up, which loaded the cell already, starts its telerobot so)",
    )
    credential: SecretStr | None = Field(
        None, description="the credential consoles must present (TELEPROG_ROBOT_CREDENTIAL; teleprog up sets it for its robot)",
    )
    credential_file: Path | None = Field(
        None, description="a file, readable by its owner alone, holding the credential (used when no credential is set; "
        "with neither, the robot makes one and writes it to a file it names)",
    )
    world: WorldSettings = WorldSettings()
    executor: ExecutorSettings = ExecutorSettings()
