"""The layer a steered wheel drags, in the plane (issue 70): the two-dimensional continuity of
the layer the rim drags (grouser height + ``shear_band`` d at ``slip_flow`` f times the
mobilised shear of eq. (8); :mod:`.deformation` has the straight wheel's account).

The ground passes under a steered wheel along the carriage's travel, at V, entering across the
front (v b per unit time, b the width) and across the leading side (|v_y| L, L the footprint's
length). The rim drags the layer over it at f times the slip vector s. Only where the layer's
flux changes along the ground's path is soil taken or left, so the straight wheel's rules hold
along the travel, with the slip's component along it, s_t = s . V / |V|
(:func:`.layer.travel_slip`): a skid-like s_t > 0 drags the layer off the ground ahead (a
locked wheel's s_t is V at every angle, so it digs as deep whatever its angle); a drive-like
s_t < 0 thins it and leaves it behind; none where the rim's speed along the travel, omega r
cos(beta), equals the carriage's. :func:`.flow._convey` digs the heading's share v / V of a
skid and the drive's thinning per row; :func:`drag_along_axle` the side's share, node by node
where the shear mobilises.

The slip's component across the travel, s_p, shears the layer sideways over ground that
passes along the travel: no soil is taken inside the footprint, but near its upstream side edge
the layer is dragged away and nothing is dragged in from the ground beside it, which the wheel
does not shear. Ground that has been under the wheel for a time tau has lost its layer within
f |s_p| tau of that edge, the share f |s_p| tau / W of the footprint's width W across the travel;
:func:`carry_across` takes that share from every loaded node as it grows (where across the
footprint a node lies is not tracked) and leaves it beyond the downstream side edge. A wheel
dragged sideways while it turns (beta = 90 deg: s_p is the rim's speed) so carries its layer
out of its trench along its heading. What the travel's own dig has taken is not taken again.

No new parameter; at beta = 0 neither runs and the straight rules are unchanged bit for bit.
"""

from __future__ import annotations

import math

from numba import njit

from .layer import row_mobilised, travel_slip
from .layout import (
    P_B,
    P_DIGMOB,
    P_DT,
    P_DX,
    P_FLOWDEPTH,
    P_J,
    P_SHEARDISP,
    P_SLIPFLOW,
    P_V,
    P_VLAT,
)
from .soil_grid import LOADED_ELASTIC, LOADED_YIELDING, take_soil

__all__ = ["carry_across", "drag_along_axle"]


@njit(cache=True)
def _footprint_extent(cmin, cmax, ncw):
    """(loaded columns, first loaded row, last loaded row) of the window's footprint."""
    n_cols = 0
    jmin = 1 << 30
    jmax = -1
    for k in range(ncw):
        if cmax[k] >= 0:
            n_cols += 1
            jmin = min(jmin, cmin[k])
            jmax = max(jmax, cmax[k])
    return n_cols, jmin, jmax


@njit(cache=True)
def drag_along_axle(prm, ground, marks, window, scratch, vty, dy):
    """The side's share of a skid-like layer (module doc), per window column: the layer is
    dragged off the ground and pushed out of the leading side into the soil beside the rut (it
    cannot thicken under the wheel), at f s_t / V of its depth d per node passing. A node loses
    it as its shear mobilises: in the displacement form d f' (exp(-(j - dj)/J) - exp(-j/J)) in
    a step in which its shear path grew from j - dj to j, with f' = f s_t / V times the side's
    share of the ground passing, |v_y| L / (v b + |v_y| L) (every node sees the rule, only that
    share entered across the side); in the velocity form, mobilised at once, at the column's
    leading node, d f s_t / V (1 - exp(-|v_t|/J)) |v_y| per length (the ground crossing the
    side). A locked wheel dragged along its axle (s_t = V, all of it across the side) is dug by
    up to d f per passage. Added to the columns' accumulators."""
    h0, hl, js = ground.h0, ground.hl, ground.js
    cflag = marks.cflag
    c0, ncw = window.c0, window.ncw
    work, iwork = scratch.work, scratch.iwork
    vtx_col, vt_col = work[1], work[7]
    acc_p, acc_m = work[5], work[6]
    cmin, cmax = iwork[3, :ncw], iwork[4, :ncw]
    depth = prm[P_FLOWDEPTH]
    fslip = prm[P_SLIPFLOW]
    if depth <= 0.0 or fslip <= 0.0:
        return
    J = prm[P_J]
    disp_form = prm[P_SHEARDISP] > 0.5
    dt = prm[P_DT]
    v = prm[P_V]
    v_lat = prm[P_VLAT]
    speed = math.hypot(v, v_lat)
    side_share = 1.0
    if disp_form:
        n_cols = _footprint_extent(cmin, cmax, ncw)[0]
        side_in = abs(v_lat) * n_cols * prm[P_DX] / prm[P_B]
        side_share = side_in / (v + side_in) if side_in > 0.0 else 0.0
    for k in range(ncw):
        if cmax[k] < 0:
            continue
        s_t = travel_slip(vtx_col[k], vty, v, v_lat)
        if s_t <= 0.0:
            continue  # drive-like: _convey thins the layer
        f = fslip * s_t / speed * side_share
        a = 0.0  # [m * nodes] dragged off in this step
        lead = -1
        for j in range(cmin[k], cmax[k] + 1):
            if LOADED_ELASTIC <= cflag[k + 1, j] <= LOADED_YIELDING:
                if disp_form:
                    path = js[c0 + k, j]
                    grown = math.exp(-max(path - vt_col[k] * dt, 0.0) / J) - math.exp(-path / J)
                    take_soil(c0 + k, j, depth * f * grown, h0, hl)
                    a += depth * f * grown
                elif lead < 0 or vty > 0.0:
                    lead = j
        if lead >= 0:
            a = depth * f * (1.0 - math.exp(-vt_col[k] / J)) * abs(vty) * dt / dy
            take_soil(c0 + k, lead, a, h0, hl)
        if vty > 0.0:
            acc_p[k] += a
        else:
            acc_m[k] += a


