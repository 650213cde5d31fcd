"""Plastic soil deformation (paper section 3.2): the node update under the wheel and the bow wave's
load; the flow fields are :mod:`.flow` (the dragged layer's rules along one direction
:mod:`.layer`, a steered wheel's in the plane :mod:`.lateral_flow`), erosion :mod:`.erosion`,
the grid's node operations :mod:`.soil_grid`.

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
    P_DT,
    P_K,
    P_OMEGA,
    P_SHEARDISP,
    P_SHEARSCALE,
    P_SLIPV,
    P_V,
    P_VLAT,
)
from .soil_grid import LOADED_ELASTIC, LOADED_YIELDING, LOOSE_PUSHED
from .state import Columns, Ground, Marks, Patches, Window


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
) -> tuple[float, float]:
    """Apply the converged step to the nodes under the wheel; return the displaced soil
    [m * nodes] and the plastic work done on the nodes per unit area, the sum of their yield
    stress times their plastic sinkage's increment [Pa m = J/m^2] (the compaction's energy).

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
    # the shear path: eq. (8)'s displacement form, and a steered wheel's layer
    # (lateral_flow.carry_across: how long a node has been under the wheel)
    track = disp_form or vty != 0.0
    flow = 0.0
    work = 0.0
    for p in range(npatch):
        k = pc[p]
        c = c0 + k
        hit = zw + e[k]
        if pflag[p] == 0:
            continue
        vt = 0.0
        if track:
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
                work += sb * (spn - sp[c, jj])
                sp[c, jj] = spn
                sy[c, jj] = sb
                el = sink - spn
                ke[c, jj] = sb / el if el > 1e-12 and sb / el > K else K
            else:
                cflag[k + 1, jj] = LOADED_ELASTIC
            if track:
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
    return flow, work


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
