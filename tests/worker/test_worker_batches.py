"""How a stage's chains are cut into work batches (``worker.orchestrator.work_batches``):
consecutive ranges covering every chain once, full-size batches first, then shrinking ones so
a stage ends with short batches; and the split changes no result (the store workflow tests and
the service tests compare posteriors bit for bit)."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st

from worker.orchestrator import work_batches


@given(n=st.integers(1, 5000), size=st.integers(1, 400))
def test_batches_cover_the_chains_once_in_order(n: int, size: int) -> None:
    batches = work_batches(n, size)
    assert batches[0].start == 0 and batches[-1].stop == n
    assert all(a.stop == b.start for a, b in itertools.pairwise(batches))
    lengths = [len(b) for b in batches]
    assert all(0 < k <= size for k in lengths)
    # never growing: long batches first, the shortest at the end of the stage
    assert all(a >= b for a, b in itertools.pairwise(lengths))
    # the shrinking tail stays short: at most ~log(size) + 4 * 2 batches more than n / size
    assert len(batches) <= -(-n // size) + 4 * (size.bit_length() + 2)


def test_tail_shrinks_to_an_eighth_of_the_batch_size() -> None:
    assert [len(b) for b in work_batches(32, 8)] == [8, 6, 5, 4, 3, 2, 1, 1, 1, 1]
    assert [len(b) for b in work_batches(2000, 50)][:37] == [50] * 37
    assert min(len(b) for b in work_batches(2000, 50)[:-1]) == 7  # an eighth of 50, rounded up
    assert [len(b) for b in work_batches(5, 50)] == [5]
    assert [len(b) for b in work_batches(9, None)] == [9]


def test_bad_sizes_are_refused() -> None:
    with pytest.raises(ValueError, match="batch_size"):
        work_batches(10, 0)
    with pytest.raises(ValueError, match="at least one chain"):
        work_batches(0, 5)
