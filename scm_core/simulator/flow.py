"""The soil flow fields (paper section 3.2; Krenn & Hirzinger 2009): where the volume the wheel
displaces goes, radially out of the footprint and along the slip, the layer the sliding surface
drags, the grouser pockets' conveyor, and where it is deposited (:mod:`.deformation` has the
model's whole account)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .contact import surface_velocity
from .lateral_flow import carry_across, drag_along_axle
from .layer import conveyed, row_mobilised, sliding_face_height, travel_slip
from .layout import (
    P_B,
    P_COMPACTION,
    P_DIGMOB,
    P_DT,
    P_DX,
    P_FACEPLOUGH,
    P_FLOWDEPTH,
    P_HG,
    P_J,
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
from .soil_grid import LOADED_ELASTIC, LOADED_YIELDING, LOOSE_PUSHED, deposit_soil, take_soil
from .state import Columns, FlowScratch, Ground, Marks, Window

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
    vty = prm[P_VLAT] * prm[P_SLIPV]
    compacted = _displaced(keep, cols.xi, marks, window, scratch, xc, yc, wx, vty)
    _convey(prm, zw, cols.xi, ground, marks, window, scratch)
    if vty != 0.0:
        drag_along_axle(prm, ground, marks, window, scratch, vty, dy)
        carry_across(prm, cols.xi, ground, marks, window, scratch, vty, dy)
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
    vty = prm[P_VLAT] * sv  # a steered wheel's slip along its axle (0 straight)
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
        vt = math.sqrt(vtx * vtx + vtz * vtz + vty * vty)
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
def _displaced(keep, xi, marks, window, scratch, xc, yc, wx, vty):
    """The displaced volume of the loaded nodes, less the compacted share (1 - keep): its
    parallel share along the surface's slip and the rest radially from the centroid (xc, yc),
    in the proportion wx along x, gathered per row and column. A steered wheel's parallel share
    follows its horizontal slip (vtx, vty [m/s]), split between x and y as |vtx| : |vty|.
    Returns the compacted volume [m * nodes]."""
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
            par = share_col[k] * dv if vtx_col[k] != 0.0 or vty != 0.0 else 0.0
            if par > 0.0:
                par_x = par
                if vty != 0.0:
                    # the soil flows along the slip, whatever the wheel's heading
                    par_y = par * abs(vty) / (abs(vtx_col[k]) + abs(vty))
                    par_x = par - par_y
                    if vty > 0.0:
                        acc_p[k] += par_y
                    else:
                        acc_m[k] += par_y
                if vtx_col[k] > 0.0:
                    acc_f[j] += par_x
                elif vtx_col[k] < 0.0:
                    acc_b[j] += par_x
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
    v_lat = prm[P_VLAT]  # a steered wheel's lateral velocity (0 straight)
    vty = v_lat * prm[P_SLIPV]  # and its slip along the axle
    travel_x = 1.0  # the heading's share of the carriage's speed, v / V
    if v_lat != 0.0:
        # a steered wheel's layer digs and thins by its slip along the travel (layer.travel_slip),
        # and a skidding rim's sliding face is the one it meets along the travel, where the rim
        # moves at omega r cos(beta) against the carriage's V
        speed = math.hypot(v, v_lat)
        travel_x = v / speed
        if face_plough:
            y_slide = sliding_face_height(
                speed * prm[P_SLIPV], omega_s * travel_x, r_out, prm[P_TANDELTA]
            )
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
            if v_lat != 0.0:
                u = travel_slip(u, vty, v, v_lat)
            if u == 0.0:
                continue
            sgn = 1 if u > 0.0 else -1
            f = fslip
            v_pass = v  # the ground's speed through the row's footprint
            if v_lat != 0.0:
                # fresh ground enters a steered row's footprint across it too, at |v_y| over the
                # row's loaded length out of the wheel's width; a skid's dig is shared with the
                # ground entering across the side (lateral_flow.drag_along_axle) as the
                # carriage's velocity is: the heading's share v / V of it here
                v_pass = v + abs(v_lat) * nu * dx / prm[P_B]
                if sgn > 0:
                    if travel_x == 0.0:
                        continue  # dragged along its axle: all of it across the side
                    f *= travel_x
            if dig_mobilised and sgn < 0:
                mob = row_mobilised(u, v_pass, nu * dx, J, disp_form)
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
            flux = conveyed(layer, f * mob, u, v_pass, dig_mobilised)
            if sgn > 0 and plough > 0.0 and not face_plough:
                # ploughing: in the wheel's frame the path ahead comes at v; the rim rolls it
                # under at its bottom speed omega r, the rest meets the front face as a blade,
                # which pushes the fraction `plough` of it ahead with the dragged layer
                flux += plough * h * max(v - omega * r_shear, 0.0)
            a_pocket = 0.0
            # (a steered wheel's pockets too only where its slip along the travel is drive-like:
            # the straight rule has no continuity floor, and a wheel at 90 deg, whose pockets
            # pass the same trench again and again, then digs without bound; docs/steering.md)
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
                    take_soil(c0 + kb, j, a, h0, hl)
                    acc_f[j] += a
            else:
                # drive: the layer thins as it passes under the wheel (taken from every loaded
                # ground node of the row alike) and leaves behind the wheel
                share = a / nu
                for k in range(rmin[j], gmax[j] + 1):
                    if LOADED_ELASTIC <= cflag[k + 1, j] <= LOADED_YIELDING:
                        take_soil(c0 + k, j, share, h0, hl)
                if a_pocket > 0.0:
                    # the pockets' soil is cut where the grousers enter it: from the top of the
                    # front wall (the row's front-most loaded node), which the wheel then meets
                    # excavated instead of compacting it; left behind the wheel with the layer
                    take_soil(c0 + gmax[j], j, a_pocket, h0, hl)
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
    one = np.int64(1)  # directions as values: literals would compile deposit once per value
    zero = np.int64(0)
    for j in range(jw0, jw0 + nyw):
        if rmax[j] < 0:
            continue
        if acc_f[j] > 0.0:
            left, tail = deposit_soil(acc_f[j], c0 + rmax[j] + 1, j, one, zero, grid, tail)
            spilled += left
        if acc_b[j] > 0.0:
            left, tail = deposit_soil(acc_b[j], c0 + rmin[j] - 1, j, -one, zero, grid, tail)
            spilled += left
    for k in range(ncw):
        if cmax[k] < 0:
            continue
        if acc_p[k] > 0.0:
            left, tail = deposit_soil(acc_p[k], c0 + k, cmax[k] + 1, zero, one, grid, tail)
            spilled += left
        if acc_m[k] > 0.0:
            left, tail = deposit_soil(acc_m[k], c0 + k, cmin[k] - 1, zero, -one, grid, tail)
            spilled += left
    return spilled, tail
