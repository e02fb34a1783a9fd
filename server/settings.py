"""The console's one typed settings object: defaults that run, overridden by environment
variables (``TELEPROG_PORT=9000``, ``TELEPROG_DELAY_MS=200``) and then by command-line flags."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, SecretStr
from pydantic_settings import BaseSettings, SettingsConfigDict

from shared.paths import DEFAULT_CELL, PROJECT_DIR, USER_CACHE_DIR, CacheDir
from shared.wire.liveness import DEFAULT_SILENCE_LIMIT_S


class ConsoleSettings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="TELEPROG_", extra="ignore")

    host: str = Field("127.0.0.1", description="address the console binds")
    port: int = Field(8080, ge=0, le=65535, description="HTTP port of the console (0: any free port)")
    cell: Path = Field(DEFAULT_CELL, description="workcell file")
    viser_prefix: str = Field("/viser", description="path under which the 3D page is served")
    gizmo_send_interval_ms: int = Field(
        10, ge=0, le=1000,
        description="the page sends the gizmo's drag updates at most this often, ms (0: viser's own 50 ms)",
    )
    robot_url: str | None = Field(
        None, description="ws:// base URL of a robot or link to use (teleprog up starts its own when unset)"
    )
    robot_credential: SecretStr | None = Field(
        None, description="the credential of the robot at robot_url (TELEPROG_ROBOT_CREDENTIAL); "
        "the robot teleprog up starts gets this one, or a new one when unset",
    )
    robot_credential_file: Path | None = Field(
        None, description="a file, readable by its owner alone, with the robot's credential (when none is set)",
    )
    identity_file: str = Field(
        ".console-identity", description="file in record_dir keeping this console's identity with its robot across restarts",
    )
    strict_editing: bool = Field(
        False, description="the editor keeps the thesis's editing rules (§4.3.6) instead of free editing (--strict-editing)",
    )
    handover_timeout_s: float = Field(
        30.0, gt=0.0, description="a request for control the holder neither hands over nor refuses passes control after this, s",
    )
    no_robot: bool = Field(False, description="console only: no robot, no link (nothing can be submitted)")
    delay_ms: float = Field(3000.0, ge=0.0, description="delay of the started link, each way, ms")
    robot_port: int = Field(0, ge=0, le=65535, description="port of the started telerobot (0: any free)")
    link_port: int = Field(0, ge=0, le=65535, description="port of the started link (0: any free)")
    cache_dir: CacheDir = Field(
        USER_CACHE_DIR,
        description="folder of the collision-model cache, built once per robot and cell (TELEPROG_CACHE_DIR; empty: none)",
    )
    child_start_timeout_s: float = Field(60.0, gt=0, description="how long to wait for robot and link to listen")
    restart_children: bool = Field(
        True, description="teleprog up starts a telerobot or link child again, on its port, when it exits (--no-restart: off)"
    )
    silence_limit_s: float = Field(
        DEFAULT_SILENCE_LIMIT_S, gt=0.0, le=3600.0,
        description="silence beyond the expected arrival after which the console shows the robot silent, telemetry stale (s)",
    )
    record: bool = Field(True, description="record the session into an MCAP file (--no-record: off)")
    record_dir: Path = Field(
        PROJECT_DIR / "recordings", description="folder of the session recordings (--record DIR; GET /api/sessions lists it)"
    )
    record_queue: int = Field(20_000, ge=100, description="messages the recorder may hold before it drops (never blocks)")
    record_flush_s: float = Field(
        1.0, gt=0.0, le=60.0, description="a chunk is closed at least this often: a killed console loses at most this much (s)"
    )
    fault_injection: bool = Field(
        False, description="serve /api/faults (the console misbehaving on purpose, for tests and surprise campaigns; never on by default)"
    )
    # the sedimentation view (``teleprog up --sedimentation``, thesis chapter 5)
    sedimentation: bool = Field(False, description="serve the particle-sedimentation view instead of the robot console")
    sedimentation_method: str = Field("usscd", description="broadphase method the sedimentation view starts with")
    sedimentation_n: int = Field(2000, ge=2, description="number of bodies the sedimentation view starts with")
    sedimentation_kind: str = Field("uniform", description="scene kind: uniform, gaussian or sediment")
    sedimentation_speed: float = Field(0.5, ge=0.0, description="SPEED, length units per frame (sphere radius 1)")
    sedimentation_density: float = Field(0.0005, gt=0.0, description="bodies per unit volume, N / L^3")
    sedimentation_max_n: int = Field(200_000, ge=2, description="largest N the operator may choose")
    sedimentation_steps_hz: float = Field(40.0, gt=0.0, description="most frames simulated per second")
    sedimentation_draw_hz: float = Field(20.0, gt=0.0, description="most pictures sent to the page per second")

    def with_overrides(self, **overrides: object) -> "ConsoleSettings":
        """A copy with the given non-None values replaced (command-line flags), validated."""
        values = {k: v for k, v in overrides.items() if v is not None}
        return type(self).model_validate({**self.model_dump(), **values})

    def page_send_intervals_ms(self) -> dict[str, int]:
        """The senders of viser's page to re-pace (``server.viser_page.SENDERS``), by name."""
        return {"gizmo": self.gizmo_send_interval_ms} if self.gizmo_send_interval_ms else {}
