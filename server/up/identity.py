"""The console's identity with its robot, kept across restarts.

The robot keeps its books per client id (``shared.wire.session``): what it answered, what it
applied, which statements each client sent. A console that keeps its id can be told, when it
starts again after a crash, what the robot holds and ran for it (``Welcome.holds`` and ``ran``),
and its counters go on from the robot's (``CommandSender.adopt``). The id lives in a small file
in the recording folder (``ConsoleSettings.identity_file``), locked (``flock``) while the console
runs: a second console started on the same folder gets a fresh id of its own rather than
sharing one (two consoles under one identity would take each other's answers). The lock goes
with the process, however it ends, so a console killed with SIGKILL leaves the id to the next.
"""

from __future__ import annotations

import fcntl
import logging
import os
import re
import uuid
from pathlib import Path

log = logging.getLogger(__name__)

_ID = re.compile(r"console-[0-9a-f]{12}")
_held: list[int] = []  # the locked files' descriptors, open for the process's life


def new_identity() -> str:
    return f"console-{uuid.uuid4().hex[:12]}"


def console_identity(path: Path) -> str:
    """The id kept in ``path`` (made and written there the first time), locked for this process;
    a fresh id, not kept, when the file is locked by another console or cannot be used (logged)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
    except OSError as exc:
        log.warning("cannot keep the console's identity in %s (%s): this run's is new and not kept", path, exc.strerror or exc)
        return new_identity()
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        log.warning("another console runs with the identity kept in %s: this one gets its own, not kept", path)
        return new_identity()
    text = os.pread(fd, 64, 0).decode("ascii", "replace").strip()
    if _ID.fullmatch(text):
        log.info("console identity %s (kept in %s)", text, path)
    else:
        text = new_identity()
        os.ftruncate(fd, 0)
        os.pwrite(fd, (text + "\n").encode("ascii"), 0)
        os.fsync(fd)
        log.info("console identity %s, kept in %s for the next start", text, path)
    _held.append(fd)
    return text
