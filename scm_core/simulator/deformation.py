"""Plastic soil deformation (paper section 3.2): node update, soil flow fields, erosion.

Volume bookkeeping: the soil volume is V = dA * sum(h0 - sp) (the unloaded surface). Plastic sinkage
removes volume from the footprint; the fraction ``compaction`` of it is lost to densification (and
counted), the rest flows out of the footprint. Flow and erosion only move volume, so V changes by
exactly the compacted volume (to rounding), plus what would leave the grid (counted as spilled).

Flow fields (Krenn & Hirzinger 2009, "SCM - A soil contact model for multi-body system
simulations"; paper section 3.2) are driven by each loaded node's contact velocity relative to the
ground, split into its normal part v_n (pressing into the soil) and its tangential part v_t (the
wheel surface sliding over the soil):

* the displaced volume of a node is shared in the ratio |v_n| : |v_t| between a *radial* flow
  (outward from the footprint's centroid: side ridges, bow wave, rear lip) and a *parallel* flow
  (along the horizontal slip direction: backwards behind a driven wheel, forwards ahead of a
  skidding or locked one, which then bulldozes it);
* the layer the sliding surface drags (grouser height + ``shear_band``) is a conveyor moving at
  ``slip_flow`` times the mobilised shear of eq. (8) (1 - exp(-v_t/J)) times the slip speed.
  Continuity in the wheel's frame fixes its net effect: a driven wheel accelerates the layer
  backwards, which thins as it passes under the wheel (taken from every loaded node of the row,
  so the rear of the contact unloads and the front carries the load: the wheel digs itself in,
  by at most the layer's depth times the slip) and leaves behind the wheel; optionally
  (``RigConfig.drive_digging = "mobilised"``) the rim carries the layer off to the depth in which
  its shear is mobilised, whatever the slip. Under a skidding wheel the layer
  cannot thicken: the rim drags it forwards from under the wheel's bottom (the wheel sinks: slip
  sinkage, the skid's counterpart of digging in) and pushes it ahead into the bow wave. Each row
  at its mean slip. Optional ploughing (``SoilParams.ploughing`` kappa > 0): of the path ahead
  of a skidding wheel (height h above its lowest point, coming at v in the wheel's frame) the rim
  rolls under what its bottom speed omega r takes; the rest, h (v - omega r), meets the front
  face as a blade, which pushes the fraction kappa of it ahead with the dragged layer, taken
  from under the wheel's bottom: the slip sinkage grows with the sinkage itself and with the
  skid (a locked wheel's faster than 1 / (1 - kappa)). Or, without a parameter
  (``RigConfig.skid_ploughing = "sliding_face"``): the layer a skidding rim drags is the soil met
  by the part of its front face where the rim slides over the soil (outside the friction cone
  of angle phi), :func:`sliding_face_height`, instead of the grouser height + shear band.
* with the grousers' soil trapped (``RigConfig.grouser_contact = "tip_circle"``) the pockets
  are a second conveyor of depth h_g at the rim speed of their mean radius r_p: a driven wheel's
  pockets take the ground's top layer from v to omega r_p (continuity: it thins, the wheel digs
  in by h_g s_p) or, with ``SoilParams.pocket_fill`` f, carry off h_g u_p (f + (1 - f) v /
  (omega r_p)) per width and time (f = 1: full pockets), cut from the top of the front wall
  (each row's front-most loaded node, where the grousers enter the soil) to behind the wheel;
  with ``RigConfig.pocket_carry = "kept"`` only what the pockets keep as they leave the
  contact, h_g u_p f (no continuity floor: what they spill falls back under the wheel).

Soil is deposited only on free nodes and never inside the circle swept by the wheel's outer
surface (as Chrono's SCMTerrain clamps deposits at the body's hit level): what does not fit
moves on to the next node in the flow's direction. So soil left behind a driven wheel lies in its
rut below the receding wheel and cannot push it forward, while soil pushed ahead of a skidding
wheel piles against its front and is compressed again. Erosion then moves soil between free
neighbours until no slope exceeds the angle of repose, with the same clamp.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .contact import surface_velocity
from .layout import (
    P_COMPACTION,
    P_DIGMOB,
    P_DT,
    P_DX,
    P_FACEPLOUGH,
    P_FLOWDEPTH,
    P_HG,
    P_J,
    P_K,
    P_OMEGA,
    P_PLOUGH,
    P_POCKET,
    P_POCKETFILL,
    P_POCKETKEEP,
    P_R,
    P_SHEARDISP,
    P_SHEARSCALE,
    P_SLIPFLOW,
    P_SLIPV,
    P_TANDELTA,
    P_V,
    P_VLAT,
)
from .state import Columns, FlowScratch, Ground, Marks, Patches, Window

EROSION_TOL = 1e-6  # m: slopes may exceed the angle of repose by this height difference
EROSION_MAX_MOVES_PER_NODE = 64
STEPS = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]])  # a node's four neighbours (dc, dj)
ROLLING_PARCELS = 256  # parcels of soil rolling down a face at once (erosion's avalanches)
LOADED_ELASTIC = 1  # cflag: node in contact, elastic (unloading or reloading below its yield)
LOADED_YIELDING = 2  # cflag: node in contact on the Bekker curve (plastic)
LOOSE_PUSHED = 3  # cflag: only the node's loose soil was reached (pushed away, no stress)


@njit(cache=True)
def commit_contact(
    zw: float,
    vz: float,
    prm: np.ndarray,
    npatch: int,
    patches: Patches,
    cols: Columns,
    ground: Ground,
    marks: Marks,
    window: Window,
) -> float:
    """Apply the converged step to the nodes under the wheel; return the displaced soil
    [m * nodes].

    Yielding nodes update sp, sy, ke (plastic sinkage never decreases, elastic rebound never lifts
    a node above its reference level). A node's surface is the wheel's while loaded and h0 - sp +
    hl (unloaded) otherwise, so it is not stored. Loose soil (hl, deposited by the flows) above
    the wheel's surface is pushed away: it carries no stress of its own. cflag[k + 1, j] marks
    the nodes under the wheel of column k (LOADED_ELASTIC, LOADED_YIELDING, or LOOSE_PUSHED when
    only its loose soil was reached) and dsp[k + 1, j] holds what each displaced.
    """
    pc, pj0, pj1, _pst, pflag, psig = patches
    xi, e, fx, fz = cols.xi, cols.e, cols.fx, cols.fz
    h0, sp, sy, ke, js, hl = ground
    cflag, dsp = marks
    c0, ncw, jw0, nyw = window
    K = prm[P_K]
    dt = prm[P_DT]
    disp_form = prm[P_SHEARDISP] > 0.5
    # the shearing surface's slip over the ground, as in contact.evaluate_contact
    v = prm[P_V] * prm[P_SLIPV]
    vz = vz * prm[P_SLIPV]
    vty = prm[P_VLAT] * prm[P_SLIPV]  # a steered wheel's slip along its axle
    omega = prm[P_OMEGA] * prm[P_SHEARSCALE]
    flow = 0.0
    for p in range(npatch):
        k = pc[p]
        c = c0 + k
        hit = zw + e[k]
        if pflag[p] == 0:
            continue
        vt = 0.0
        if disp_form:
            vpx, vpz, vn = surface_velocity(v, vz, omega, xi[k], e[k], fx[k], fz[k])
            vt = math.hypot(math.hypot(vpx - vn * fx[k], vpz - vn * fz[k]), vty)
        sb = psig[p]
        for j in range(pj0[p], pj1[p]):
            jj = jw0 + j
            dsp[k + 1, jj] = 0.0
            if pflag[p] == 2:
                cflag[k + 1, jj] = LOADED_YIELDING
                sink = h0[c, jj] - hit
                spn = max(sp[c, jj], sink - sb / K, 0.0)
                dsp[k + 1, jj] = spn - sp[c, jj]
                flow += spn - sp[c, jj]
                sp[c, jj] = spn
                sy[c, jj] = sb
                el = sink - spn
                ke[c, jj] = sb / el if el > 1e-12 and sb / el > K else K
            else:
                cflag[k + 1, jj] = LOADED_ELASTIC
            if disp_form:
                js[c, jj] += vt * dt
    for k in range(ncw):  # loose soil above the wheel's surface is pushed away
        if not np.isfinite(e[k]):
            continue
        c = c0 + k
        hit = zw + e[k]
        for jj in range(jw0, jw0 + nyw):
            if hl[c, jj] <= 0.0:
                continue
            ground = h0[c, jj] - sp[c, jj]
            if cflag[k + 1, jj] == 0:
                dsp[k + 1, jj] = 0.0
            if hit >= ground + hl[c, jj]:
                continue
            d = min(hl[c, jj], ground + hl[c, jj] - max(hit, ground))
            hl[c, jj] -= d
            dsp[k + 1, jj] += d
            flow += d
            if cflag[k + 1, jj] == 0:
                cflag[k + 1, jj] = LOOSE_PUSHED
    return flow


@njit(cache=True)
def bow_wave(
    ground: Ground, c_ax: int, n_ahead: int, jw0: int, nyw: int, top: float
) -> tuple[float, float]:
    """The loose soil heaped ahead of the wheel: (h, base) [m], the mean over the wheel's rows
    of the thickest loose layer hl in the ``n_ahead`` columns from the axle's column ``c_ax``
    on, and the mean ground level h0 - sp beneath it; h at most ``top`` - base (the rim's
    highest point). What the heap weighs on the wheel is :func:`heap_passive_pressure`'s."""
    h0, sp, hl = ground.h0, ground.sp, ground.hl
    nx = hl.shape[0]
    c0 = min(max(c_ax, 0), nx - 1)
    h_sum = 0.0
    base_sum = 0.0
    for j in range(jw0, jw0 + nyw):
        best = 0.0
        base = h0[c0, j] - sp[c0, j]
        for c in range(c0, min(c_ax + n_ahead, nx)):
            if hl[c, j] > best:
                best = hl[c, j]
                base = h0[c, j] - sp[c, j]
        h_sum += best
        base_sum += base
    base = base_sum / nyw
    return min(h_sum / nyw, max(top - base, 0.0)), base


