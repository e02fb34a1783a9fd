"""Strict editing from the start (issue 37): ``teleprog up --strict-editing`` and
``TELEPROG_STRICT_EDITING`` reach the session's editor, as the Program tab's box does later."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.cli import build_parser
from server.settings import ConsoleSettings
from server.up.early import settings_from_args


def test_the_flag_and_the_variable_set_strict_editing(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("TELEPROG_STRICT_EDITING", raising=False)
    assert settings_from_args(build_parser().parse_args(["up"])).strict_editing is False
    assert settings_from_args(build_parser().parse_args(["up", "--strict-editing"])).strict_editing is True
    monkeypatch.setenv("TELEPROG_STRICT_EDITING", "1")
    assert settings_from_args(build_parser().parse_args(["up"])).strict_editing is True


@pytest.mark.parametrize("strict", [False, True])
def test_the_console_starts_in_the_editing_mode_its_settings_name(strict: bool) -> None:
    with TestClient(create_app(ConsoleSettings(no_robot=True, record=False, strict_editing=strict), build_page=False)) as client:
        assert client.get("/api/program").json()["strict_editing"] is strict
