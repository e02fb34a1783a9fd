"""The robot's door (shared.wire.credential) in-process, stated exactly: pinned by its mutation run
(issue 38). tests/safety/test_robot_credential.py drives the same rules through real processes."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from shared.errors import InputError
from shared.wire.credential import (
    ENV_VAR,
    HEADER,
    MAX_CHARS,
    MIN_CHARS,
    SCHEME,
    checked,
    headers,
    new_credential,
    presented,
    read_credential_file,
    refusal,
)

GOOD = "s3cret-credential-0123456789"


def test_the_names_of_the_door():
    assert (ENV_VAR, HEADER, SCHEME, MIN_CHARS, MAX_CHARS) == ("TELEPROG_ROBOT_CREDENTIAL", "Authorization", "Bearer", 16, 256)


def test_a_new_credential_is_256_random_bits_as_url_safe_text():
    made = {new_credential() for _ in range(20)}
    assert len(made) == 20
    for value in made:
        assert len(value) == 43  # 32 bytes in unpadded base64
        assert checked(value, "new") == value


def test_a_credential_is_16_to_256_printable_characters_stripped_of_white_space():
    assert checked(f"  {GOOD}\n", "here") == GOOD
    assert checked("a" * MIN_CHARS, "here") == "a" * MIN_CHARS
    assert checked("b" * MAX_CHARS, "here") == "b" * MAX_CHARS
    assert checked("!" + "~" * 15, "here") == "!" + "~" * 15  # the ends of printable ASCII
    with pytest.raises(InputError) as err:
        checked("a" * (MIN_CHARS - 1), "the variable")
    assert str(err.value) == "the variable: a credential has 16 to 256 characters, this one 15"
    with pytest.raises(InputError) as err:
        checked("a" * (MAX_CHARS + 1), "the variable")
    assert str(err.value) == "the variable: a credential has 16 to 256 characters, this one 257"
    with pytest.raises(InputError) as err:
        checked("   " + "a" * 14 + "  ", "the file")  # 14 once stripped
    assert str(err.value) == "the file: a credential has 16 to 256 characters, this one 14"


@pytest.mark.parametrize("bad", ["with a space inside!!", "tab\tinside-a-credential", "é" * 16, "del\x7f" + "x" * 14])
def test_a_credential_is_printable_ascii_without_spaces(bad):
    with pytest.raises(InputError) as err:
        checked(bad, "the header")
    assert str(err.value) == "the header: a credential is printable ASCII without spaces"


def _file(tmp_path: Path, text: str | bytes, mode: int = 0o600) -> Path:
    path = tmp_path / "robot.credential"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    os.chmod(path, mode)
    return path


def test_a_credential_file_of_the_owner_alone_is_read_and_stripped(tmp_path):
    assert read_credential_file(_file(tmp_path, GOOD + "\n")) == GOOD
    assert read_credential_file(_file(tmp_path, GOOD, 0o400)) == GOOD


def test_a_missing_file_is_refused_with_the_reason(tmp_path):
    path = tmp_path / "absent"
    with pytest.raises(InputError) as err:
        read_credential_file(path)
    assert str(err.value) == f"credential file {path}: No such file or directory"


def test_a_folder_is_not_a_credential_file(tmp_path):
    folder = tmp_path / "folder"
    folder.mkdir(mode=0o700)
    with pytest.raises(InputError) as err:
        read_credential_file(folder)
    assert str(err.value) == f"credential file {folder}: not a regular file"


@pytest.mark.parametrize("mode", [0o640, 0o604, 0o620, 0o602, 0o610, 0o601, 0o666])
def test_a_file_others_may_touch_is_refused_with_its_mode_and_the_fix(tmp_path, mode):
    path = _file(tmp_path, GOOD, mode)
    with pytest.raises(InputError) as err:
        read_credential_file(path)
    assert str(err.value) == (f"credential file {path}: readable or writable by others (mode {mode:o}); "
                              f"make it the owner's alone: chmod 600 {path}")


def test_a_file_larger_than_four_credentials_is_refused(tmp_path):
    path = _file(tmp_path, "a" * (4 * MAX_CHARS))
    with pytest.raises(InputError) as err:  # 1024 bytes of 'a' pass the size, then fail the length
        read_credential_file(path)
    assert str(err.value) == f"credential file {path}: a credential has 16 to 256 characters, this one 1024"
    path = _file(tmp_path, "a" * (4 * MAX_CHARS + 1))
    with pytest.raises(InputError) as err:
        read_credential_file(path)
    assert str(err.value) == f"credential file {path}: 1025 bytes, more than a credential"


def test_a_file_that_is_not_ascii_is_refused_naming_the_error(tmp_path):
    path = _file(tmp_path, "é".encode() * 10)
    with pytest.raises(InputError) as err:
        read_credential_file(path)
    assert str(err.value) == f"credential file {path}: cannot be read as ASCII text (UnicodeDecodeError)"


def test_an_empty_file_is_refused_as_too_short(tmp_path):
    path = _file(tmp_path, "")
    with pytest.raises(InputError) as err:
        read_credential_file(path)
    assert str(err.value) == f"credential file {path}: a credential has 16 to 256 characters, this one 0"


def test_the_headers_present_the_credential_as_bearer():
    assert headers(GOOD) == {"Authorization": f"Bearer {GOOD}"}
    assert headers(None) == {}


def test_what_a_header_presents():
    assert presented(None) is None
    assert presented(f"Bearer {GOOD}") == GOOD
    assert presented(f"  bearer   {GOOD}  ") == GOOD  # the scheme in any case, white space around stripped
    assert presented(f"BEARER {GOOD}") == GOOD
    assert presented("Bearer") is None
    assert presented("Bearer ") is None
    assert presented(f"Basic {GOOD}") is None
    assert presented(GOOD) is None


def test_the_refusal_says_why_and_never_the_credential():
    assert refusal(f"Bearer {GOOD}", GOOD) is None
    assert refusal(None, GOOD) == (
        "no credential: the robot answers only to its console ('Authorization: Bearer ...'; "
        "the console takes TELEPROG_ROBOT_CREDENTIAL or --robot-credential-file)"
    )
    assert refusal(f"Basic {GOOD}", GOOD) == refusal(None, GOOD)
    wrong = refusal("Bearer another-credential-000000", GOOD)
    assert wrong == "wrong credential: the robot answers only to its console"
    assert refusal(f"Bearer {GOOD}x", GOOD) == wrong
    assert refusal(f"Bearer {GOOD[:-1]}", GOOD) == wrong


def test_a_read_only_file_mode_is_reported_in_octal(tmp_path):
    path = _file(tmp_path, GOOD, 0o644)
    with pytest.raises(InputError, match=r"\(mode 644\)"):
        read_credential_file(path)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
