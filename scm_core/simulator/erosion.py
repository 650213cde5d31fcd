"""Erosion (paper section 3.2): soil moves between free neighbours until no slope exceeds the
angle of repose, avalanches rolling down a face in parcels, never into the circle the wheel's
surface sweeps (:mod:`.soil_grid`'s room)."""

from __future__ import annotations

import numpy as np
from numba import njit

from .soil_grid import is_loaded, push_node, room_at, surface, take_soil

EROSION_TOL = 1e-6  # m: slopes may exceed the angle of repose by this height difference
EROSION_MAX_MOVES_PER_NODE = 64
STEPS = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]])  # a node's four neighbours (dc, dj)
ROLLING_PARCELS = 256  # parcels of soil rolling down a face at once (erosion's avalanches)


@njit(cache=True)
def _headroom(
    c: int, j: int, skip_c: int, skip_j: int, lim_x: float, lim_y: float, grid, gaps: np.ndarray
):
    """How far free node (c, j) may rise [m] before a slope to a free neighbour (other than
    (skip_c, skip_j)) exceeds the angle of repose (negative when already over-steep), and how
    far before it reaches the wheel's swept circle: (slope room, circle room). ``gaps[q]`` is
    left holding the rise that brings the slope to neighbour q (STEPS) to its limit (inf where
    q is not a free neighbour)."""
    c0, ncw, jw0, nyw, clamp, h0, sp, hl, cflag, _queue, _inq = grid
    nx, ny = h0.shape
    s = surface(c, j, h0, sp, hl)
    room = np.inf
    for q in range(4):
        gaps[q] = np.inf
        cn = c + STEPS[q, 0]
        jn = j + STEPS[q, 1]
        if cn < 0 or cn >= nx or jn < 0 or jn >= ny or (cn == skip_c and jn == skip_j):
            continue
        if is_loaded(cn, jn, c0, ncw, cflag):
            continue
        lim = lim_x if STEPS[q, 1] == 0 else lim_y
        gaps[q] = lim - (s - surface(cn, jn, h0, sp, hl))
        room = min(room, gaps[q])
    return room, room_at(c, j, c0, ncw, jw0, nyw, clamp, h0, sp, hl)


@njit(cache=True)
def _binding(gaps: np.ndarray, room: float, lim_x: float, lim_y: float, binds: np.ndarray) -> int:
    """The neighbours q (STEPS) not above the node whose slope reaches the angle of repose
    first when it rises by ``room`` (to EROSION_TOL), from :func:`_headroom`'s ``gaps``; written
    to ``binds``, returns their count."""
    count = 0
    for q in range(4):
        lim = lim_x if STEPS[q, 1] == 0 else lim_y
        if gaps[q] <= lim and gaps[q] <= room + EROSION_TOL:  # gap <= lim: not above the node
            binds[count] = q
            count += 1
    return count


@njit(cache=True, inline="always")
def _slide(
    ca: int,
    ja: int,
    cb: int,
    jb: int,
    excess: float,
    lims: tuple[float, float],
    grid,
    tail: int,
    scratch,
) -> tuple[int, bool]:
    """Soil slides from free node a down to its free neighbour b, the pair's height difference
    exceeding the angle of repose by ``excess`` [m]. Returns (queue tail, whether soil moved).

    When b can hold half the excess (its other slopes and the wheel's swept circle allow it),
    half moves and the pair rests at the angle of repose (the pair rule). Otherwise b rises to
    its own limit, a drops to rest at the angle of repose above it, and the rest rolls on down
    the face, each node keeping what its slopes allow and passing the rest on in equal parts to
    the lower neighbours whose slopes bind: grains roll down a face that is at rest and stop at
    its toe, so a pile fed at its top keeps its face at the angle of repose and grows at the toe
    in one pass, where the pair rule would relax the whole face pair by pair, step after step.
    Soil does not roll past a node held down by the wheel's swept circle (it rests against the
    wheel). ``stack`` (m x 2) and ``amounts`` (m) hold the rolling parcels; ``gaps`` and
    ``binds`` (4) are scratch (:func:`erosion_scratch`); ``lims``: the rises at the angle of
    repose over one cell along x and y [m]."""
    _c0, _ncw, _jw0, _nyw, _clamp, h0, _sp, hl, _cflag, queue, inq = grid
    lim_x, lim_y = lims
    stack, amounts, gaps, binds, _excess = scratch
    half = 0.5 * excess
    room_b, circle_b = _headroom(cb, jb, ca, ja, lim_x, lim_y, grid, gaps)
    n_b = 0
    if room_b < half and room_b < circle_b:
        n_b = _binding(gaps, room_b, lim_x, lim_y, binds)
    if n_b == 0:  # the pair rule (also where the wheel holds b down)
        amount = min(half, circle_b)
        if amount <= EROSION_TOL:
            return tail, False
        take_soil(ca, ja, amount, h0, hl)  # what slides down is loose
        hl[cb, jb] += amount
        return push_node(cb, jb, queue, inq, tail), True
    keep = max(room_b, 0.0)
    taken = excess - keep  # a rests at the angle of repose above b risen by keep
    take_soil(ca, ja, taken, h0, hl)
    hl[cb, jb] += keep
    top = 0
    share = (taken - keep) / n_b
    for i in range(n_b):
        stack[top, 0] = cb + STEPS[binds[i], 0]
        stack[top, 1] = jb + STEPS[binds[i], 1]
        amounts[top] = share
        top += 1
    m = stack.shape[0]
    hops = 0
    no_skip = np.int64(-1)  # a value, not a literal (one compiled _headroom)
    while top > 0:
        top -= 1
        c = stack[top, 0]
        j = stack[top, 1]
        rolling = amounts[top]
        room, circle = _headroom(c, j, no_skip, no_skip, lim_x, lim_y, grid, gaps)
        hops += 1
        n_lower = 0
        if room < rolling and room < circle:
            n_lower = _binding(gaps, room, lim_x, lim_y, binds)
        if n_lower == 0 or top + n_lower > m or hops > 4 * m:
            hl[c, j] += rolling  # it rests here (if over-steep, the work list sorts it out)
            tail = push_node(c, j, queue, inq, tail)
            continue
        put = max(room, 0.0)
        hl[c, j] += put
        share = (rolling - put) / n_lower  # each hop ends lim below the risen node
        for i in range(n_lower):
            stack[top, 0] = c + STEPS[binds[i], 0]
            stack[top, 1] = j + STEPS[binds[i], 1]
            amounts[top] = share
            top += 1
    return tail, True