@njit(cache=True)
def passive_coefficient(tan_phi: float) -> float:
    """Rankine's passive earth pressure coefficient K_p = (1 + sin phi) / (1 - sin phi) [-]."""
    sin_phi = tan_phi / math.sqrt(1.0 + tan_phi * tan_phi)
    return (1.0 + sin_phi) / (1.0 - sin_phi)


@njit(cache=True)
def heap_passive_pressure(
    gamma: float, tan_phi: float, tan_repose: float, h: float
) -> tuple[float, float]:
    """Rankine's passive resistance of a cohesionless heap of height h [m] and unit weight gamma
    [N/m^3] pushed by a wall: (sigma_q, F_b), the surcharge K_p(phi) gamma h [Pa] its weight
    puts on the wall below its base, where the ground fails at phi, and the force of its own
    wedge, 0.5 K_p(repose) gamma h^2 [N/m] (Bekker's bulldozing resistance with c = 0, for loose
    soil, whose friction angle is its angle of repose)."""
    return (
        passive_coefficient(tan_phi) * gamma * h,
        0.5 * passive_coefficient(tan_repose) * gamma * h * h,
    )


@njit(cache=True)
def _is_loaded(c: int, j: int, c0: int, ncw: int, cflag: np.ndarray) -> bool:
    k = c - c0 + 1
    if k < 0 or k > ncw + 1:
        return False
    return cflag[k, j] != 0


