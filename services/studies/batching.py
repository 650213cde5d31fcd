"""How a stage's chains (or points) are cut into work batches: one policy for the service."""

from __future__ import annotations

import math

__all__ = [
    "DEFAULT_BATCH_SIZE",
    "DEFAULT_WORKERS",
    "batch_size_of",
    "local_batch_size",
    "work_batches",
]

DEFAULT_BATCH_SIZE = 50  # chains per work batch: ~1-2 min of simulator time at the defaults
#: workers assumed for a study's first stage (later stages count those of the previous one)
DEFAULT_WORKERS = 2


def batch_size_of(requested: int | None, configured: int | None, default: int) -> int:
    """Chains (or points) per work batch: the request's, else the case's, else the kind's
    ``default`` (stages then cut it by guided self-scheduling, see :func:`work_batches`)."""
    return int(requested or configured or default)


def local_batch_size(n: int, workers: int | None) -> int:
    """Largest batch of a stage's n chains (``stage_chains``: n / P for waste-free moves) run
    on this machine (``scm-calib calibrate``). In-process (``workers`` None: numba's threads
    share each batch) four batches, so that progress is reported often; on ``workers``
    processes half a share each, the rest cut ever shorter by :func:`work_batches` (guided
    self-scheduling) so that no process waits long at a stage's end."""
    parts = 4 if workers is None else 2 * workers
    return max(1, math.ceil(n / parts))


def work_batches(
    n: int, batch_size: int | None, workers: int = DEFAULT_WORKERS, min_size: int | None = None
) -> list[range]:
    """Consecutive ranges covering chains (or points) 0..n-1: the work batches of a stage.

    Guided self-scheduling (Polychronopoulos and Kuck 1987): each batch takes what remains
    divided by the number of ``workers``, capped at ``batch_size`` and at least ``min_size``
    (default an eighth of ``batch_size``). A stage thus ends with short batches: workers take
    batches in order, and one that finishes early picks a short batch instead of idling at the
    stage barrier while another runs a long one. The idle time at a barrier is about half the
    duration of the last batches; each extra batch costs ~15 ms of bookkeeping (docs/store.md,
    "Where the time goes"). One worker: plain batches of ``batch_size``. Results do not depend
    on the split: chains are seeded by (study seed, stage, chain index). ``batch_size`` None:
    one batch.
    """
    if n < 1:
        raise ValueError(f"a stage needs at least one chain, got n={n}")
    if batch_size is None:
        return [range(n)]
    size = int(batch_size)
    if size < 1:
        raise ValueError(f"'batch_size' must be >= 1 or None, got {batch_size!r}")
    workers = max(1, int(workers))
    smallest = max(1, min(size, -(-size // 8) if min_size is None else int(min_size)))
    out: list[range] = []
    start = 0
    while start < n:
        k = min(size, max(smallest, math.ceil((n - start) / workers)), n - start)
        out.append(range(start, start + k))
        start += k
    return out
