"""Checks a statement passes before it enters the program or leaves for the robot, whatever
built it (a parser, a generator, an API body): validated again by its own model and written as
text once, so nothing the program view cannot show, or the robot cannot read, gets in."""

from __future__ import annotations

from pydantic import ValidationError

from shared.errors import InputError, TeleprogError
from shared.language.formatter import format_statement
from shared.language.statements import Statement


_TEXTS: dict[int, tuple[Statement, str]] = {}
"""id(statement) -> (the statement, kept alive; its text): ``statement_text``'s."""


def checked_statement(statement: Statement) -> Statement:
    """``statement`` validated again by its own model and formatted once; ``InputError`` (a
    validation error) or the formatter's error names what is wrong."""
    try:
        checked = type(statement).model_validate(statement.model_dump())
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first.get("loc", ()))
        raise InputError(f"{statement.kind}: {where + ': ' if where else ''}{first.get('msg', 'invalid')}") from None
    text = format_statement(checked)  # raises InputError for what cannot be written (a NaN, say)
    _keep_text(statement, text)  # the same text: the two models are equal
    return checked


_REFUSALS: dict[int, tuple[Statement, str | None]] = {}
"""id(statement) -> (the statement, kept alive; what ``checked_statement`` says of it, or None)."""


def statement_refusal(statement: Statement) -> str | None:
    """What ``checked_statement`` refuses ``statement`` with, or None; once per statement object
    (statements are frozen), so readiness, asked after every change, checks only new lines."""
    kept = _REFUSALS.get(id(statement))
    if kept is not None and kept[0] is statement:
        return kept[1]
    try:
        checked_statement(statement)
        refusal = None
    except TeleprogError as exc:
        refusal = str(exc)
    if len(_REFUSALS) > 100_000:  # statements long gone keep ids alive: start again
        _REFUSALS.clear()
    _REFUSALS[id(statement)] = (statement, refusal)
    return refusal


def statement_text(statement: Statement) -> str:
    """The statement as text; one that cannot be written (a value no statement may hold) is
    named by its kind and why, so a list of what was sent can always be shown. Kept per
    statement object, as a refusal is (a submission writes each statement three times: its
    check, the sent list, the submission's event)."""
    kept = _TEXTS.get(id(statement))
    if kept is not None and kept[0] is statement:
        return kept[1]
    try:
        text = format_statement(statement)
    except Exception as exc:  # noqa: BLE001 - a list of what was sent must never fail to render
        text = f"{getattr(statement, 'kind', type(statement).__name__)} (cannot be written: {exc})"
    _keep_text(statement, text)
    return text


def _keep_text(statement: Statement, text: str) -> None:
    if len(_TEXTS) > 100_000:  # statements long gone keep ids alive: start again
        _TEXTS.clear()
    _TEXTS[id(statement)] = (statement, text)