@njit(cache=True)
def _push(c: int, j: int, queue: np.ndarray, inq: np.ndarray, tail: int) -> int:
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
def _take(c: int, j: int, amount: float, h0: np.ndarray, hl: np.ndarray) -> None:
    """Remove ``amount`` [m] from the top of node (c, j): its loose soil first, then ground."""
    loose = min(amount, hl[c, j])
    hl[c, j] -= loose
    h0[c, j] -= amount - loose


@njit(cache=True)
def _room(
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
def _deposit(amount: float, c: int, j: int, dc: int, dj: int, grid, tail: int):
    """Deposit ``amount`` [m * nodes] of loose soil at (c, j) and onward along (dc, dj): loaded
    nodes are passed, free nodes take what fits below the wheel's swept circle. ``grid`` is
    (c0, ncw, jw0, nyw, clamp, h0, sp, hl, cflag, queue, inq). Returns (what is left when the
    march leaves the grid, queue tail)."""
    c0, ncw, jw0, nyw, clamp, h0, sp, hl, cflag, queue, inq = grid
    nx, ny = h0.shape
    while amount > 0.0:
        if c < 0 or c >= nx or j < 0 or j >= ny:
            break
        if not _is_loaded(c, j, c0, ncw, cflag):
            room = _room(c, j, c0, ncw, jw0, nyw, clamp, h0, sp, hl)
            if room > 0.0:
                put = min(room, amount)
                hl[c, j] += put
                amount -= put
                tail = _push(c, j, queue, inq, tail)
        c += dc
        j += dj
    return amount, tail


@njit(cache=True)
def _row_mobilised(u: float, v: float, length: float, J: float, disp_form: bool) -> float:
    """Mean mobilised shear of eq. (8) over a row of contact ``length`` [m] sliding at its mean
    slip velocity ``u`` [m/s] over ground at carriage speed v [m/s].

    Velocity form: 1 - exp(-|u|/J). Displacement form (Janosi & Hanamoto 1961): the ground
    under the row has slid j(x) = x |u| / v by the time it is x behind the front of the
    contact, so the mean over the length L is 1 - (1 - exp(-a)) / a with a = L |u| / (v J);
    fully mobilised for a wheel spinning in place (v = 0). Vanishes with the slip, so the dug
    depth is continuous where the row's slip changes sign.
    """
    if not disp_form:
        return 1.0 - math.exp(-abs(u) / J)
    if v <= 0.0:
        return 1.0
    a = length * abs(u) / (v * J)
    if a < 1e-6:
        return 0.5 * a
    return 1.0 - (1.0 - math.exp(-a)) / a


@njit(cache=True)
def sliding_face_height(v: float, omega: float, r: float, tan_phi: float) -> float:
    """Height [m] above a skidding wheel's lowest point of the part of its front face where the
    rim slides over the soil (0 unless omega r < v).

    At the angle theta ahead of the lowest point the rim moves over the ground with a normal
    component v sin(theta) (into the soil) and a tangential one v cos(theta) - omega r (up the
    face). It slides where that velocity lies outside the friction cone of the rim-soil
    interface, whose angle is the one of the shear law of eq. (8) on the wheel (``tan_phi``:
    tan(delta), the soil's phi unless SoilParams.interface_friction < 1): v cos(theta) -
    omega r > tan(phi) v sin(theta), i.e. below theta_s = arccos((1 - f) cos phi) - phi with
    f = 1 - omega r / v the skid (0: rolling; 1: locked, theta_s = 90 deg - phi). Above
    theta_s the soil moves with the rim (a wedge pushed ahead, the forward-flow zone of a braked
    wheel, Wong & Reece 1967 part II); below, the sliding rim shears it out forwards. Height
    r (1 - cos theta_s) [m]; locked: r (1 - sin phi).
    """
    if v <= 0.0 or omega * r >= v:
        return 0.0
    f = 1.0 - omega * r / v
    cos_phi = 1.0 / math.sqrt(1.0 + tan_phi * tan_phi)
    theta_s = math.acos((1.0 - f) * cos_phi) - math.atan(tan_phi)
    return r * (1.0 - math.cos(theta_s))


@njit(cache=True)
def _conveyed(depth: float, f: float, u: float, v: float, mobilised: bool) -> float:
    """Flux [m^2/s] of the layer of ``depth`` the rim drags at the mean slip velocity ``u``
    over ground (< 0: backwards, a driven wheel), f the dragged fraction (slip_flow times the
    mobilised shear of eq. (8)), v the carriage speed.

    Drive, ``mobilised`` False (thinning): continuity in the wheel's frame; the ground enters
    the footprint at v, a layer accelerated backwards to v + f|u| thins to depth v / (v + f|u|),
    and the wheel sinks by the difference, depth f|u| / (v + f|u|), at most depth * slip.
    Drive, ``mobilised`` True: the rim carries off the layer to the fraction f of its depth in
    which its shear is mobilised (f from the row's slip, :func:`_row_mobilised`: the soil in the
    band has failed and escapes backwards and to the sides), dug depth depth * f over the path,
    flux depth f v, not bounded by the slip. Skid: a layer dragged forwards cannot thicken
    under the wheel; it keeps its depth and what it carries, depth f|u|, is pushed ahead.
    """
    speed = f * abs(u)
    if u < 0.0 and v > 0.0:
        if mobilised:
            return depth * f * v
        return depth * v / (v + speed) * speed
    return depth * speed


#: the flow fields' scratch rows (FlowScratch.work, .iwork): per window column the swept
#: circle's lowest level (0), the slip velocity along x (1), the parallel share (2) and the slip
#: speed (7); per row the volumes flowing forward (3) and backward (4); per column to +y (5) and
#: -y (6); per row (iwork) the first (0) and last (1) occupied column and the front-most node
#: loaded on its ground (2); per column the first (3) and last (4) occupied row


@njit(cache=True)
def flow_and_deposit(
    prm: np.ndarray,
    zw: float,
    vz: float,
    cols: Columns,
    ground: Ground,
    marks: Marks,
    window: Window,
    dy: float,
    scratch: FlowScratch,
    tail: int,
):
    """Flow fields: the displaced and dragged soil deposited outside the footprint (see the
    module docstring).

    ``scratch.work`` (>= 8 rows, >= max(ncw, ny) columns) and ``scratch.iwork`` (int64, >= 5
    rows, as many columns) are scratch space (allocated once per run, not per step); ``work``'s
    row 0 is left holding the wheel's swept circle per window column (for :func:`erode`). The
    nodes that received soil are queued in ``scratch.queue`` / ``inq`` after the ``tail`` queued
    before. Returns
    (compacted volume [m^3], spilled volume [m^3], queue length).
    """
    ncw, jw0, nyw = window.ncw, window.jw0, window.nyw
    dx = prm[P_DX]
    dA = dx * dy
    keep = 1.0 - prm[P_COMPACTION]
    xsum, nload = _survey(prm, zw, vz, cols, marks, window, scratch)
    if nload == 0:
        return 0.0, 0.0, tail  # the nodes queued earlier still wait for erosion
    iwork = scratch.iwork
    ny = scratch.inq.shape[1]
    rmax = iwork[1, :ny]
    cmax = iwork[4, :ncw]
    xc = xsum / nload
    yc = jw0 + 0.5 * (nyw - 1)
    # radial flow: along x and y in the proportion the footprint's ring faces them (its rows
    # against its columns), forwards or backwards from the centroid, to either side of the
    # centre line; the same for every row, so identical rows stay identical (patches)
    n_rows = 0
    for j in range(jw0, jw0 + nyw):
        if rmax[j] >= 0:
            n_rows += 1
    n_cols = 0
    for k in range(ncw):
        if cmax[k] >= 0:
            n_cols += 1
    wx = n_rows / (n_rows + n_cols)
    compacted = _displaced(keep, cols.xi, marks, window, scratch, xc, yc, wx)
    _convey(prm, zw, cols.xi, ground, marks, window, scratch)
    spilled, tail = _deposit_flows(ground, marks, window, scratch, tail)
    return compacted * dA, spilled * dA, tail


@njit(cache=True)
def _survey(prm, zw, vz, cols, marks, window, scratch):
    """flow_and_deposit's first pass: per window column the swept circle, the surface's slip
    velocity and parallel share, the occupied rows and columns (scratch rows as above), the
    per-row and per-column accumulators zeroed. Returns (sum of the loaded nodes' x, their
    count)."""
    xi, e, fx, fz = cols.xi, cols.e, cols.fx, cols.fz
    cflag = marks.cflag
    ncw, jw0, nyw = window.ncw, window.jw0, window.nyw
    work, iwork = scratch.work, scratch.iwork
    ny = scratch.inq.shape[1]
    # the shearing surface's slip over the ground (rim bearing: layout._slip_velocity_scale,
    # contact.evaluate_contact)
    sv = prm[P_SLIPV]
    v = prm[P_V] * sv
    vz = vz * sv
    r_out = prm[P_R] + prm[P_HG]
    omega_s = prm[P_OMEGA] * prm[P_SHEARSCALE]  # the shearing surface's at the contact circle
    clamp = work[0]  # per window column: lowest level of the swept circle (inf: none)
    vtx_col = work[1]  # horizontal slip velocity of the wheel surface over ground [m/s]
    share_col = work[2]  # parallel share |v_t| / (|v_t| + |v_n|)
    vt_col = work[7]  # slip speed of the wheel surface over the ground [m/s]
    acc_f = work[3]  # per row: volume flowing forward (+x) out of the footprint [m * nodes]
    acc_b = work[4]  # per row: backward
    acc_p = work[5]  # per column: to +y
    acc_m = work[6]  # per column: to -y
    rmin = iwork[0, :ny]  # per row: first and last occupied column
    rmax = iwork[1, :ny]
    gmax = iwork[2, :ny]  # per row: front-most node loaded on its ground (not loose only)
    cmin = iwork[3, :ncw]
    cmax = iwork[4, :ncw]
    rmin[:] = 1 << 30
    rmax[:] = -1
    gmax[:] = -1
    cmin[:] = 1 << 30
    cmax[:] = -1
    r2 = r_out * r_out
    xsum = 0.0
    nload = 0
    for k in range(ncw):
        clamp[k] = np.inf
        if xi[k] * xi[k] < r2:
            clamp[k] = zw - math.sqrt(r2 - xi[k] * xi[k])
        acc_p[k] = 0.0
        acc_m[k] = 0.0
        # contact kinematics of the column (see contact.evaluate_contact)
        vpx, vpz, vn = surface_velocity(v, vz, omega_s, xi[k], e[k], fx[k], fz[k])
        vtx = vpx - vn * fx[k]
        vtz = vpz - vn * fz[k]
        vt = math.sqrt(vtx * vtx + vtz * vtz)
        vtx_col[k] = vtx
        vt_col[k] = vt
        vn = vn / sv  # the surface's own normal speed (the scale is the shear's, not the rim's)
        share_col[k] = vt / (vt + abs(vn)) if vt + abs(vn) > 0.0 else 0.0
        for j in range(jw0, jw0 + nyw):
            if cflag[k + 1, j] != 0:
                rmin[j] = min(rmin[j], k)
                rmax[j] = max(rmax[j], k)
                if cflag[k + 1, j] != LOOSE_PUSHED:
                    gmax[j] = max(gmax[j], k)
                cmin[k] = min(cmin[k], j)
                cmax[k] = max(cmax[k], j)
                xsum += xi[k]
                nload += 1
    for j in range(ny):
        acc_f[j] = 0.0
        acc_b[j] = 0.0
    return xsum, nload


@njit(cache=True)
def _displaced(keep, xi, marks, window, scratch, xc, yc, wx):
    """The displaced volume of the loaded nodes, less the compacted share (1 - keep): its
    parallel share along the surface's slip and the rest radially from the centroid (xc, yc),
    in the proportion wx along x, gathered per row and column. Returns the compacted volume
    [m * nodes]."""
    cflag, dsp = marks
    ncw = window.ncw
    work, iwork = scratch.work, scratch.iwork
    vtx_col, share_col = work[1], work[2]
    acc_f, acc_b, acc_p, acc_m = work[3], work[4], work[5], work[6]
    cmin, cmax = iwork[3, :ncw], iwork[4, :ncw]
    # ---- displaced volume: radial and parallel shares, gathered per row / column
    compacted = 0.0
    for k in range(ncw):
        if cmax[k] < 0:
            continue
        rx = xi[k] - xc
        for j in range(cmin[k], cmax[k] + 1):
            d = dsp[k + 1, j]
            if cflag[k + 1, j] == 0 or d <= 0.0:  # elastic nodes: loose soil pushed off
                continue
            compacted += (1.0 - keep) * d
            dv = keep * d
            par = share_col[k] * dv if vtx_col[k] != 0.0 else 0.0
            if par > 0.0:
                if vtx_col[k] > 0.0:
                    acc_f[j] += par
                else:
                    acc_b[j] += par
            rad = dv - par
            if rx >= 0.0:
                acc_f[j] += wx * rad
            else:
                acc_b[j] += wx * rad
            side = (1.0 - wx) * rad
            if j > yc:
                acc_p[k] += side
            elif j < yc:
                acc_m[k] += side
            else:
                acc_p[k] += 0.5 * side
                acc_m[k] += 0.5 * side
    return compacted


@njit(cache=True)
def _convey(prm, zw, xi, ground, marks, window, scratch):
    """The layer the sliding surface drags per row along its mean slip (skid: forwards from
    under the wheel's bottom into the bow wave; drive: thinned under the wheel and left behind
    it), and the grouser pockets' soil cut from the front wall; added to the rows'
    accumulators."""
    h0, sp, hl, js = ground.h0, ground.sp, ground.hl, ground.js
    cflag = marks.cflag
    c0, jw0, nyw = window.c0, window.jw0, window.nyw
    work, iwork = scratch.work, scratch.iwork
    nx, ny = h0.shape
    vtx_col, vt_col = work[1], work[7]
    acc_f, acc_b = work[3], work[4]
    rmin, gmax = iwork[0, :ny], iwork[2, :ny]
    dx = prm[P_DX]
    r_out = prm[P_R] + prm[P_HG]
    v = prm[P_V]
    omega = prm[P_OMEGA]
    r_shear = prm[P_SHEARSCALE] * r_out  # the surface shearing the soil (rim bearing: the tips)
    omega_s = omega * prm[P_SHEARSCALE]  # its angular speed at the contact circle
    dt = prm[P_DT]
    depth = prm[P_FLOWDEPTH]
    fslip = prm[P_SLIPFLOW]
    plough = prm[P_PLOUGH]
    face_plough = prm[P_FACEPLOUGH] > 0.5
    # sliding face: height above the lowest point of the part of a skidding wheel's front face
    # where the rim slides over the soil (see sliding_face_height)
    v_s = v * prm[P_SLIPV]  # the carriage's speed in the shearing surface's slip
    y_slide = sliding_face_height(v_s, omega_s, r_out, prm[P_TANDELTA]) if face_plough else 0.0
    dig_mobilised = prm[P_DIGMOB] > 0.5
    # soil trapped between grousers: carried at the rim speed of the pocket's mean radius,
    # half a pocket inside the tips
    pocket = prm[P_POCKET]
    u_pocket = omega * (r_shear - 0.5 * pocket) - v
    fill = prm[P_POCKETFILL]
    kept_only = prm[P_POCKETKEEP] > 0.5  # no continuity floor: only the soil the pockets keep
    J = prm[P_J]
    disp_form = prm[P_SHEARDISP] > 0.5
    # ---- conveyor: the layer dragged by the sliding surface, per row along the mean slip
    if (depth > 0.0 and fslip > 0.0) or plough > 0.0 or y_slide > 0.0 or pocket > 0.0:
        for j in range(jw0, jw0 + nyw):
            if gmax[j] < 0:
                continue
            u = 0.0
            mob = 0.0
            nu = 0
            for k in range(rmin[j], gmax[j] + 1):
                if LOADED_ELASTIC <= cflag[k + 1, j] <= LOADED_YIELDING:
                    u += vtx_col[k]
                    # mobilised shear, eq. (8): the surface drags the layer only as far as the
                    # soil's shear strength is mobilised
                    x = js[c0 + k, j] if disp_form else vt_col[k]
                    mob += 1.0 - math.exp(-x / J)
                    nu += 1
            u /= nu
            mob /= nu
            if u == 0.0:
                continue
            sgn = 1 if u > 0.0 else -1
            if dig_mobilised and sgn < 0:
                mob = _row_mobilised(u, v, nu * dx, J, disp_form)
            # path ahead of a skidding row: its height above the wheel's lowest point [m]
            h = 0.0
            if sgn > 0 and (face_plough or plough > 0.0):
                ca = c0 + gmax[j] + 1
                if ca < nx:
                    h = max(h0[ca, j] - sp[ca, j] - (zw - r_out), 0.0)
            layer = depth
            if sgn > 0 and face_plough:
                # skid: the layer the rim drags forwards is the soil that the sliding part of
                # its front face meets (at most the path's height; at least the grousers'),
                # pushed ahead under the wedge that the face above carries
                layer = max(min(y_slide, h), prm[P_HG])
            flux = _conveyed(layer, fslip * mob, u, v, dig_mobilised)
            if sgn > 0 and plough > 0.0 and not face_plough:
                # ploughing: in the wheel's frame the path ahead comes at v; the rim rolls it
                # under at its bottom speed omega r, the rest meets the front face as a blade,
                # which pushes the fraction `plough` of it ahead with the dragged layer
                flux += plough * h * max(v - omega * r_shear, 0.0)
            a_pocket = 0.0
            if sgn < 0 and pocket > 0.0 and u_pocket > 0.0:
                # the trapped soil moves with the rim, backwards over the ground at u_pocket
                # whatever the shear: by continuity the pocket layer thins under the wheel
                # (fill 0: net flux pocket u_pocket v / (v + u_pocket)), up to pockets that
                # leave the contact full (fill 1: pocket u_pocket); pocket_carry 'kept': only
                # the fraction fill the pockets keep as they leave, the rest spilled back
                if kept_only:
                    q = pocket * u_pocket * fill
                else:
                    q = pocket * u_pocket * (fill + (1.0 - fill) * v / (v + u_pocket))
                a_pocket = q * dt / dx
            a = flux * dt / dx
            if sgn > 0:
                # skid: the rim drags the ground's top layer forwards from under the wheel's
                # bottom (slip sinkage) and pushes it ahead as the bow wave (loose soil)
                kb = gmax[j]
                for k in range(rmin[j], gmax[j] + 1):
                    fl = cflag[k + 1, j]
                    if LOADED_ELASTIC <= fl <= LOADED_YIELDING and abs(xi[k]) < abs(xi[kb]):
                        kb = k
                if kb < gmax[j]:
                    _take(c0 + kb, j, a, h0, hl)
                    acc_f[j] += a
            else:
                # drive: the layer thins as it passes under the wheel (taken from every loaded
                # ground node of the row alike) and leaves behind the wheel
                share = a / nu
                for k in range(rmin[j], gmax[j] + 1):
                    if LOADED_ELASTIC <= cflag[k + 1, j] <= LOADED_YIELDING:
                        _take(c0 + k, j, share, h0, hl)
                if a_pocket > 0.0:
                    # the pockets' soil is cut where the grousers enter it: from the top of the
                    # front wall (the row's front-most loaded node), which the wheel then meets
                    # excavated instead of compacting it; left behind the wheel with the layer
                    _take(c0 + gmax[j], j, a_pocket, h0, hl)
                acc_b[j] += a + a_pocket


@njit(cache=True)
def _deposit_flows(ground, marks, window, scratch, tail):
    """Deposit the rows' and columns' accumulated flows outside the footprint, along the flow,
    below the wheel's swept circle. Returns (spilled volume [m * nodes], queue length)."""
    h0, sp, hl = ground.h0, ground.sp, ground.hl
    cflag = marks.cflag
    c0, ncw, jw0, nyw = window
    work, iwork, queue, inq = scratch
    ny = inq.shape[1]
    clamp = work[0]
    acc_f, acc_b, acc_p, acc_m = work[3], work[4], work[5], work[6]
    rmin, rmax = iwork[0, :ny], iwork[1, :ny]
    cmin, cmax = iwork[3, :ncw], iwork[4, :ncw]
    # ---- deposit outside the footprint, along the flow, below the wheel's swept circle
    grid = (c0, ncw, jw0, nyw, clamp, h0, sp, hl, cflag, queue, inq)
    spilled = 0.0
    one = np.int64(1)  # directions as values: literals would compile _deposit once per value
    zero = np.int64(0)
    for j in range(jw0, jw0 + nyw):
        if rmax[j] < 0:
            continue
        if acc_f[j] > 0.0:
            left, tail = _deposit(acc_f[j], c0 + rmax[j] + 1, j, one, zero, grid, tail)
            spilled += left
        if acc_b[j] > 0.0:
            left, tail = _deposit(acc_b[j], c0 + rmin[j] - 1, j, -one, zero, grid, tail)
            spilled += left
    for k in range(ncw):
        if cmax[k] < 0:
            continue
        if acc_p[k] > 0.0:
            left, tail = _deposit(acc_p[k], c0 + k, cmax[k] + 1, zero, one, grid, tail)
            spilled += left
        if acc_m[k] > 0.0:
            left, tail = _deposit(acc_m[k], c0 + k, cmin[k] - 1, zero, -one, grid, tail)
            spilled += left
    return spilled, tail


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
        if _is_loaded(cn, jn, c0, ncw, cflag):
            continue
        lim = lim_x if STEPS[q, 1] == 0 else lim_y
        gaps[q] = lim - (s - surface(cn, jn, h0, sp, hl))
        room = min(room, gaps[q])
    return room, _room(c, j, c0, ncw, jw0, nyw, clamp, h0, sp, hl)


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
        _take(ca, ja, amount, h0, hl)  # what slides down is loose
        hl[cb, jb] += amount
        return _push(cb, jb, queue, inq, tail), True
    keep = max(room_b, 0.0)
    taken = excess - keep  # a rests at the angle of repose above b risen by keep
    _take(ca, ja, taken, h0, hl)
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
            tail = _push(c, j, queue, inq, tail)
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
    ``grid`` (the work list; ``grid`` as for :func:`_deposit`), below the wheel's swept circle;
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
        if _is_loaded(ca, ja, c0, ncw, cflag):
            continue
        # the excess of each of the node's four slopes (+: a above b), taken together so that
        # a node over-steep on several sides sheds to all of them alike
        sa = surface(ca, ja, h0, sp, hl)
        n_down = 0
        for q in range(4):
            cb = ca + STEPS[q, 0]
            jb = ja + STEPS[q, 1]
            excess[q] = 0.0
            if cb < 0 or cb >= nx or jb < 0 or jb >= ny or _is_loaded(cb, jb, c0, ncw, cflag):
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
                tail = _push(ca, ja, queue, inq, tail)
    visits = head
    while head < tail:  # budget exhausted: clear the remaining marks
        inq[queue[head & mask, 0], queue[head & mask, 1]] = 0
        head += 1
    return visits
