"""The console's one typed settings object: defaults that run, overridden by environment
variables (``TELEPROG_PORT=9000``) and then by command-line flags."""

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

    def with_overrides(self, **overrides: object) -> "ConsoleSettings":
        """A copy with the given non-None values replaced (command-line flags)."""
        values = {k: v for k, v in overrides.items() if v is not None}
        return self.model_copy(update=values)