@njit(cache=True)
def carry_across(prm, xi, ground, marks, window, scratch, vty, dy):
    """The layer the slip's component across the travel, s_p, carries out of the footprint's
    side edge (module doc). A loaded node that has been under the wheel for tau = j / |v_t|
    (its shear path over its slip speed) loses d (1 - r) f |s_p| dt / W in a step, W the
    footprint's extent across the travel, while f |s_p| tau < W: the layer of the share of the
    ground the bare strip reaches in the step, so d (1 - r) once the strip spans the footprint.
    r is the share of the layer the travel's own rule took (skid: min(f s_t / V, 1); drive:
    thinning f|s_t| / (V + f|s_t|), or ``slip_flow`` times the mobilised shear over the
    ground's mean path L b / W where the rim carries off its layer); f is ``slip_flow`` times
    the node's mobilised shear. The slip is the rim's at the wheel's lowest point. Left beyond
    the downstream side edge: along the heading (the rows' accumulators) and the axle (the
    columns') in the proportion of that direction's components."""
    h0, hl, js = ground.h0, ground.hl, ground.js
    cflag = marks.cflag
    c0, ncw = window.c0, window.ncw
    work, iwork = scratch.work, scratch.iwork
    vtx_col, vt_col = work[1], work[7]
    acc_f, acc_b, acc_p, acc_m = work[3], work[4], work[5], work[6]
    cmin, cmax = iwork[3, :ncw], iwork[4, :ncw]
    depth = prm[P_FLOWDEPTH]
    fslip = prm[P_SLIPFLOW]
    if depth <= 0.0 or fslip <= 0.0:
        return
    J = prm[P_J]
    disp_form = prm[P_SHEARDISP] > 0.5
    dx = prm[P_DX]
    dt = prm[P_DT]
    v = prm[P_V]
    v_lat = prm[P_VLAT]
    speed = math.hypot(v, v_lat)
    n_cols, jmin, jmax = _footprint_extent(cmin, cmax, ncw)
    if n_cols == 0:
        return
    kb = -1  # the loaded column nearest the axle: the rim's lowest point
    for k in range(ncw):
        if cmax[k] >= 0 and (kb < 0 or abs(xi[k]) < abs(xi[kb])):
            kb = k
    u = vtx_col[kb]
    s_t = travel_slip(u, vty, v, v_lat)
    s_p = (vty * v - u * v_lat) / speed  # along (-v_y, v) / V
    length = n_cols * dx
    width = (jmax - jmin + 1) * dy
    if s_p == 0.0:
        return
    across = (length * abs(v_lat) + width * v) / speed  # the footprint's extent across the travel
    along = length * width / across  # the ground's mean path under it (mean chord)
    # downstream across the travel: sign(s_p) (-v_y, v) / V
    ex = -math.copysign(1.0, s_p) * v_lat / speed
    ey = math.copysign(1.0, s_p) * v / speed
    wx = abs(ex) / (abs(ex) + abs(ey))
    dig_mobilised = prm[P_DIGMOB] > 0.5
    for k in range(ncw):
        if cmax[k] < 0 or vt_col[k] <= 0.0:
            continue
        for j in range(cmin[k], cmax[k] + 1):
            if not LOADED_ELASTIC <= cflag[k + 1, j] <= LOADED_YIELDING:
                continue
            path = js[c0 + k, j]
            f = fslip * (1.0 - math.exp(-(path if disp_form else vt_col[k]) / J))
            grow = f * abs(s_p)  # the strip's growth across the travel [m/s]
            if grow * path / vt_col[k] >= across:
                continue  # reached: its layer is gone
            if s_t > 0.0:
                taken = min(f * s_t / speed, 1.0)
            elif dig_mobilised:
                taken = fslip * row_mobilised(s_t, speed, along, J, disp_form)
            else:
                taken = f * abs(s_t) / (speed + f * abs(s_t))
            a = depth * (1.0 - taken) * grow * dt / across
            if a <= 0.0:
                continue
            take_soil(c0 + k, j, a, h0, hl)
            if ex > 0.0:
                acc_f[j] += wx * a
            elif ex < 0.0:
                acc_b[j] += wx * a
            if ey > 0.0:
                acc_p[k] += (1.0 - wx) * a
            elif ey < 0.0:
                acc_m[k] += (1.0 - wx) * a
