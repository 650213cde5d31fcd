"""Plastic soil deformation (paper section 3.2): node update, soil flow, angle-of-repose erosion.

Volume bookkeeping: the soil volume is V = dA * sum(h0 - sp) (the unloaded surface). Plastic sinkage
removes volume from the footprint; the fraction ``compaction`` of it is lost to densification (and
counted), the rest is deposited on the footprint's boundary ring (radial flow). The parallel flow
carries a layer of thickness flow_depth = grouser height + shear band at ``slip_flow`` times the
rim's horizontal velocity relative to the ground, donor-cell from node to node along x; erosion
moves soil between free neighbours until no slope exceeds the angle of repose. Flow and erosion
only move volume, so V changes by exactly the compacted volume (to rounding).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .layout import P_COMPACTION, P_DT, P_FLOWDEPTH, P_K, P_OMEGA, P_SHEARDISP, P_SLIPFLOW, P_V

EROSION_TOL = 1e-8  # m: slopes may exceed the angle of repose by this height difference
EROSION_MAX_MOVES_PER_NODE = 64


@njit(cache=True)
def commit_contact(
    zw: float,
    vz: float,
    prm: np.ndarray,
    npatch: int,
    pc: np.ndarray,
    pj0: np.ndarray,
    pj1: np.ndarray,
    pflag: np.ndarray,
    psig: np.ndarray,
    xi: np.ndarray,
    e: np.ndarray,
    fx: np.ndarray,
    fz: np.ndarray,
    c0: int,
    jw0: int,
    h0: np.ndarray,
    sp: np.ndarray,
    sy: np.ndarray,
    ke: np.ndarray,
    js: np.ndarray,
    cflag: np.ndarray,
) -> float:
    """Apply the converged step to the nodes under the wheel; return the plastic flow [m * nodes].

    Yielding nodes update sp, sy, ke (plastic sinkage never decreases, elastic rebound never lifts
    a node above its reference level). A node's surface is the wheel's while loaded and h0 - sp
    (unloaded) otherwise, so it is not stored. cflag[k + 1, j] marks loaded nodes of column k.
    """
    K = prm[P_K]
    dt = prm[P_DT]
    disp_form = prm[P_SHEARDISP] > 0.5
    v = prm[P_V]
    omega = prm[P_OMEGA]
    flow = 0.0
    for p in range(npatch):
        k = pc[p]
        c = c0 + k
        hit = zw + e[k]
        if pflag[p] == 0:
            continue
        vt = 0.0
        if disp_form:
            vpx = v + omega * e[k]
            vpz = vz - omega * xi[k]
            vn = vpx * fx[k] + vpz * fz[k]
            vt = math.hypot(vpx - vn * fx[k], vpz - vn * fz[k])
        sb = psig[p]
        for j in range(pj0[p], pj1[p]):
            jj = jw0 + j
            cflag[k + 1, jj] = 1
            if pflag[p] == 2:
                sink = h0[c, jj] - hit
                spn = max(sp[c, jj], sink - sb / K, 0.0)
                flow += spn - sp[c, jj]
                sp[c, jj] = spn
                sy[c, jj] = sb
                el = sink - spn
                ke[c, jj] = sb / el if el > 1e-12 and sb / el > K else K
            if disp_form:
                js[c, jj] += vt * dt
    return flow


@njit(cache=True)
def _is_loaded(c: int, j: int, c0: int, ncw: int, cflag: np.ndarray) -> bool:
    k = c - c0 + 1
    if k < 0 or k > ncw + 1:
        return False
    return cflag[k, j] != 0


@njit(cache=True)
def _push(node: int, queue: np.ndarray, inq: np.ndarray, tail: int) -> int:
    if inq[node] == 0:
        inq[node] = 1
        queue[tail % queue.shape[0]] = node
        tail += 1
    return tail


@njit(cache=True)
def _move(a_c: int, a_j: int, b_c: int, b_j: int, amount: float, h0: np.ndarray):
    h0[a_c, a_j] -= amount
    h0[b_c, b_j] += amount


@njit(cache=True)
def flow_and_erode(
    flow: float,
    prm: np.ndarray,
    npatch: int,
    pc: np.ndarray,
    pj0: np.ndarray,
    pj1: np.ndarray,
    pflag: np.ndarray,
    e: np.ndarray,
    c0: int,
    ncw: int,
    jw0: int,
    dx: float,
    dy: float,
    tan_repose: float,
    h0: np.ndarray,
    sp: np.ndarray,
    cflag: np.ndarray,
    queue: np.ndarray,
    inq: np.ndarray,
) -> float:
    """Radial and parallel soil flow, then erosion.

    Returns (compacted volume [m^3], erosion node visits).
    """
    nx, ny = h0.shape
    tail = 0
    # ---- radial flow: displaced volume to the ring of free nodes around the footprint
    compacted = 0.0
    if flow > 0.0:
        for p in range(npatch):  # the ring: free 4-neighbours of loaded nodes, into the queue
            if pflag[p] == 0:
                continue
            c = c0 + pc[p]
            for j in range(jw0 + pj0[p], jw0 + pj1[p]):
                for dc, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                    cb = c + dc
                    jb = j + dj
                    if cb < 0 or cb >= nx or jb < 0 or jb >= ny:
                        continue
                    if not _is_loaded(cb, jb, c0, ncw, cflag):
                        tail = _push(cb * ny + jb, queue, inq, tail)
        if tail > 0:
            amount = (1.0 - prm[P_COMPACTION]) * flow / tail
            for i in range(tail):
                node = queue[i]
                h0[node // ny, node % ny] += amount
            compacted = prm[P_COMPACTION] * flow * dx * dy
        else:
            compacted = flow * dx * dy  # nowhere to go: all of it compacts
    # ---- parallel flow: layer dragged along x by the slipping rim (donor cell)
    depth = prm[P_FLOWDEPTH] * prm[P_SLIPFLOW]
    if depth > 0.0:
        v = prm[P_V]
        omega = prm[P_OMEGA]
        dt = prm[P_DT]
        for p in range(npatch):
            if pflag[p] == 0:
                continue
            k = pc[p]
            vpx = v + omega * e[k]  # horizontal velocity of the rim point over ground
            amount = depth * abs(vpx) * dt / dx
            if amount <= 0.0:
                continue
            c = c0 + k
            cb = c + (1 if vpx > 0.0 else -1)
            if cb < 0 or cb >= nx:
                continue
            for j in range(pj0[p], pj1[p]):
                jj = jw0 + j
                _move(c, jj, cb, jj, amount, h0)
                if not _is_loaded(cb, jj, c0, ncw, cflag):
                    tail = _push(cb * ny + jj, queue, inq, tail)
    # ---- erosion to the angle of repose among free nodes (work list)
    lim_x = dx * tan_repose
    lim_y = dy * tan_repose
    head = 0
    max_moves = EROSION_MAX_MOVES_PER_NODE * (tail + 1) + 1000
    moves = 0
    qn = queue.shape[0]
    while head < tail and moves < max_moves:
        a = queue[head % qn]
        head += 1
        inq[a] = 0
        ca = a // ny
        ja = a - ca * ny
        if _is_loaded(ca, ja, c0, ncw, cflag):
            continue
        for dc, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            cb = ca + dc
            jb = ja + dj
            if cb < 0 or cb >= nx or jb < 0 or jb >= ny:
                continue
            if _is_loaded(cb, jb, c0, ncw, cflag):
                continue
            lim = lim_x if dj == 0 else lim_y
            d = (h0[ca, ja] - sp[ca, ja]) - (h0[cb, jb] - sp[cb, jb])
            if d > lim + EROSION_TOL:
                _move(ca, ja, cb, jb, 0.5 * (d - lim), h0)
            elif -d > lim + EROSION_TOL:
                _move(cb, jb, ca, ja, 0.5 * (-d - lim), h0)
            else:
                continue
            moves += 1
            tail = _push(cb * ny + jb, queue, inq, tail)
            tail = _push(a, queue, inq, tail)
    visits = head
    while head < tail:  # budget exhausted: clear the remaining marks
        inq[queue[head % qn]] = 0
        head += 1
    return compacted, visits
