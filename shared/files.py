"""Opening a file that a person or a client names, without surprises.

``name_in_folder(folder, name)`` is where a name a client gives (over HTTP, from a page) may lead:
only inside the configured folder, symlinks followed (``..``, an absolute path elsewhere and a
symlink leading out are refused). ``regular_file(path)`` checks with ``os.stat`` that a path is a
regular file before anything opens it: opening a FIFO blocks until a writer comes, a device or a
socket is no file to read. ``open_regular(path)`` opens one for reading without blocking on a
FIFO swapped in meanwhile. Every refusal is an ``InputError`` of one line that names the path and
never quotes what the file holds.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import BinaryIO

from shared.errors import InputError

MAX_NAME_SHOWN = 200
"""Characters of a client's name quoted in a message at most."""


def shown_name(name: str) -> str:
    """A name a client gave, quoted and cut short for a message."""
    return repr(name if len(name) <= MAX_NAME_SHOWN else name[:MAX_NAME_SHOWN] + "...")


def kind_of(mode: int) -> str:
    """What a file of ``st_mode`` is, for a message (``a FIFO (named pipe)``)."""
    if stat.S_ISREG(mode):
        return "a regular file"
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    return "not a regular file"


def name_in_folder(folder: str | Path, name: str, what: str = "file") -> Path:
    """The resolved path of ``name`` inside ``folder`` (a name, a relative path, or an absolute
    path that leads into the folder); ``InputError`` when it leads anywhere else. Whether the file
    exists is not checked here."""
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"give the name of a {what} in {folder}")
    if "\x00" in name:
        raise InputError(f"{what} name {shown_name(name)}: holds a NUL character")
    try:
        root = Path(folder).resolve()
        given = Path(name)
        path = (given if given.is_absolute() else root / given).resolve()
    except (OSError, RuntimeError, ValueError) as exc:  # a symlink loop, a name too long
        raise InputError(f"{what} {shown_name(name)}: cannot be resolved ({type(exc).__name__})") from None
    if path != root and root not in path.parents:
        raise InputError(f"{what} {shown_name(name)} is outside the folder {root}: only names in that folder may be opened")
    return path


def regular_file(path: str | Path, what: str = "file") -> os.stat_result:
    """``os.stat`` of ``path`` (symlinks followed); ``InputError`` when it cannot be read or is
    not a regular file. Nothing is opened."""
    try:
        st = os.stat(path)
    except (OSError, ValueError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else type(exc).__name__
        raise InputError(f"{path}: cannot read the {what}: {reason}") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{path}: cannot read the {what}: it is {kind_of(st.st_mode)}, not a regular file")
    return st


def open_regular(path: str | Path, what: str = "file") -> tuple[BinaryIO, int]:
    """``path`` opened for binary reading, and its size: checked with ``regular_file`` first,
    opened without blocking (a FIFO put in its place meanwhile is refused, never waited on)."""
    regular_file(path, what)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NOCTTY", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what}: {exc.strerror or type(exc).__name__}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"{path}: cannot read the {what}: it is {kind_of(st.st_mode)}, not a regular file")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb"), st.st_size
    except BaseException:
        os.close(fd)
        raise