@njit(cache=True)
def erosion_scratch():
    """Scratch arrays of :func:`erode` (allocated once per run): rolling parcels' nodes and
    amounts, and per-neighbour gaps, binding neighbours and excess heights."""
    return (
        np.empty((ROLLING_PARCELS, 2), np.int64),
        np.empty(ROLLING_PARCELS),
        np.empty(4),
        np.empty(4, np.int64),
        np.empty(4),
    )


@njit(cache=True)
def erode(grid, dx: float, dy: float, tan_repose: float, tail: int, scratch) -> int:
    """Erosion to the angle of repose among free nodes, from the ``tail`` nodes queued in
    ``grid`` (the work list; ``grid`` as for :func:`deposit`), below the wheel's swept circle;
    see :func:`_slide`. ``scratch``: :func:`erosion_scratch`. Returns the node visits."""
    c0, ncw, _jw0, _nyw, _clamp, h0, sp, hl, cflag, queue, inq = grid
    nx, ny = h0.shape
    excess = scratch[4]
    lim_x = dx * tan_repose
    lim_y = dy * tan_repose
    head = 0
    max_moves = EROSION_MAX_MOVES_PER_NODE * (tail + 1) + 1000
    moves = 0
    mask = queue.shape[0] - 1
    while head < tail and moves < max_moves:
        ca = queue[head & mask, 0]
        ja = queue[head & mask, 1]
        head += 1
        inq[ca, ja] = 0
        if is_loaded(ca, ja, c0, ncw, cflag):
            continue
        # the excess of each of the node's four slopes (+: a above b), taken together so that
        # a node over-steep on several sides sheds to all of them alike
        sa = surface(ca, ja, h0, sp, hl)
        n_down = 0
        for q in range(4):
            cb = ca + STEPS[q, 0]
            jb = ja + STEPS[q, 1]
            excess[q] = 0.0
            if cb < 0 or cb >= nx or jb < 0 or jb >= ny or is_loaded(cb, jb, c0, ncw, cflag):
                continue
            lim = lim_x if STEPS[q, 1] == 0 else lim_y
            d = sa - surface(cb, jb, h0, sp, hl)
            if d > lim + EROSION_TOL:
                excess[q] = d - lim
                n_down += 1
            elif -d > lim + EROSION_TOL:
                excess[q] = d + lim
        for q in range(4):
            cb = ca + STEPS[q, 0]
            jb = ja + STEPS[q, 1]
            if excess[q] > 0.0:
                tail, moved = _slide(
                    ca, ja, cb, jb, excess[q] / n_down, (lim_x, lim_y), grid, tail, scratch
                )
            elif excess[q] < 0.0:
                tail, moved = _slide(
                    cb, jb, ca, ja, -excess[q], (lim_x, lim_y), grid, tail, scratch
                )
            else:
                continue
            if moved:
                moves += 1
                tail = push_node(ca, ja, queue, inq, tail)
    visits = head
    while head < tail:  # budget exhausted: clear the remaining marks
        inq[queue[head & mask, 0], queue[head & mask, 1]] = 0
        head += 1
    return visits
