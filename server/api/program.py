"""The programming panel (§4.3.6): select (one entry, a range, a move of the cursor), insert,
delete (the selection or a range), modify, conditions, move statements, undo/redo, the editing
mode (free, the default, or the thesis's strict rules), automatic generation, load and save
program files. The page's program list calls these from clicks and keys
(``server/program_keys_js.py``). A refused edit is a 409 whose ``rule`` is the stable id and whose
``detail`` the sentence for the operator."""

from __future__ import annotations

from typing import Literal

from starlette.concurrency import run_in_threadpool
from fastapi import APIRouter, Request
from fastapi.responses import PlainTextResponse
from pydantic import Field

from server.api.deps import ClientDep, SessionDep
from server.api_models import MAX_COUNT, ApiIn
from server.console import ProgramView
from shared.errors import InputError
from shared.language.statements import Speed, Statement, Until
from shared.program.editor import KEEP

router = APIRouter(prefix="/api/program", tags=["program"])


class SelectIn(ApiIn):
    index: int = Field(ge=-MAX_COUNT, le=MAX_COUNT, description="0-based; the trailing empty statement is entries[-1]")
    extend: bool = Field(False, description="select the range from the anchor to index (a shift-click)")


class RangeIn(ApiIn):
    first: int = Field(ge=-MAX_COUNT, le=MAX_COUNT, description="0-based first entry")
    last: int = Field(ge=-MAX_COUNT, le=MAX_COUNT, description="0-based last entry, included")


class MoveIn(ApiIn):
    by: Literal[-1, 1] = Field(description="1: the next entry (down), -1: the previous one (up)")
    extend: bool = Field(False, description="keep the anchor: extend the range (shift+arrow)")


class MoveStatementsIn(ApiIn):
    by: int = Field(ge=-MAX_COUNT, le=MAX_COUNT, description="places to move the selected statements: negative up, positive down")


class EditingIn(ApiIn):
    strict: bool = Field(description="true: the thesis's editing rules (§4.3.6); false: free editing (the default)")


class StatementIn(ApiIn):
    """A statement as text (``DRAW TO (600, 0, 300) mm``) or as its JSON form; exactly one."""

    text: str | None = Field(None, max_length=10_000)
    statement: Statement | None = None

    def resolve(self) -> Statement | str:
        """The statement model, or the text for the session to parse (after its lock check)."""
        if (self.text is None) == (self.statement is None):
            raise InputError("give the statement either as 'text' or as 'statement' (JSON form), not both or neither")
        return self.text if self.text is not None else self.statement  # type: ignore[return-value]


class ConditionsIn(ApiIn):
    """Fields left out are kept; ``null`` clears. Text forms: ``with`` like ``SPEED 20 %``,
    ``until`` like ``FORCE > 5 N``."""

    speed: Speed | None = None
    until: Until | None = None
    clear_speed: bool = False
    clear_until: bool = False


class AutoIn(ApiIn):
    on: bool


class LoadIn(ApiIn):
    text: str = Field(max_length=10_000_000, description="the file's content")
    filename: str = Field("program.tp", max_length=1000, description="its name; .json selects the JSON form")


@router.get("", response_model=ProgramView)
def get_program(session: SessionDep) -> ProgramView:
    return session.program.view()


@router.post("/select", response_model=ProgramView)
def select(body: SelectIn, session: SessionDep, client: ClientDep) -> ProgramView:
    return session.program.select(body.index, extend=body.extend, client=client)


@router.post("/select-range", response_model=ProgramView)
def select_range(body: RangeIn, session: SessionDep, client: ClientDep) -> ProgramView:
    """Select entries first..last (both included)."""
    return session.program.select_range(body.first, body.last, client=client)


@router.post("/move", response_model=ProgramView)
def move(body: MoveIn, session: SessionDep, client: ClientDep) -> ProgramView:
    """Move the selection one entry up or down (arrow keys); ``extend`` keeps its anchor."""
    return session.program.move_selection(body.by, extend=body.extend, client=client)


@router.post("/move-statements", response_model=ProgramView)
def move_statements(body: MoveStatementsIn, session: SessionDep, client: ClientDep) -> ProgramView:
    """Move the selected statements (Alt+arrow): one undo step; free editing re-plans the rest,
    strict editing moves only parameter statements and tasks that keep the arm still."""
    return session.program.move_statements(body.by, client=client)


@router.put("/editing", response_model=ProgramView)
def editing(body: EditingIn, session: SessionDep, client: ClientDep) -> ProgramView:
    """Free editing (the default) or the thesis's strict editing rules; not an edit, not undone."""
    return session.program.set_strict_editing(body.strict, client=client)


@router.post("/insert", response_model=ProgramView)
def insert(body: StatementIn, session: SessionDep, client: ClientDep) -> ProgramView:
    """Insert before the selection; 409 names the rule that refuses it."""
    return session.program.insert(body.resolve(), client=client)


@router.post("/delete", response_model=ProgramView)
def delete(session: SessionDep, client: ClientDep) -> ProgramView:
    """Delete the selected range (one undo step); 409 names the rule (GET /api/program: `refusal`, with its statement)."""
    return session.program.delete(client=client)


@router.post("/delete-range", response_model=ProgramView)
def delete_range(body: RangeIn, session: SessionDep, client: ClientDep) -> ProgramView:
    """Delete entries first..last (both included; the trailing empty statement stays)."""
    return session.program.delete(body.first, body.last, client=client)


@router.post("/modify", response_model=ProgramView)
def modify(body: StatementIn, session: SessionDep, client: ClientDep) -> ProgramView:
    return session.program.modify(body.resolve(), client=client)


@router.post("/conditions", response_model=ProgramView)
def conditions(body: ConditionsIn, session: SessionDep, client: ClientDep) -> ProgramView:
    """Set or clear the WITH speed and UNTIL condition of the selected action."""
    speed = None if body.clear_speed else (body.speed if body.speed is not None else KEEP)
    until = None if body.clear_until else (body.until if body.until is not None else KEEP)
    return session.program.modify_conditions(speed=speed, until=until, client=client)


@router.post("/undo", response_model=ProgramView)
def undo(session: SessionDep, client: ClientDep) -> ProgramView:
    return session.program.undo(client=client)


@router.post("/redo", response_model=ProgramView)
def redo(session: SessionDep, client: ClientDep) -> ProgramView:
    return session.program.redo(client=client)


@router.put("/auto", response_model=ProgramView)
def auto(body: AutoIn, session: SessionDep, client: ClientDep) -> ProgramView:
    """Automatic generation from the arm's motion on or off."""
    return session.program.set_auto_generate(body.on, client=client)


@router.post("/load", response_model=ProgramView)
def load(body: LoadIn, session: SessionDep, client: ClientDep) -> ProgramView:
    """Replace the program by a file's content; a broken file is a 400 naming file:line:col."""
    return session.program.load(body.text, body.filename, client=client)


@router.post("/upload", response_model=ProgramView)
async def upload(request: Request, session: SessionDep, client: ClientDep, filename: str = "program.tp") -> ProgramView:
    """The same as ``load`` with the file as the raw request body."""
    raw = await request.body()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{filename}: not UTF-8 text (byte {exc.start})") from None
    # parsing a long file takes seconds: on a worker thread, as the other endpoints run, never on the loop
    return await run_in_threadpool(session.program.load, text, filename, client=client)


@router.get("/save", response_class=PlainTextResponse)
def save(session: SessionDep, format: Literal["text", "json"] = "text") -> PlainTextResponse:
    """The program as a file (text form or JSON)."""
    return PlainTextResponse(session.program.save(format))
