"""The on-disk collision-model cache (``shared.collision.model_cache``): the same model with and
without it, a corrupt or stale file ignored and rebuilt, concurrent writers leaving whole files."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from shared.cells.loader import DEFAULT_CELL, load_cell
from shared.collision import interference, model_cache
from shared.collision.obb_tree import OBBTree, build_obb_tree


@pytest.fixture
def cache_dir(tmp_path):
    model_cache.configure(tmp_path / "cache")
    try:
        yield tmp_path / "cache"
    finally:
        model_cache.configure(None)


def _box():
    v = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 2.0) for z in (0.0, 0.5)])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f


def _same_tree(a: OBBTree, b: OBBTree) -> None:
    for name in OBBTree.__dataclass_fields__:
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y), name


def _files(folder, kind):
    return sorted(folder.glob(f"{kind}-*.npz"))


def test_trees_are_identical_built_stored_and_read(cache_dir) -> None:
    v, f = _box()
    model_cache.configure(None)
    plain = build_obb_tree(v, f)
    model_cache.configure(cache_dir)
    stored = build_obb_tree(v, f)  # built and written
    assert len(_files(cache_dir, "obb")) == 1
    read = build_obb_tree(v, f)  # read back
    _same_tree(plain, stored)
    _same_tree(plain, read)


def test_zones_and_checks_are_identical_with_and_without_the_cache(cache_dir) -> None:
    cell = load_cell(DEFAULT_CELL)
    robot = cell.robot
    q = np.random.default_rng(3).uniform(robot.lower, robot.upper, size=(40, robot.dof))

    def model_and_zones():
        from shared.collision.scene import SceneModel

        interference._generated.cache_clear()
        model = SceneModel.from_cell(cell)
        zones = interference._generated(robot, ((2, 3),), 2.0, None)
        return [model.check(x).colliding for x in q], repr(zones)

    model_cache.configure(None)
    without = model_and_zones()
    model_cache.configure(cache_dir)
    written = model_and_zones()
    assert _files(cache_dir, "selfgrid") and _files(cache_dir, "obb")
    read = model_and_zones()
    assert without == written == read


@pytest.mark.parametrize("damage", ["garbage", "truncated", "empty", "other key"])
def test_a_corrupt_or_foreign_file_is_ignored_and_rebuilt(cache_dir, damage, caplog) -> None:
    v, f = _box()
    model_cache.configure(None)
    plain = build_obb_tree(v, f)
    model_cache.configure(cache_dir)
    build_obb_tree(v, f)
    (path,) = _files(cache_dir, "obb")
    whole = path.read_bytes()
    if damage == "garbage":
        path.write_bytes(b"not a zip file at all" * 10)
    elif damage == "truncated":
        path.write_bytes(whole[: len(whole) // 2])
    elif damage == "empty":
        path.write_bytes(b"")
    else:  # a whole file of other triangles under this file's name
        build_obb_tree(v * 2.0, f)
        other = next(p for p in _files(cache_dir, "obb") if p != path)
        path.write_bytes(other.read_bytes())
    tree = build_obb_tree(v, f)
    _same_tree(plain, tree)
    assert "ignoring the cache file" in caplog.text
    assert path.read_bytes() == whole  # rebuilt and written again


def test_changed_content_misses_the_cache(cache_dir) -> None:
    v, f = _box()
    build_obb_tree(v, f)
    moved = build_obb_tree(v + 1e-9, f)  # any change of the input is another key
    assert len(_files(cache_dir, "obb")) == 2
    model_cache.configure(None)
    _same_tree(build_obb_tree(v + 1e-9, f), moved)


def test_concurrent_writers_leave_a_whole_file(cache_dir) -> None:
    key = model_cache.content_key("test", ("concurrent",))
    big = {"a": np.arange(400_000, dtype=np.float64), "b": np.ones((300, 300))}
    errors: list[BaseException] = []
    seen: list[int] = []
    stop = threading.Event()

    def write() -> None:
        try:
            for _ in range(15):
                model_cache.store("test", key, big)
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    def read() -> None:
        while not stop.is_set():
            got = model_cache.load("test", key, ("a", "b"))
            if got is not None:  # never a part of a file: absent, or the whole arrays
                assert np.array_equal(got["a"], big["a"]) and np.array_equal(got["b"], big["b"])
                seen.append(1)

    readers = [threading.Thread(target=read) for _ in range(2)]
    writers = [threading.Thread(target=write) for _ in range(4)]
    for t in readers + writers:
        t.start()
    for t in writers:
        t.join()
    stop.set()
    for t in readers:
        t.join()
    assert not errors and seen
    assert [p.name for p in cache_dir.iterdir()] == [f"test-{key}.npz"]  # no temporary file left


def test_an_unwritable_folder_only_costs_the_build(tmp_path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("a file where the folder would be")
    model_cache.configure(blocker / "cache")
    try:
        v, f = _box()
        tree = build_obb_tree(v, f)
    finally:
        model_cache.configure(None)
    _same_tree(build_obb_tree(v, f), tree)


def test_convex_pieces_are_identical_built_stored_and_read(cache_dir) -> None:
    from shared.collision.convex import cached_convex_pieces, convex_pieces

    v, f = _box()
    model_cache.configure(None)
    plain = convex_pieces(v, f, [(0, len(f))])
    model_cache.configure(cache_dir)
    stored = cached_convex_pieces(v, f, [(0, len(f))])
    read = cached_convex_pieces(v, f, [(0, len(f))])
    assert len(_files(cache_dir, "convex")) == 1
    for got in (stored, read):
        for name in ("vertices", "start", "count", "adj_start", "adj", "center", "radius"):
            np.testing.assert_array_equal(getattr(got, name), getattr(plain, name))
    # a refused mesh is remembered as refused
    dented = v.copy()
    dented[0] = 0.8 * v.mean(axis=0) + 0.2 * v[0]  # a corner pushed towards the centre: concave
    assert cached_convex_pieces(dented, f, [(0, len(f))]) is None
    assert cached_convex_pieces(dented, f, [(0, len(f))]) is None
    assert len(_files(cache_dir, "convex")) == 2
