"""The soil grid's nodes as the flows and erosion move soil between them: what the wheel did to a
node this step (``cflag`` marks), a node's surface, taking soil from it, the room on it under the
circle the wheel's surface sweeps (Chrono's SCMTerrain clamps deposits at the body's hit level),
and depositing soil that moves on to the next node in its direction when it does not fit; the
work list of nodes that received soil (for erosion)."""

from __future__ import annotations

import numpy as np
from numba import njit

LOADED_ELASTIC = 1  # cflag: node in contact, elastic (unloading or reloading below its yield)
LOADED_YIELDING = 2  # cflag: node in contact on the Bekker curve (plastic)
LOOSE_PUSHED = 3  # cflag: only the node's loose soil was reached (pushed away, no stress)


@njit(cache=True)
def is_loaded(c: int, j: int, c0: int, ncw: int, cflag: np.ndarray) -> bool:
    k = c - c0 + 1
    if k < 0 or k > ncw + 1:
        return False
    return cflag[k, j] != 0


@njit(cache=True)
def push_node(c: int, j: int, queue: np.ndarray, inq: np.ndarray, tail: int) -> int:
    """Queue node (c, j) unless it is queued; ``queue`` is a ring of (c, j) pairs whose length
    is a power of two (no division per push or pop). Returns the new tail."""
    if inq[c, j] == 0:
        inq[c, j] = 1
        slot = tail & (queue.shape[0] - 1)
        queue[slot, 0] = c
        queue[slot, 1] = j
        tail += 1
    return tail


@njit(cache=True)
def surface(c: int, j: int, h0: np.ndarray, sp: np.ndarray, hl: np.ndarray) -> float:
    """Unloaded surface of node (c, j) [m]: ground reference - plastic sinkage + loose soil."""
    return h0[c, j] - sp[c, j] + hl[c, j]


@njit(cache=True)
def take_soil(c: int, j: int, amount: float, h0: np.ndarray, hl: np.ndarray) -> None:
    """Remove ``amount`` [m] from the top of node (c, j): its loose soil first, then ground."""
    loose = min(amount, hl[c, j])
    hl[c, j] -= loose
    h0[c, j] -= amount - loose


@njit(cache=True)
def room_at(
    c: int,
    j: int,
    c0: int,
    ncw: int,
    jw0: int,
    nyw: int,
    clamp: np.ndarray,
    h0: np.ndarray,
    sp: np.ndarray,
    hl: np.ndarray,
) -> float:
    """Height [m] by which free node (c, j) may rise before it reaches the wheel's swept circle."""
    k = c - c0
    if k < 0 or k >= ncw or j < jw0 or j >= jw0 + nyw:
        return np.inf
    return clamp[k] - surface(c, j, h0, sp, hl)


@njit(cache=True)
def deposit_soil(amount: float, c: int, j: int, dc: int, dj: int, grid, tail: int):
    """Deposit ``amount`` [m * nodes] of loose soil at (c, j) and onward along (dc, dj): loaded
    nodes are passed, free nodes take what fits below the wheel's swept circle. ``grid`` is
    (c0, ncw, jw0, nyw, clamp, h0, sp, hl, cflag, queue, inq). Returns (what is left when the
    march leaves the grid, queue tail)."""
    c0, ncw, jw0, nyw, clamp, h0, sp, hl, cflag, queue, inq = grid
    nx, ny = h0.shape
    while amount > 0.0:
        if c < 0 or c >= nx or j < 0 or j >= ny:
            break
        if not is_loaded(c, j, c0, ncw, cflag):
            room = room_at(c, j, c0, ncw, jw0, nyw, clamp, h0, sp, hl)
            if room > 0.0:
                put = min(room, amount)
                hl[c, j] += put
                amount -= put
                tail = push_node(c, j, queue, inq, tail)
        c += dc
        j += dj
    return amount, tail
