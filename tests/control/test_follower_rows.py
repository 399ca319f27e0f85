"""The pooled rows batched laser followers keep their arrays in, and the stacked route
tables their kernel reads: members keep their numbers when the pool grows, a member
that is gone gives its row back, and each path's rows are its own arrays."""

from __future__ import annotations

import gc

import numpy as np

from platoon_sumo.control.follower_rows import FollowerRows, PathTables


class Member:
    """Keeps a view of its row of the pool's one array, as a follower does."""

    def __init__(self, value: float):
        self.value = value
        self.row: np.ndarray | None = None
        self.slot = -1

    def bind(self, pool: FollowerRows, slot: int) -> None:
        if self.row is None:  # joining: the member's numbers go into its row
            pool.arrays["state"][slot] = self.value
        self.row, self.slot = pool.arrays["state"][slot], slot


def test_members_keep_their_numbers_when_the_pool_grows():
    pool = FollowerRows({"state": (3,)}, capacity=2)
    members = [Member(float(k)) for k in range(9)]
    for m in members:
        pool.join(m)
    assert sorted(m.slot for m in members) == list(range(9))
    assert len(pool.arrays["state"]) >= 9
    for k, m in enumerate(members):
        assert m.row is not None
        assert np.shares_memory(m.row, pool.arrays["state"])  # rebound after each growth
        assert m.row.tolist() == [float(k)] * 3
        m.row[:] = -k  # written through the view: the pool holds it
        assert pool.arrays["state"][m.slot].tolist() == [float(-k)] * 3


def test_a_member_that_is_gone_gives_its_row_back():
    pool = FollowerRows({"state": (2,)}, capacity=4)
    kept, gone = Member(1.0), Member(2.0)
    pool.join(kept)
    pool.join(gone)
    slot = gone.slot
    del gone
    gc.collect()
    again = Member(3.0)
    pool.join(again)
    assert again.slot == slot
    assert pool.arrays["state"][kept.slot].tolist() == [1.0, 1.0]


class Path:
    def __init__(self, n: int, first: float):
        self.xy = np.arange(2 * n, dtype=np.float64).reshape(n, 2) + first
        self.codes = np.arange(n - 1, dtype=np.int64)


def arrays_of(path: object) -> tuple[np.ndarray, ...]:
    assert isinstance(path, Path)
    return path.xy, path.codes


def test_each_path_gets_a_number_and_its_own_rows():
    tables = PathTables(("xy", "codes"))
    paths = [Path(n, 100.0 * n) for n in (3, 40, 5, 7)]
    numbers = tables.numbers([paths[0], paths[1], paths[0], paths[2], paths[3]], arrays_of)
    assert numbers == [0, 1, 0, 2, 3]
    for k, path in enumerate(paths):
        for name, want in zip(("xy", "codes"), arrays_of(path), strict=True):
            starts = tables.starts(name)
            np.testing.assert_array_equal(tables.table(name)[starts[k] : starts[k + 1]], want)
            assert tables.table(name).dtype == want.dtype


def test_tables_start_again_when_most_paths_they_hold_are_no_longer_used():
    tables = PathTables(("xy", "codes"))
    old = [Path(4, float(k)) for k in range(70)]
    tables.numbers(old, arrays_of)
    new = Path(6, 5000.0)
    assert tables.numbers([new], arrays_of) == [0]  # the tables started again
    starts = tables.starts("xy")
    assert starts.tolist() == [0, 6]
    np.testing.assert_array_equal(tables.table("xy")[0:6], new.xy)
