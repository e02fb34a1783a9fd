"""Validate a message against the Foxglove JSON Schema shipped in assets/foxglove_schemas/.

``validate(schema_name, message)`` raises ``FoxgloveSchemaError`` naming the path of the first
problem: a value that is not plain JSON data (a numpy scalar or array, a tuple) or the schema's
best-matching error. The schemas declare no ``$schema``; they are checked and applied as JSON
Schema draft 2020-12 (``jsonschema``'s default for such schemas).
"""

from __future__ import annotations

import json
from functools import lru_cache

import jsonschema
from jsonschema.exceptions import best_match

from server.recording.foxglove import schema_bytes


class FoxgloveSchemaError(AssertionError):
    """A message that does not validate; ``path`` is where (``$`` the message itself)."""

    def __init__(self, schema_name: str, path: str, message: str) -> None:
        self.path = path
        super().__init__(f"{schema_name}: {path}: {message}")


@lru_cache(maxsize=None)
def validator(schema_name: str) -> jsonschema.protocols.Validator:
    schema = json.loads(schema_bytes(schema_name))
    cls = jsonschema.validators.validator_for(schema, default=jsonschema.Draft202012Validator)
    cls.check_schema(schema)
    return cls(schema)


def _first_not_plain(value: object, path: str) -> tuple[str, str] | None:
    kind = type(value)
    if kind is dict:
        for key, item in value.items():
            if type(key) is not str:
                return path, f"key {key!r} is a {type(key).__name__}, not a str"
            found = _first_not_plain(item, f"{path}.{key}")
            if found:
                return found
        return None
    if kind is list:
        for i, item in enumerate(value):
            found = _first_not_plain(item, f"{path}[{i}]")
            if found:
                return found
        return None
    if kind in (str, int, float, bool) or value is None:
        return None
    return path, f"{value!r} is a {kind.__module__}.{kind.__name__}, not plain JSON data"


def validate(schema_name: str, message: object) -> None:
    """Raise ``FoxgloveSchemaError`` unless ``message`` is plain JSON data valid for the schema."""
    found = _first_not_plain(message, "$")
    if found:
        raise FoxgloveSchemaError(schema_name, *found)
    error = best_match(validator(schema_name).iter_errors(message))
    if error is not None:
        raise FoxgloveSchemaError(schema_name, error.json_path, error.message)
