"""The JSON form of a net (the pydantic model ``PTNet`` as JSON) and loading and saving a net
by its file's suffix: ``.pnml`` (PNML) or ``.json``. A ``.json`` file may also hold the compact
condition/event form (``places``/``transitions`` with ``pre`` and ``post``/``initial_marking``)."""

from __future__ import annotations

import json
from pathlib import Path

from pydantic import ValidationError

from shared.errors import FileFormatError, InputError
from shared.tasknet.ptnet import PTNet

SUFFIXES = (".pnml", ".json")


def net_to_json(net: PTNet) -> str:
    return net.model_dump_json(indent=2, exclude_none=True) + "\n"


def net_from_json(text: str | bytes, path: str | Path = "<json>") -> PTNet:
    from shared.tasknet.cenet import ConditionEventModel, from_condition_event_model

    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FileFormatError(path, f"not valid JSON: {exc.msg} at line {exc.lineno}, column {exc.colno}") from None
    except UnicodeDecodeError as exc:
        raise FileFormatError(path, f"not UTF-8 text (byte {exc.start})") from None
    except RecursionError:
        raise FileFormatError(path, "not a net: its JSON nests too deep") from None
    except ValueError:  # Python's limit on the digits of an integer (4300)
        raise FileFormatError(path, "not a net: a number has too many digits") from None
    if not isinstance(data, dict):
        raise FileFormatError(path, f"a net is a JSON object; got {type(data).__name__}")
    compact = "initial_marking" in data or any(
        isinstance(t, dict) and ("pre" in t or "post" in t) for t in data.get("transitions", [])
    )
    try:
        if compact:
            return from_condition_event_model(ConditionEventModel.model_validate(data), net_id=str(data.get("id", "net")))
        return PTNet.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(x) for x in first.get("loc", ())) or None
        raise FileFormatError(path, str(first["msg"]).removeprefix("Value error, "), field=where) from None
    except InputError as exc:
        raise FileFormatError(path, str(exc)) from None


def load_net(path: str | Path) -> PTNet:
    """A net from a ``.pnml`` or ``.json`` file."""
    from shared.tasknet.pnml import read_pnml

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise FileFormatError(path, f"unknown net file suffix {path.suffix or '(none)'!r}; valid: {', '.join(SUFFIXES)}")
    if suffix == ".pnml":
        return read_pnml(path)
    try:
        text = path.read_bytes()
    except OSError as exc:
        raise FileFormatError(path, f"cannot read: {exc.strerror or exc}") from None
    return net_from_json(text, path)


def save_net(net: PTNet, path: str | Path) -> None:
    from shared.tasknet.pnml import net_to_pnml

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".pnml":
        path.write_text(net_to_pnml(net), encoding="utf-8")
    elif suffix == ".json":
        path.write_text(net_to_json(net), encoding="utf-8")
    else:
        raise FileFormatError(path, f"unknown net file suffix {path.suffix or '(none)'!r}; valid: {', '.join(SUFFIXES)}")
