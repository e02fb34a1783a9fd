"""The robot's door: the credential its command and telemetry channels require.

The robot answers to one console. Both channels are WebSocket upgrades that must present
``Authorization: Bearer <credential>``; one without it, or with another credential, is refused
with HTTP 401 and one line saying why, before any message is read. ``teleprog up`` makes a fresh
credential for the robot and console it starts and hands it to the robot through the child's
environment (``TELEPROG_ROBOT_CREDENTIAL``, readable by the same user only). A robot started on
its own takes the credential from that variable or from a file readable by its user alone
(``--credential-file``); given neither, it makes one and writes it to such a file, naming the
file (never the credential) in its first line. The link relay passes the header through
unchanged and never logs it.

The credential is an opaque string of 16 to 256 printable ASCII characters without spaces. Its
comparison takes the same time whatever the mismatch (``hmac.compare_digest``).
"""

from __future__ import annotations

import hmac
import secrets
import stat
from pathlib import Path

from shared.errors import InputError

ENV_VAR = "TELEPROG_ROBOT_CREDENTIAL"
"""The environment variable the robot and the console read the credential from."""
HEADER = "Authorization"
SCHEME = "Bearer"
MIN_CHARS = 16
MAX_CHARS = 256


def new_credential() -> str:
    """A fresh credential: 256 random bits, URL-safe text."""
    return secrets.token_urlsafe(32)


def checked(value: str, where: str) -> str:
    """``value`` stripped of surrounding white space, if it is a credential; else ``InputError``
    naming ``where`` it came from (never the value)."""
    value = value.strip()
    if not MIN_CHARS <= len(value) <= MAX_CHARS:
        raise InputError(f"{where}: a credential has {MIN_CHARS} to {MAX_CHARS} characters, this one {len(value)}")
    if not all("!" <= c <= "~" for c in value):
        raise InputError(f"{where}: a credential is printable ASCII without spaces")
    return value


def read_credential_file(path: Path) -> str:
    """The credential in ``path``: a regular file that only its owner may read or write (as for
    an ssh key). Refused, naming the file and why, when it is missing, special, too open or empty."""
    try:
        info = path.stat()
    except OSError as exc:
        raise InputError(f"credential file {path}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"credential file {path}: not a regular file")
    if info.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise InputError(
            f"credential file {path}: readable or writable by others (mode {stat.S_IMODE(info.st_mode):o}); "
            f"make it the owner's alone: chmod 600 {path}"
        )
    if info.st_size > 4 * MAX_CHARS:
        raise InputError(f"credential file {path}: {info.st_size} bytes, more than a credential")
    try:
        text = path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"credential file {path}: cannot be read as ASCII text ({type(exc).__name__})") from None
    return checked(text, f"credential file {path}")


def headers(credential: str | None) -> dict[str, str]:
    """The upgrade request's headers that present ``credential`` (none for None)."""
    return {} if credential is None else {HEADER: f"{SCHEME} {credential}"}


def presented(header_value: str | None) -> str | None:
    """The credential an ``Authorization`` header value presents (None if it presents none)."""
    if header_value is None:
        return None
    scheme, _, value = header_value.strip().partition(" ")
    return value.strip() or None if scheme.lower() == SCHEME.lower() else None


def refusal(header_value: str | None, credential: str) -> str | None:
    """Why a connection that sent ``header_value`` as its ``Authorization`` is refused (None: it
    presents ``credential``). The reason never contains either credential."""
    given = presented(header_value)
    if given is None:
        return (f"no credential: the robot answers only to its console ('{HEADER}: {SCHEME} ...'; "
                f"the console takes {ENV_VAR} or --robot-credential-file)")
    if not hmac.compare_digest(given.encode(), credential.encode()):
        return "wrong credential: the robot answers only to its console"
    return None

