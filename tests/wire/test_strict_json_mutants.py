"""Strict JSON (shared.wire.strict_json), stated exactly: pinned by its mutation run (issue 38).

Every decoder of outside input goes through ``loads_strict``; these tests state what it accepts,
what it refuses and the words of each refusal."""

from __future__ import annotations

import json
import math

import pytest

from shared.wire.strict_json import MAX_DEPTH, StrictJSONError, _depth, dumps_finite, loads_strict


@pytest.mark.parametrize("name", ["NaN", "Infinity", "-Infinity"])
def test_the_non_finite_constants_are_refused_by_name(name):
    with pytest.raises(StrictJSONError) as err:
        loads_strict(f'{{"x": {name}}}')
    assert str(err.value) == f"{name} is not a JSON number (only finite numbers are accepted)"


def test_a_number_that_overflows_is_refused_with_its_text():
    with pytest.raises(StrictJSONError) as err:
        loads_strict('[1e999]')
    assert str(err.value) == "number 1e999 is too large to be finite"
    long_text = "1" * 50 + "e999"
    with pytest.raises(StrictJSONError) as err:
        loads_strict(f"[{long_text}]")
    assert str(err.value) == f"number {long_text[:40]} is too large to be finite"


def test_finite_numbers_read_as_python_numbers():
    assert loads_strict('{"a": 1.5, "b": -2e3, "c": 7}') == {"a": 1.5, "b": -2000.0, "c": 7}
    assert loads_strict("1e308") == 1e308


def test_a_repeated_key_is_refused_naming_the_key():
    with pytest.raises(StrictJSONError) as err:
        loads_strict('{"type": "hello", "type": "stop"}')
    assert str(err.value) == "key 'type' appears twice in one object"
    # keys are compared within one object only
    assert loads_strict('{"a": {"k": 1}, "b": {"k": 2}}') == {"a": {"k": 1}, "b": {"k": 2}}
    assert list(loads_strict('{"z": 1, "a": 2}')) == ["z", "a"]  # order of the text kept


def test_bytes_must_be_utf8_and_the_refusal_names_the_byte():
    assert loads_strict('{"name": "é"}'.encode()) == {"name": "é"}
    assert loads_strict(bytearray(b"[1, 2]")) == [1, 2]
    with pytest.raises(StrictJSONError) as err:
        loads_strict(b'["ab\xff"]')
    assert str(err.value) == "not UTF-8 text: byte 4"


def test_nesting_to_max_depth_is_accepted_and_one_deeper_refused():
    at_limit = "[" * MAX_DEPTH + "]" * MAX_DEPTH
    value = loads_strict(at_limit)
    for _ in range(MAX_DEPTH - 1):
        value = value[0]
    assert value == []
    too_deep = "[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1)
    with pytest.raises(StrictJSONError) as err:
        loads_strict(too_deep)
    assert str(err.value) == f"nested deeper than {MAX_DEPTH} levels"
    objects = '{"a":' * (MAX_DEPTH + 1) + "1" + "}" * (MAX_DEPTH + 1)
    with pytest.raises(StrictJSONError, match="nested deeper than 64 levels"):
        loads_strict(objects)


def test_many_brackets_side_by_side_are_not_deep():
    wide = "[" + ",".join(["[]"] * (MAX_DEPTH * 3)) + "]"
    assert loads_strict(wide) == [[]] * (MAX_DEPTH * 3)
    # brackets inside strings do not count, escaped quotes do not end a string
    text = json.dumps(["[" * (MAX_DEPTH * 2), 'a "quoted" [[[ word \\', "{" * MAX_DEPTH])
    assert loads_strict(text)[0] == "[" * (MAX_DEPTH * 2)


def test_the_depth_walk():
    assert _depth("") == 0
    assert _depth("[]") == 1
    assert _depth("[[], [[]]]") == 3
    assert _depth('{"a": [{"b": []}]}') == 4
    assert _depth('["[[[", "]"]') == 1
    assert _depth('["\\"[[[", 1]') == 1  # an escaped quote does not end the string
    assert _depth('["\\\\", [[1]]]') == 3  # an escaped backslash does not escape the closing quote
    assert _depth("[" * 70) == MAX_DEPTH + 1  # stops counting once past the limit


def test_text_that_is_not_json_is_refused_with_the_parser_line():
    with pytest.raises(StrictJSONError) as err:
        loads_strict('{"a": }')
    assert str(err.value) == "Expecting value: line 1 column 7 (char 6)"
    with pytest.raises(StrictJSONError) as err:
        loads_strict("")
    assert str(err.value) == "Expecting value: line 1 column 1 (char 0)"


def test_the_refusal_is_a_value_error():
    assert issubclass(StrictJSONError, ValueError)


def test_dumps_finite_writes_non_finite_floats_as_their_text():
    text = dumps_finite({"a": math.nan, "b": [math.inf, -math.inf, 1.5], "c": (2, "x"), 3: None})
    assert json.loads(text) == {"a": "nan", "b": ["inf", "-inf", 1.5], "c": [2, "x"], "3": None}
    assert dumps_finite({"n": {"deep": [math.inf]}}) == '{"n": {"deep": ["inf"]}}'


def test_dumps_finite_writes_other_objects_as_their_str():
    class Thing:
        def __str__(self) -> str:
            return "a thing"

    assert dumps_finite({"t": Thing()}) == '{"t": "a thing"}'


def test_the_depth_walk_counts_brackets_only_and_each_closing_one_once():
    assert _depth("[X]") == 1  # a stray character outside strings is not a bracket (invalid JSON, still depth 1)
    assert _depth("[X[") == 2
    assert _depth("[[]][[]]") == 2  # a closing bracket takes one level off, whatever the depth


def test_depth_exactly_max_depth_is_accepted_when_there_are_more_brackets_than_that():
    # 65 opening brackets (so the character walk runs) but nesting exactly MAX_DEPTH deep
    text = "[[]," + "[" * (MAX_DEPTH - 1) + "]" * (MAX_DEPTH - 1) + "]"
    assert text.count("[") == MAX_DEPTH + 1
    assert _depth(text) == MAX_DEPTH
    value = loads_strict(text)
    assert value[0] == []
