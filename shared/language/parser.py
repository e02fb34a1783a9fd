"""Text form of a program -> typed statements, with every error located at line and column.

One statement a line; ``#`` starts a comment; keywords, frame names, modes and units are
case-insensitive. Grammar (``num`` is a signed decimal with optional exponent)::

    MOVE '(' num {',' num} ')' deg tail
    DRIVE J<n> TO num deg tail
    DRAW TO '(' num ',' num ',' num ')' mm tail
    ROTATE TO '(' num ',' num ',' num ')' deg tail
    MOVES TO '(' num ',' num ',' num ')' mm '(' num ',' num ',' num ')' deg tail
    tail  := { IN frame | WITH SPEED num (% | mm/s | deg/s)
             | UNTIL (FORCE '>' num N | CONTACT | TIME num s) }    each clause at most once;
                                                                 IN only on DRAW/ROTATE/MOVES
    SPEED num (% | mm/s | deg/s)
    MODE (FORCE | POSITION)
    EVENT name
    TASK name [ '(' [name {',' name}] ')' ]

Each line is parsed on its own, so one bad line never hides the errors of the others: the result
carries every error of the file. The parser is a hand-written tokenizer plus recursive descent
over one line; its regular expressions have no nested repetition, so no input makes it hang.
Whether a program makes sense for a robot (joint count, limits, reach, names, units per action)
is :mod:`shared.language.checks`; the parser only enforces what the models themselves require.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from pydantic import ValidationError

from shared.errors import FileFormatError, InputError
from shared.language import bounds
from shared.language.json_form import JSONFormFault, loads_located, pointer, validation_faults
from shared.language.statements import (
    DEFAULT_FRAME,
    SPEED_MIN,
    SPEED_TEXT_UNIT,
    Draw,
    Drive,
    Event,
    Frame,
    Mode,
    Move,
    Moves,
    Rotate,
    SetMode,
    SetSpeed,
    Speed,
    Statement,
    TaskCall,
    UntilContact,
    UntilForce,
    UntilTime,
    statement_adapter,
)
from shared.language.units import ConversionError, TextUnit, to_si, unit_from_text

_TOKEN = re.compile(
    r"[ \t\r\f\v]*(?:"
    r"(?P<num>[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?)"
    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z]+)?)"
    r"|(?P<punct>[(),%>])"
    r"|(?P<bad>.))",
    re.DOTALL,
)
_KINDS = (None, "num", "name", "punct", "bad")  # group number -> token kind
_XYZ = ("x", "y", "z")
_RPY = ("roll", "pitch", "yaw")
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_JOINT = re.compile(r"[Jj]([0-9]{1,6})")

STATEMENT_KEYWORDS = ("MOVE", "DRIVE", "DRAW", "ROTATE", "MOVES", "SPEED", "MODE", "EVENT", "TASK")
_SPEED_UNITS = {text: unit for unit, text in SPEED_TEXT_UNIT.items()}

_TEXT_BOUND: dict[TextUnit, tuple[float, float, str]] = {
    # text unit: (bound in SI, text units per SI unit, name of the bound)
    TextUnit.MM: (bounds.WORKSPACE_M, 1e3, "workspace bound"),
    TextUnit.DEG: (bounds.MAX_ANGLE_RAD, 180.0 / math.pi, "angle bound"),
    TextUnit.PERCENT: (bounds.MAX_SPEED_FRACTION, 100.0, "speed bound"),
    TextUnit.MM_PER_S: (bounds.MAX_LINEAR_SPEED_M_S, 1e3, "speed bound"),
    TextUnit.DEG_PER_S: (bounds.MAX_ANGULAR_SPEED_RAD_S, 180.0 / math.pi, "speed bound"),
    TextUnit.NEWTON: (bounds.MAX_FORCE_N, 1.0, "force bound"),
    TextUnit.SECOND: (bounds.MAX_TIME_S, 1.0, "time bound"),
}
"""The physical bound (``shared.language.bounds``) of a number written in each text unit."""


@dataclass(frozen=True)
class ParseError:
    """One problem in a program file. ``line`` and ``col`` are 1-based (``None`` when the
    source has no lines, e.g. a JSON statement); ``statement`` is the 0-based statement index
    where known; ``pointer`` is the JSON pointer of the fault in a JSON-form document
    (``/3/target``)."""

    message: str
    line: int | None = None
    col: int | None = None
    statement: int | None = None
    pointer: str | None = None

    def format(self, path: str = "<text>") -> str:
        if self.line is not None:
            where = f"{path}:{self.line}:{self.col if self.col is not None else 1}"
        elif self.pointer:
            where = f"{path}: {self.pointer}"
        else:
            where = path
        return f"{where}: {self.message}"


@dataclass(frozen=True)
class ParsedProgram:
    """The statements of a source, the 1-based source line and column of each (``None`` for JSON
    input, which has the JSON ``pointers`` of its statements instead), and every error found.
    ``statements`` holds only the statements that parsed."""

    statements: list[Statement]
    lines: list[int | None]
    errors: list[ParseError] = field(default_factory=list)
    path: str = "<text>"
    cols: list[int | None] = field(default_factory=list)
    pointers: list[str | None] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.errors

    def error_lines(self) -> list[str]:
        return [e.format(self.path) for e in self.errors]


class _Tok:
    """A token: ``kind`` is num, name, punct or end; ``col`` is 1-based."""

    __slots__ = ("kind", "text", "col")

    def __init__(self, kind: str, text: str, col: int) -> None:
        self.kind = kind
        self.text = text
        self.col = col


class _Fail(Exception):
    def __init__(self, col: int, message: str) -> None:
        super().__init__(message)
        self.col = col
        self.message = message


def _clip(text: str, limit: int = 32) -> str:
    """Token text for a message; a huge token (a 100 kB number) is shortened."""
    return text if len(text) <= limit else f"{text[:12]}...{text[-8:]} ({len(text)} characters)"


def _describe(tok: _Tok) -> str:
    return "end of line" if tok.kind == "end" else repr(_clip(tok.text))


def _tokenize(line: str) -> list[_Tok]:
    line = line.rstrip(" \t\r\f\v")  # so the leading-blank part of _TOKEN never ends a line
    toks: list[_Tok] = []
    kinds = _KINDS
    for m in _TOKEN.finditer(line):
        index = m.lastindex
        start = m.start(index)
        if index == 4:
            raise _Fail(start + 1, f"unexpected character {m.group(index)!r}")
        toks.append(_Tok(kinds[index], m.group(index), start + 1))
    toks.append(_Tok("end", "", len(line) + 1))
    return toks


class _Line:
    """Recursive descent over the tokens of one line."""

    def __init__(self, toks: list[_Tok]) -> None:
        self.toks = toks
        self.i = 0

    # -- primitives -----------------------------------------------------------------------
    @property
    def tok(self) -> _Tok:
        return self.toks[self.i]

    def next(self) -> _Tok:
        t = self.toks[self.i]
        if t.kind != "end":
            self.i += 1
        return t

    def fail(self, expected: str, tok: _Tok | None = None) -> _Fail:
        tok = tok or self.tok
        return _Fail(tok.col, f"expected {expected}, found {_describe(tok)}")

    def at_keyword(self, word: str) -> bool:
        return self.tok.kind == "name" and self.tok.text.upper() == word

    def keyword(self, word: str, context: str = "") -> _Tok:
        if not self.at_keyword(word):
            raise self.fail(f"{word}{context}")
        return self.next()

    def punct(self, ch: str, context: str = "") -> None:
        if self.tok.kind != "punct" or self.tok.text != ch:
            raise self.fail(f"{ch!r}{context}")
        self.next()

    def number(self, what: str = "a number") -> _Tok:
        if self.tok.kind != "num":
            raise self.fail(what)
        return self.next()

    def unit(self, allowed: tuple[TextUnit, ...]) -> TextUnit:
        tok = self.tok
        spelled = " or ".join(u.value for u in allowed)
        if tok.kind in ("name", "punct"):
            u = unit_from_text(tok.text)
            if u in allowed:
                self.next()
                return u
            if u is not None:
                raise _Fail(tok.col, f"unit {_clip(tok.text)!r} does not fit here; expected {spelled}")
        raise self.fail(f"unit {spelled}")

    def ident(self, what: str) -> _Tok:
        tok = self.tok
        if tok.kind != "name" or not _IDENT.fullmatch(tok.text):
            raise self.fail(what)
        if len(tok.text) > bounds.MAX_NAME_LENGTH:
            raise _Fail(tok.col, f"{what.split(' (')[0]} of {len(tok.text)} characters is longer than {bounds.MAX_NAME_LENGTH}")
        return self.next()

    @staticmethod
    def si(tok: _Tok, unit: TextUnit, what: str = "") -> float:
        """The SI value of a number token, refused at its column when it has none or lies beyond
        the physical bound of its unit (``what`` names the field in the message)."""
        try:
            value = to_si(tok.text, unit)
        except ConversionError as exc:
            raise _Fail(tok.col, f"{exc}: {_clip(tok.text)}") from None
        limit, scale, name = _TEXT_BOUND[unit]
        if not -limit <= value <= limit:
            label = f"{what} = " if what else ""
            raise _Fail(tok.col, f"{label}{_clip(tok.text)} {unit.value} is beyond the {name} of "
                                 f"\u00b1{limit * scale:.6g} {unit.value}")
        return value

    def values(self, unit: TextUnit, count: int | None, names: tuple[str, ...] = ()) -> tuple[tuple[float, ...], _Tok]:
        """``'(' num {',' num} ')' unit`` with exactly ``count`` numbers when given."""
        open_tok = self.tok
        self.punct("(")
        nums = [self.number()]
        while self.tok.kind == "punct" and self.tok.text == ",":
            self.next()
            nums.append(self.number())
            if count is None and len(nums) > bounds.MAX_JOINTS:
                raise _Fail(nums[-1].col, f"more than {bounds.MAX_JOINTS} joint values")
        self.punct(")", " or ','" if count is None or len(nums) < count else "")
        if count is not None and len(nums) != count:
            raise _Fail(open_tok.col, f"expected {count} values in parentheses, found {len(nums)}")
        u = self.unit((unit,))
        labels = names or tuple(f"J{i + 1}" for i in range(len(nums)))
        return tuple(self.si(t, u, what) for t, what in zip(nums, labels)), open_tok

    def end(self) -> None:
        if self.tok.kind != "end":
            raise _Fail(self.tok.col, f"unexpected {_describe(self.tok)} after the end of the statement")

    # -- statements -----------------------------------------------------------------------
    def statement(self) -> Statement:
        head = self.tok
        if head.kind != "name":
            raise _Fail(head.col, f"expected a statement ({', '.join(STATEMENT_KEYWORDS)}), found {_describe(head)}")
        word = head.text.upper()
        self.next()
        if word == "MOVE":
            joints, _ = self.values(TextUnit.DEG, None)
            return self.action(Move, {"joints": joints}, cartesian=False)
        if word == "DRIVE":
            jt = self.tok
            m = _JOINT.fullmatch(jt.text) if jt.kind == "name" else None
            if m is None:
                raise self.fail("a joint such as J3")
            joint = int(m.group(1))
            if joint < 1:
                raise _Fail(jt.col, "joints are numbered from J1")
            if joint > bounds.MAX_JOINTS:
                raise _Fail(jt.col, f"J{joint} is beyond the highest joint number, J{bounds.MAX_JOINTS}")
            self.next()
            self.keyword("TO")
            num = self.number()
            u = self.unit((TextUnit.DEG,))
            return self.action(Drive, {"joint": joint, "target": self.si(num, u, f"J{joint}")}, cartesian=False)
        if word == "DRAW":
            self.keyword("TO")
            xyz, _ = self.values(TextUnit.MM, 3, _XYZ)
            return self.action(Draw, {"position": xyz}, cartesian=True)
        if word == "ROTATE":
            self.keyword("TO")
            rpy, _ = self.values(TextUnit.DEG, 3, _RPY)
            return self.action(Rotate, {"rpy": rpy}, cartesian=True)
        if word == "MOVES":
            self.keyword("TO")
            xyz, _ = self.values(TextUnit.MM, 3, _XYZ)
            rpy, _ = self.values(TextUnit.DEG, 3, _RPY)
            return self.action(Moves, {"position": xyz, "rpy": rpy}, cartesian=True)
        if word == "SPEED":
            speed = self.speed()
            self.end()
            return SetSpeed(speed=speed)
        if word == "MODE":
            tok = self.tok
            if tok.kind == "name" and tok.text.upper() in Mode.__members__:
                self.next()
                self.end()
                return SetMode(mode=Mode(tok.text.upper()))
            raise self.fail("FORCE or POSITION")
        if word == "EVENT":
            name = self.ident("an event name (letters, digits, _)")
            self.end()
            return Event(name=name.text)
        if word == "TASK":
            name = self.ident("a task name (letters, digits, _)")
            args: list[str] = []
            if self.tok.kind == "punct" and self.tok.text == "(":
                self.next()
                if not (self.tok.kind == "punct" and self.tok.text == ")"):
                    args.append(self.ident("an object or feature name").text)
                    while self.tok.kind == "punct" and self.tok.text == ",":
                        self.next()
                        args.append(self.ident("an object or feature name").text)
                        if len(args) > bounds.MAX_TASK_ARGS:
                            raise _Fail(self.toks[self.i - 1].col, f"more than {bounds.MAX_TASK_ARGS} task arguments")
                self.punct(")", " or ','")
            self.end()
            return TaskCall(name=name.text, args=tuple(args))
        raise _Fail(head.col, f"unknown statement {_clip(head.text)!r}; expected one of {', '.join(STATEMENT_KEYWORDS)}")

    def speed(self) -> Speed:
        num = self.number("a speed")
        u = self.unit(tuple(_SPEED_UNITS))
        value = self.si(num, u, "speed")
        if not value > 0.0:
            raise _Fail(num.col, f"a speed must be above zero, got {_clip(num.text)} {u.value}")
        slowest = SPEED_MIN[_SPEED_UNITS[u]]
        if value < slowest * (1.0 - 1e-9):
            raise _Fail(num.col, f"speed = {_clip(num.text)} {u.value} is below the slowest speed bound of "
                                 f"{slowest * _TEXT_BOUND[u][1]:.6g} {u.value} (a motion at it could not finish "
                                 f"within {bounds.MAX_MOTION_S / 3600.0:g} h)")
        return Speed(value=value, unit=_SPEED_UNITS[u])

    def action(self, model: type, fields: dict, *, cartesian: bool) -> Statement:
        seen: dict[str, _Tok] = {}
        while self.tok.kind != "end":
            tok = self.tok
            word = tok.text.upper() if tok.kind == "name" else ""
            if word not in ("IN", "WITH", "UNTIL"):
                expected = "IN, WITH or UNTIL" if cartesian else "WITH or UNTIL"
                raise _Fail(tok.col, f"expected {expected} or the end of the statement, found {_describe(tok)}")
            if word in seen:
                raise _Fail(tok.col, f"{word} given twice (first at column {seen[word].col})")
            if word == "IN" and not cartesian:
                raise _Fail(tok.col, "IN applies to DRAW, ROTATE and MOVES only; joint moves have no frame")
            seen[word] = tok
            self.next()
            if word == "IN":
                ft = self.tok
                if ft.kind == "name" and ft.text.upper() in Frame.__members__:
                    self.next()
                    fields["frame"] = Frame(ft.text.upper())
                else:
                    raise self.fail("a frame: WORLD, BASE, WORK or TOOL")
            elif word == "WITH":
                self.keyword("SPEED", " after WITH")
                fields["speed"] = self.speed()
            else:
                ct = self.tok
                kind = ct.text.upper() if ct.kind == "name" else ""
                if kind == "FORCE":
                    self.next()
                    self.punct(">", " after UNTIL FORCE")
                    num = self.number("a force")
                    self.unit((TextUnit.NEWTON,))
                    value = self.si(num, TextUnit.NEWTON, "force")
                    if not value > 0.0:
                        raise _Fail(num.col, f"a force threshold must be above zero, got {_clip(num.text)} N")
                    fields["until"] = UntilForce(newtons=value)
                elif kind == "CONTACT":
                    self.next()
                    fields["until"] = UntilContact()
                elif kind == "TIME":
                    self.next()
                    num = self.number("a time")
                    self.unit((TextUnit.SECOND,))
                    value = self.si(num, TextUnit.SECOND, "time")
                    if not value > 0.0:
                        raise _Fail(num.col, f"a time limit must be above zero, got {_clip(num.text)} s")
                    fields["until"] = UntilTime(seconds=value)
                else:
                    raise self.fail("FORCE, CONTACT or TIME after UNTIL")
        if cartesian:
            fields.setdefault("frame", DEFAULT_FRAME)
        return model(**fields)


def _strip_comment(line: str) -> str:
    cut = line.find("#")
    return line if cut < 0 else line[:cut]


def parse_statement(text: str) -> Statement:
    """One statement from one line of text (the editor's hand entry); raises ``InputError``
    naming the column."""
    if "\n" in text:
        raise InputError("a statement is one line of text")
    result = parse_program(text)
    if result.errors:
        e = result.errors[0]
        raise InputError(f"column {e.col}: {e.message}")
    if len(result.statements) != 1:
        raise InputError("expected one statement, found none")
    return result.statements[0]


def _too_large(text: str | bytes) -> ParseError | None:
    if len(text) > bounds.MAX_PROGRAM_BYTES:
        return ParseError(f"program of {len(text)} characters is over the bound of {bounds.MAX_PROGRAM_BYTES}")
    return None


PROGRESS_EVERY = 500
"""Lines (statements, for checks and planning) between two progress reports of a long program."""


def parse_program(text: str, path: str = "<text>", progress: Callable[[int, int], None] | None = None) -> ParsedProgram:
    """Parse the text form; never raises for bad input, returns every error instead.
    ``progress(lines done, lines)`` is called every ``PROGRESS_EVERY`` lines of a long text."""
    too_large = _too_large(text)
    if too_large is not None:
        return ParsedProgram([], [], [too_large], path)
    statements: list[Statement] = []
    lines: list[int | None] = []
    cols: list[int | None] = []
    errors: list[ParseError] = []
    raw_lines = text.split("\n")
    for number, raw in enumerate(raw_lines, start=1):
        if progress is not None and number % PROGRESS_EVERY == 0:
            progress(number, len(raw_lines))
        body = _strip_comment(raw)
        if not body.strip():
            continue
        if len(statements) >= bounds.MAX_PROGRAM_STATEMENTS:
            errors.append(ParseError(f"more than {bounds.MAX_PROGRAM_STATEMENTS} statements in one program", number, 1))
            break
        col = len(body) - len(body.lstrip()) + 1
        try:
            toks = _tokenize(body)
            statement = _Line(toks).statement()
        except _Fail as exc:
            errors.append(ParseError(exc.message, number, exc.col))
            continue
        except ValidationError as exc:  # a model rule the grammar did not already enforce
            first = exc.errors()[0]
            where = ".".join(str(p) for p in first["loc"] if not (isinstance(p, str) and p.isupper()))
            errors.append(ParseError(f"invalid statement: {where + ': ' if where else ''}{first['msg']}", number, col))
            continue
        statements.append(statement)
        lines.append(number)
        cols.append(col)
    return ParsedProgram(statements, lines, errors, path, cols=cols)


def parse_json(text: str | bytes, path: str = "<json>") -> ParsedProgram:
    """The JSON form (a list of statement objects) -> statements, decoded strictly (no NaN,
    Infinity, overflowing number or repeated key); every error carries the JSON pointer of the
    fault (``/3/target``), a syntax error its line and column."""
    too_large = _too_large(text)
    if too_large is not None:
        return ParsedProgram([], [], [too_large], path)
    try:
        data = loads_located(text)
    except JSONFormFault as exc:
        return ParsedProgram([], [], [_json_fault(exc)], path)
    if not isinstance(data, list):
        return ParsedProgram([], [], [ParseError("a JSON program is a list of statement objects", pointer="")], path)
    if len(data) > bounds.MAX_PROGRAM_STATEMENTS:
        return ParsedProgram(
            [], [], [ParseError(f"{len(data)} statements is more than the {bounds.MAX_PROGRAM_STATEMENTS} of one program", pointer="")], path
        )
    statements: list[Statement] = []
    pointers: list[str | None] = []
    errors: list[ParseError] = []
    for i, item in enumerate(data):
        try:
            statements.append(statement_adapter.validate_python(item))
        except ValidationError as exc:
            errors.extend(ParseError(f.message, statement=i, pointer=f.pointer) for f in validation_faults(exc, (i,)))
            continue
        pointers.append(pointer((i,)))
    n = len(statements)
    return ParsedProgram(statements, [None] * n, errors, path, cols=[None] * n, pointers=pointers)


_JSON_AT = re.compile(r": line (\d+) column (\d+) \(char \d+\)$")


def _json_fault(exc: JSONFormFault) -> ParseError:
    """A document-level fault: a located value keeps its pointer, a syntax error its line:col."""
    if exc.pointer:
        index = exc.pointer.split("/")[1]
        return ParseError(exc.message, statement=int(index) if index.isdigit() else None, pointer=exc.pointer)
    m = _JSON_AT.search(exc.message)
    if m is not None:
        return ParseError(f"not valid JSON: {exc.message[: m.start()]}", int(m.group(1)), int(m.group(2)))
    return ParseError(f"not valid JSON: {exc.message}")


def read_program_file(path: str | Path) -> str:
    """The text of a program file handed in, read up to ``MAX_PROGRAM_BYTES`` (so a device or
    a pipe that never ends cannot hold the reader); raises ``FileFormatError`` naming the file."""
    p = Path(path)
    try:
        with open(p, "rb") as f:
            data = f.read(bounds.MAX_PROGRAM_BYTES + 1)
    except FileNotFoundError:
        raise FileFormatError(p, "file does not exist") from None
    except IsADirectoryError:
        raise FileFormatError(p, "is a directory, not a program file") from None
    except OSError as exc:
        raise FileFormatError(p, f"cannot read: {exc.strerror or exc}") from None
    if len(data) > bounds.MAX_PROGRAM_BYTES:
        raise FileFormatError(p, f"larger than {bounds.MAX_PROGRAM_BYTES // (1024 * 1024)} MiB, the bound of a program file; stopped reading there")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FileFormatError(p, f"not a UTF-8 text file (byte {exc.start})") from None


def parse_file(path: str | Path) -> ParsedProgram:
    """Read a program file handed in: ``.json`` is the JSON form, anything else the text form."""
    text = read_program_file(path)
    if Path(path).suffix.lower() == ".json":
        return parse_json(text, str(path))
    return parse_program(text, str(path))
