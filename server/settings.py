"""The console's one typed settings object: defaults that run, overridden by environment
variables (``TELEPROG_PORT=9000``, ``TELEPROG_DELAY_MS=200``) and then by command-line flags."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from shared.cells.loader import DEFAULT_CELL


class ConsoleSettings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="TELEPROG_", extra="ignore")

    host: str = Field("127.0.0.1", description="address the console binds")
    port: int = Field(8080, ge=0, le=65535, description="HTTP port of the console (0: any free port)")
    cell: Path = Field(DEFAULT_CELL, description="workcell file")
    viser_prefix: str = Field("/viser", description="path under which the 3D page is served")
    robot_url: str | None = Field(
        None, description="ws:// base URL of a robot or link to use (teleprog up starts its own when unset)"
    )
    no_robot: bool = Field(False, description="console only: no robot, no link (nothing can be submitted)")
    delay_ms: float = Field(3000.0, ge=0.0, description="delay of the started link, each way, ms")
    robot_port: int = Field(0, ge=0, le=65535, description="port of the started telerobot (0: any free)")
    link_port: int = Field(0, ge=0, le=65535, description="port of the started link (0: any free)")
    child_start_timeout_s: float = Field(60.0, gt=0, description="how long to wait for robot and link to listen")

    def with_overrides(self, **overrides: object) -> "ConsoleSettings":
        """A copy with the given non-None values replaced (command-line flags), validated."""
        values = {k: v for k, v in overrides.items() if v is not None}
        return type(self).model_validate({**self.model_dump(), **values})
