"""Erosion to the angle of repose (docs/simulator.md): loose soil poured on one node portion by
portion forms a pile whose slopes do not exceed the angle of repose, with its volume kept, and
that stands as high as a heap at the angle of repose of that volume (a poured sand heap neither
stays steeper nor spreads flatter)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scm_core.simulator import RigConfig, SoilParams, WheelGeometry
from scm_core.simulator.erosion import EROSION_TOL, erode, erosion_scratch
from scm_core.simulator.flow import flow_and_deposit
from scm_core.simulator.layout import pack
from scm_core.simulator.state import Columns, FlowScratch, Ground, Marks, Window


def _pour(volume: float, dx: float, dy: float, repose_deg: float, portions: int, n: int = 61):
    """Pour ``volume`` [m * nodes] of loose soil on one node of flat ground (no wheel) in equal
    ``portions``, eroding after each (as the flows feed a pile step by step)."""
    h0 = np.zeros((n, n))
    sp = np.zeros((n, n))
    hl = np.zeros((n, n))
    c = n // 2
    cflag = np.zeros((2, n), np.int8)  # no node under a wheel
    clamp = np.zeros(1)
    queue = np.zeros((1 << math.ceil(math.log2(n * n)), 2), np.int64)
    inq = np.zeros((n, n), np.int8)
    for _ in range(portions):
        hl[c, c] += volume / portions
        queue[0] = (c, c)
        inq[c, c] = 1
        grid = (-10, 0, 0, 0, clamp, h0, sp, hl, cflag, queue, inq)
        erode(grid, dx, dy, math.tan(math.radians(repose_deg)), 1, erosion_scratch())
    return h0 - sp + hl


def _critical_height(volume: float, lim_x: float, lim_y: float, n: int) -> float:
    """Peak of the heap at the angle of repose holding ``volume`` [m * nodes] on the grid's
    four-neighbour slopes: s(i, j) = max(H - lim_x |i| - lim_y |j|, 0) (diamond contours)."""
    i = np.arange(-(n // 2), n // 2 + 1)
    ii, jj = np.meshgrid(i, i, indexing="ij")
    cone = lim_x * np.abs(ii) + lim_y * np.abs(jj)
    lo, hi = 0.0, volume
    for _ in range(200):  # bisection on the peak height
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.maximum(mid - cone, 0.0).sum() < volume else (lo, mid)
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("repose_deg, dy_over_dx", [(29.0, 2.0), (35.0, 1.0), (20.0, 2.0)])
def test_a_poured_heap_rests_at_the_angle_of_repose(repose_deg, dy_over_dx):
    dx = 0.005
    dy = dy_over_dx * dx
    height = 0.05  # m * nodes: ten cells of sand on one node, in 200 portions
    s = _pour(height, dx, dy, repose_deg, portions=200)
    lim_x = dx * math.tan(math.radians(repose_deg))
    lim_y = dy * math.tan(math.radians(repose_deg))
    # no slope steeper than the angle of repose (to the erosion tolerance)
    assert np.abs(np.diff(s, axis=0)).max() <= lim_x + 2 * EROSION_TOL
    assert np.abs(np.diff(s, axis=1)).max() <= lim_y + 2 * EROSION_TOL
    # volume kept (erosion only moves soil; the heap stays inside the grid)
    assert s.sum() == pytest.approx(height, rel=1e-12)
    assert s[0].max() == s[-1].max() == s[:, 0].max() == s[:, -1].max() == 0.0
    # a sand heap: as high as the heap at the angle of repose of its volume, within one
    # cell's rise (the grid resolves the cone to one cell)
    peak = _critical_height(height, lim_x, lim_y, s.shape[0])
    assert abs(s.max() - peak) <= lim_x
    # and symmetric about its axis to within one cell's rise (nodes are visited in order)
    assert np.abs(s - s[::-1, :]).max() < lim_x
    assert np.abs(s - s[:, ::-1]).max() < lim_x


def test_a_step_without_contact_keeps_the_nodes_waiting_for_erosion():
    """Between erosion passes (a grousered wheel's short steps) the nodes that received soil
    wait in the work list; a step in which the wheel touches nothing must not drop them (their
    queued marks would stay set and they could never be eroded again)."""
    nx, ny, ncw = 40, 12, 6
    h0 = np.zeros((nx, ny))
    zeros = np.zeros(ncw)
    queue = np.zeros((1 << math.ceil(math.log2(nx * ny)), 2), np.int64)
    inq = np.zeros((nx, ny), np.int8)
    queue[:3] = [(5, 4), (6, 4), (7, 4)]
    inq[5:8, 4] = 1
    prm = pack(SoilParams(), WheelGeometry(), RigConfig())
    grid = np.zeros((nx, ny))
    out = flow_and_deposit(
        prm,
        1.0,
        0.0,
        Columns(zeros, np.full(ncw, np.inf), np.full(ncw, np.inf), zeros, zeros, zeros, zeros,
                np.zeros(9)),
        Ground(h0, grid.copy(), grid.copy(), grid.copy(), grid.copy(), grid.copy()),
        Marks(np.zeros((ncw + 2, ny), np.int8), np.zeros((ncw + 2, ny))),
        Window(10, ncw, 2, 8),
        0.01,
        FlowScratch(
            np.zeros((8, max(ncw, ny))), np.zeros((5, max(ncw, ny)), np.int64), queue, inq
        ),
        3,
    )  # fmt: skip
    assert out == (0.0, 0.0, 3)
