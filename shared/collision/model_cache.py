"""On-disk cache of collision-model arrays (OBB trees, sampled self-collision grids), keyed by
content, so a process that starts with the same robot and cell reads them instead of building.

Off until a caller hands it a folder (``configure``; ``teleprog up`` and the telerobot pass their
settings' ``cache_dir``, default ``~/.cache/teleprog``, ``TELEPROG_CACHE_DIR`` to override):
shared code only reads and writes the folder it is given.

A file is named ``<kind>-<sha256>.npz``; the key hashes everything the arrays depend on: the
inputs the caller names (triangles, joint limits, the robot file's content ...) and the source of
the code that builds them (``code_fingerprint``), so a change of either misses and rebuilds.
Safety:

* a file that cannot be read, lacks an array, or carries another key (a truncated write, a
  corrupt disk, a hash collision) is ignored, logged, rebuilt and overwritten;
* a file is written to a temporary name in the same folder and moved into place with
  ``os.replace``: readers see the old file or the whole new one, never a part, and two processes
  writing the same entry at once both leave a whole file;
* a folder that cannot be written only costs the build (logged once per process).
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
import tempfile
import zipfile
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

FORMAT = 1
"""Bumped when the file layout changes."""

_KEY_NAME = "__key__"
_folder: Path | None = None
_write_failed = False


def configure(folder: Path | str | None) -> None:
    """Use ``folder`` for the cache (created when first written); None turns the cache off."""
    global _folder
    _folder = None if folder is None or str(folder) == "" else Path(folder).expanduser()


def folder() -> Path | None:
    return _folder


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """Hash of the source of the code the cached arrays come from (collision and robot models)."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for sub in ("collision", "robots", "cells"):
        for path in sorted((root / sub).glob("*.py")):
            h.update(path.name.encode())
            h.update(path.read_bytes())
    return h.hexdigest()


def content_key(kind: str, parts: Iterable[object]) -> str:
    """sha256 of ``kind``, the file format, the code fingerprint and ``parts`` (arrays by dtype,
    shape and bytes; bytes as they are; anything else by its ``repr``)."""
    h = hashlib.sha256(f"{kind}\0{FORMAT}\0{code_fingerprint()}".encode())
    for part in parts:
        if isinstance(part, np.ndarray):
            a = np.ascontiguousarray(part)
            h.update(f"\0a{a.dtype.str}{a.shape}".encode())
            h.update(a.tobytes())
        elif isinstance(part, (bytes, bytearray)):
            h.update(b"\0b%d:" % len(part))
            h.update(part)
        else:
            h.update(f"\0r{part!r}".encode())
    return h.hexdigest()


def file_for(kind: str, key: str) -> Path | None:
    return None if _folder is None else _folder / f"{kind}-{key}.npz"


def load(kind: str, key: str, names: Iterable[str]) -> dict[str, np.ndarray] | None:
    """The arrays stored under ``key``, or None (no cache, no file, or a file that is not whole)."""
    path = file_for(kind, key)
    if path is None or not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as npz:
            if str(npz[_KEY_NAME]) != key:
                raise ValueError("the file carries another key")
            return {name: npz[name] for name in names}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        log.warning("ignoring the cache file %s (%s); building afresh", path, exc or type(exc).__name__)
        return None


def store(kind: str, key: str, arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` under ``key`` (whole or not at all, see the module docstring)."""
    global _write_failed
    path = file_for(kind, key)
    if path is None:
        return
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{kind}-", suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **{_KEY_NAME: np.array(key)}, **arrays)
        os.replace(tmp, path)
        tmp = None
    except OSError as exc:
        if not _write_failed:
            log.warning("cannot write the collision-model cache in %s: %s", path.parent, exc)
            _write_failed = True
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass


def cached_arrays(
    kind: str, parts: Iterable[object], names: Iterable[str], build: Callable[[], dict[str, np.ndarray]]
) -> dict[str, np.ndarray]:
    """The arrays ``build()`` makes from ``parts``: read from the cache when a whole file is
    there, else built and stored. Without a folder, just ``build()``."""
    if _folder is None:
        return build()
    names = tuple(names)
    key = content_key(kind, parts)
    found = load(kind, key, names)
    if found is not None:
        return found
    arrays = build()
    store(kind, key, arrays)
    return arrays
