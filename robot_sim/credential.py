"""Which credential this robot requires (``shared.wire.credential``), and the file a robot started
without one writes its own to.

In order: ``RobotSettings.credential`` (the ``TELEPROG_ROBOT_CREDENTIAL`` variable, which
``teleprog up`` sets for its robot), then ``credential_file``; given neither, a fresh credential
written to ``USER_STATE_DIR/robot-<port>.credential``, readable by the user alone, whose path the
robot prints (never the credential) for the console to be given (``--robot-credential-file``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from robot_sim.settings import RobotSettings
from shared.wire.credential import checked, new_credential, read_credential_file

USER_STATE_DIR = Path(os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state") / "teleprog"
"""Where a robot started without a credential writes the one it made."""


@dataclass(frozen=True)
class RobotCredential:
    """The credential and where it came from (``environment``, ``file`` or ``made``)."""

    secret: str
    source: str
    file: Path | None = None

    def __repr__(self) -> str:  # never the secret in a log or a traceback
        return f"RobotCredential(source={self.source!r}, file={self.file!r})"


def given_credential(settings: RobotSettings) -> RobotCredential | None:
    """The credential the settings give (checked), or None when they give none; ``InputError``
    for a bad one (one line naming where it came from)."""
    if settings.credential is not None:
        return RobotCredential(checked(settings.credential.get_secret_value(), "TELEPROG_ROBOT_CREDENTIAL"), "environment")
    if settings.credential_file is not None:
        path = settings.credential_file.expanduser()
        return RobotCredential(read_credential_file(path), "file", path)
    return None


def made_credential(port: int, folder: Path = USER_STATE_DIR) -> RobotCredential:
    """A fresh credential, written user-only to ``folder/robot-<port>.credential``."""
    path = folder / f"robot-{port}.credential"
    secret = new_credential()
    write_user_only(path, secret)
    return RobotCredential(secret, "made", path)


def write_user_only(path: Path, secret: str) -> None:
    """Write ``secret`` to ``path``, created readable and writable by its owner alone (an
    existing file is replaced; a folder made here is the owner's alone too)."""
    path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    try:
        os.fchmod(fd, 0o600)  # whatever the umask
        os.write(fd, (secret + "\n").encode("ascii"))
    finally:
        os.close(fd)
    os.replace(tmp, path)
