"""How a stage's chains are cut into work batches (``worker.orchestrator.work_batches``):
consecutive ranges covering every chain once, full-size batches first, then shrinking ones
(guided self-scheduling over the workers seen in the previous stage) so a stage ends with
short batches. The split changes no result: the store workflow and service tests compare
posteriors bit for bit with single-process runs."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st

from services.studies import work_batches


@given(n=st.integers(1, 5000), size=st.integers(1, 400), workers=st.integers(1, 64))
def test_batches_cover_the_chains_once_in_order(n: int, size: int, workers: int) -> None:
    batches = work_batches(n, size, workers)
    assert batches[0].start == 0 and batches[-1].stop == n
    assert all(a.stop == b.start for a, b in itertools.pairwise(batches))
    lengths = [len(b) for b in batches]
    assert all(0 < k <= size for k in lengths)
    # never growing: long batches first, the shortest at the end of the stage
    assert all(a >= b for a, b in itertools.pairwise(lengths))
    # all but the last are at least an eighth of batch_size
    assert all(k >= -(-size // 8) for k in lengths[:-1])


def test_guided_self_scheduling() -> None:
    """Each batch takes what remains over the workers, between batch_size / 8 and batch_size."""
    assert [len(b) for b in work_batches(32, 8)] == [8, 8, 8, 4, 2, 1, 1]  # 2 workers
    assert [len(b) for b in work_batches(32, 8, workers=4)] == [8, 6, 5, 4, 3, 2, 1, 1, 1, 1]
    assert [len(b) for b in work_batches(2000, 50, workers=1)] == [50] * 40  # no tail needed
    two = [len(b) for b in work_batches(2000, 50, workers=2)]
    assert two == [50] * 39 + [25, 13, 7, 5]
    assert [len(b) for b in work_batches(5, 50)] == [5]
    assert [len(b) for b in work_batches(9, None)] == [9]


def test_bad_sizes_are_refused() -> None:
    with pytest.raises(ValueError, match="batch_size"):
        work_batches(10, 0)
    with pytest.raises(ValueError, match="at least one chain"):
        work_batches(0, 5)
