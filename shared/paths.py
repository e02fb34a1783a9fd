"""Where the project's data files are (the ``assets/`` folder beside the packages)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

from pydantic import BeforeValidator

PROJECT_DIR = Path(__file__).resolve().parent.parent
ASSETS_DIR = PROJECT_DIR / "assets"
CELLS_DIR = ASSETS_DIR / "cells"
DEFAULT_CELL = CELLS_DIR / "peg_in_hole.toml"
"""The cell ``teleprog`` uses when none is named."""
USER_CACHE_DIR = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "teleprog"
"""The default folder of the on-disk caches (the settings' ``cache_dir``)."""


def _empty_is_none(value: object) -> object:
    return None if value is None or str(value).strip() in ("", "none") else value


CacheDir = Annotated[Path | None, BeforeValidator(_empty_is_none)]
"""A settings field naming the cache folder: empty or ``none`` (a flag or variable) turns it off."""
