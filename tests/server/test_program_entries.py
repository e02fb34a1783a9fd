"""The program's line views kept between calls (issue 35): after any change (statements added,
replaced, inserted or taken out, durations changed, console marks moved) the views are those a
fresh cache makes, and lines before the first change are the same view objects."""

from __future__ import annotations

import numpy as np

from server.console.program_entries import EntryViews
from shared.language.statements import Draw, SetSpeed, Speed


def _statement(k: int):
    return Draw(position=(0.1 + 1e-3 * k, 0.0, 0.2)) if k % 3 else SetSpeed(speed=Speed(value=0.1 + k % 9 / 10, unit="fraction"))


def test_kept_views_are_what_a_fresh_cache_makes_after_any_change() -> None:
    rng = np.random.default_rng(11)
    kept = EntryViews()
    program = [_statement(k) for k in range(8)]
    durations: list = [0.5] * len(program)
    marked: dict = {}
    counter = 100
    for _ in range(400):
        r = rng.random()
        counter += 1
        if r < 0.3 or not program:
            program.append(_statement(counter))
            durations.append(float(rng.random()))
        elif r < 0.5:
            i = int(rng.integers(len(program)))
            program.insert(i, _statement(counter))
            durations.insert(i, None)
        elif r < 0.65:
            i = int(rng.integers(len(program)))
            del program[i], durations[i]
        elif r < 0.8:
            durations[int(rng.integers(len(program)))] = float(rng.random())
        elif r < 0.9:
            program[-1] = _statement(counter)
        else:
            s = program[int(rng.integers(len(program)))]
            marked = {} if marked else {id(s): {"added_by": "console", "added_reason": "a MODE the regime needs"}}
        before = kept._last[3] if kept._last is not None else []  # noqa: SLF001 - the last call's views
        got = kept.views(program, durations, marked)
        assert got == EntryViews().views(program, durations, marked)
        assert [v.index for v in got] == list(range(len(program)))
        same = next((i for i, (a, b) in enumerate(zip(before, got)) if a is not b), min(len(before), len(got)))
        unchanged = next((i for i, v in enumerate(before) if i >= len(program) or v.statement is not program[i]
                          or v.duration_s != durations[i] or (v.added_by is not None) != (id(program[i]) in marked)),
                         len(before))
        assert same >= min(unchanged, len(got))  # lines before the first change: the same objects


def test_the_list_handed_out_is_the_callers() -> None:
    kept = EntryViews()
    program = [_statement(k) for k in range(3)]
    first = kept.views(program, [0.1, 0.2, 0.3], {})
    first.append("the caller's own line")
    assert len(kept.views(program, [0.1, 0.2, 0.3], {})) == 3
