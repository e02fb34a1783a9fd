"""Recognition kept per statement (issue 35): ``PrefixRecognition`` plays a changed program from
its first changed statement and gives what ``recognise_program`` gives playing it whole."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from shared.cells.loader import load_cell
from shared.cells.object_world import ObjectWorld
from shared.language.parser import parse_file, parse_statement
from shared.tasknet.playback import PrefixRecognition, recognise_program
from shared.tasknet.taskspace import load_task_space

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def cell():
    return load_cell(ROOT / "assets" / "cells" / "peg_in_hole.toml")


@pytest.fixture(scope="module")
def space():
    return load_task_space(ROOT / "assets" / "tasks" / "peg_in_hole.toml")


@pytest.fixture(scope="module")
def transfer():
    return list(parse_file(ROOT / "assets" / "programs" / "peg_transfer_plain.tp").statements)


def _same(a, b) -> None:
    assert a.actions == b.actions
    assert (a.m0, a.final_marking, a.samples, a.refusal) == (b.m0, b.final_marking, b.samples, b.refusal)
    assert np.allclose(a.starts, b.starts)


def test_each_version_is_recognised_as_a_whole_play_recognises_it(cell, space, transfer) -> None:
    """The versions an operator makes: the program grown statement by statement (generation),
    one statement changed in the middle, one deleted, a prefix previewed, a tail put back."""
    start = cell.q_home.copy()
    kept = PrefixRecognition(cell, space, start)
    nudge = parse_statement("DRAW TO (0, -60, 160) mm IN WORK")
    versions = [transfer[:k] for k in range(1, len(transfer) + 1)]
    middle = len(transfer) // 2
    versions += [
        [*transfer[:middle], nudge, *transfer[middle:]],  # inserted in the middle
        [*transfer[:middle], *transfer[middle + 1:]],  # one deleted
        transfer[:3],  # a short prefix previewed
        list(transfer),  # the whole again
        [],
    ]
    for version in versions:
        got = kept.recognise(version)
        _same(got, recognise_program(version, cell, space, start))
    # growing by one statement played one statement; the whole after the prefix played the rest
    kept.recognise(transfer[:4])
    kept.recognise(transfer[:5])
    assert kept.replayed == 1
    kept.recognise(transfer)
    assert kept.replayed == len(transfer) - 5
    kept.recognise(transfer)
    assert kept.replayed == 0


def test_the_start_world_is_copied_and_a_moved_peg_is_recognised_where_it_is(cell, space, transfer) -> None:
    """The objects at the start come from the caller's world (a reported peg), copied: the play
    changes neither the caller's world nor an earlier result."""
    start = cell.q_home.copy()
    world = ObjectWorld(cell)
    peg = world.resolve("PEG")
    moved = np.array(next(o.world_T_object for o in cell.objects if o.name == peg), dtype=float)
    moved[0, 3] += 0.3  # out of its hole, on the table
    world.placed[peg] = moved
    before = {k: v.copy() for k, v in world.placed.items()}
    kept = PrefixRecognition(cell, space, start, world)
    got = kept.recognise(transfer)
    _same(got, recognise_program(transfer, cell, space, start, world.copy()))
    assert "PEGINHOLE(PEG,HOLE1)" not in got.m0
    assert world.placed.keys() == before.keys() and all(np.array_equal(world.placed[k], before[k]) for k in before)
