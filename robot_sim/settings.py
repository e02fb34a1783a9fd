"""The telerobot's settings: the process (``RobotSettings``), its world (``WorldSettings``) and its
executor (``ExecutorSettings``). Pydantic only, so ``teleprog robot`` reads its settings and
listens before it imports the collision and motion code (``robot_sim.service``)."""

from __future__ import annotations

from pydantic import BaseModel, Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from shared.paths import DEFAULT_CELL, USER_CACHE_DIR, CacheDir
from shared.wire.liveness import DEFAULT_SILENCE_LIMIT_S, HEARTBEAT_INTERVAL_S
from shared.wire.telemetry import FRAME_RATE_HZ


class WorldSettings(BaseModel):
    """How the real world departs from the model, and how it feels. Defaults run the peg task."""

    seed: int = 0
    object_offset: float = Field(0.0005, ge=0.0, description="max xy offset of movable objects and holes (m)")
    force_noise: float = Field(0.05, ge=0.0, description="std of force-sensor noise (N)")
    contact_stiffness: float = Field(2.0e5, gt=0.0, description="N per m of commanded penetration")
    chamfer: float = Field(0.0015, gt=0.0, description="lateral capture radius of a hole mouth (m)")
    stick_probability: float = Field(0.0, ge=0.0, le=1.0, description="chance a peg sticks when pulled")
    stick_force: float = Field(60.0, gt=0.0, description="pull (N) a stuck peg resists before it frees")
    grasp_tolerance: float = Field(0.004, gt=0.0, description="gripper-to-grasp-point distance that still grasps (m)")
    hole_depth: float = Field(0.030, gt=0.0, description="depth of every hole feature (m)")


class ExecutorSettings(BaseModel):
    """Servo rate and the safety thresholds of the executor."""

    servo_rate: float = Field(100.0, gt=0.0, description="joint servo rate (Hz)")
    contact_limit: float = Field(15.0, gt=0.0, description="force (N) that counts as unplanned contact in position mode")
    max_force: float = Field(80.0, gt=0.0, description="force (N) that stops any motion, guarded or not")
    touch_force: float = Field(3.0, gt=0.0, description="force (N) a task's guarded descent stops at")
    extract_limit: float = Field(40.0, gt=0.0, description="pull (N) at which extraction gives up: the peg is stuck")
    task_speed: float = Field(0.2, gt=0.0, le=1.0, description="speed of task motions (fraction of maximum)")
    search_step: float = Field(0.0005, gt=0.0, description="spacing of the hole-search spiral (m)")
    search_radius: float = Field(0.004, gt=0.0, description="how far from the first contact the search goes (m)")
    interference_zones: bool = Field(True, description="route joint moves round the arm's interference zones (seed 001)")
    collision_checks: bool = Field(True, description="stop on any contact of the arm with the cell (collision core)")
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
    world: WorldSettings = WorldSettings()
    executor: ExecutorSettings = ExecutorSettings()
