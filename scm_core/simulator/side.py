"""The side of a steered wheel pushing soil: passive earth pressure on its leading side.

A wheel at a slip angle slides along its axle (``P_VLAT``); below the ground its leading side is
a wall pushed into the soil beside the rut, which fails in passive shear ahead of it and resists
with the passive earth pressure: Bekker's and Hegedus's bulldozing resistance of a blade, which
Ishigami et al. (2007, J. Field Robotics 24(3)) apply to a steered wheel's side. Per unit length
of a smooth vertical wall of depth h in level soil of unit weight gamma, cohesion c and friction
angle phi, Rankine's passive force is

    P_p = 1/2 gamma h^2 K_p + 2 c h sqrt(K_p),   K_p = tan^2(45 deg + phi / 2)

(Coulomb's wedge gives the same for a smooth wall, which the wheel's side is taken to be: it
slides along the soil as the wheel turns). The side is short: its length along the heading, the
chord of the wheel below the soil, is about its depth, and a short wall's failure spreads
sideways beyond its ends and resists more (Hettiaratchi & Reece 1974; Godwin & Spoor 1977).
McKyes & Ali's (1977; McKyes 1985, "Soil Cutting and Tillage", ch. 4) three-dimensional wedge for
a vertical smooth wall of depth d and length w: a central wedge whose failure plane rises at
beta from the wall's foot, reaching r = d cot(beta) ahead, and two side crescents of radius r,

    P = min over beta of  w [gamma d^2 N_g + c d N_c]
    N_g = (r / 2d) (1 + 2/3 r / w) tan(beta + phi),
    N_c = (1 + cot(beta) cot(beta + phi)) (1 + r / w) tan(beta + phi),

which is Rankine's force for a long wall (w >> d: beta = 45 deg - phi / 2) and up to about twice
it for the wheel's side. The side's depth varies along it (the rim's circle, the ground beside
the rut): the wall is the rectangle with the same area and the same Rankine force, d =
Sum h^2 / Sum h and w = dx (Sum h)^2 / Sum h^2 over the window's columns where the side's lower
edge, the circle through the grouser tips, is below the level of the row the side moves into
(ground, plastic sinkage and the loose soil heaped there), and at most the disc's height there
(a wheel dug in beyond its radius pushes with its whole side, not above it). Mobilised like the
shear of eq. (8): 1 - exp(-|v_y| / J) (velocity form), 1 - exp(-|v_y| t / J) (displacement form,
the wall's travel into the soil). No new parameter: gamma, c and phi are the soil's.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .layout import P_C, P_GAMMA, P_J, P_SHEARDISP, P_SLIPV, P_TANPHI, P_VLAT
from .state import Columns, Ground

__all__ = ["passive_force_3d", "side_force"]


@njit(cache=True)
def _wedge_3d(gamma: float, c: float, phi: float, d: float, w: float, beta: float) -> float:
    """McKyes & Ali's force [N] on a smooth vertical wall (depth d, length w [m]) for the
    failure plane at ``beta`` [rad] (module doc)."""
    r = d / math.tan(beta)
    t = math.tan(beta + phi)
    n_g = 0.5 * (r / d) * (1.0 + (2.0 / 3.0) * r / w) * t
    n_c = (1.0 + 1.0 / (math.tan(beta) * t)) * (1.0 + r / w) * t
    return w * (gamma * d * d * n_g + c * d * n_c)


@njit(cache=True)
def passive_force_3d(gamma: float, c: float, tan_phi: float, d: float, w: float) -> float:
    """McKyes & Ali's three-dimensional passive force [N] on a smooth vertical wall of depth
    ``d`` and length ``w`` [m] pushed into level soil (module doc): the least over the failure
    plane's angle, found by golden-section search (the force is unimodal in beta)."""
    if d <= 0.0 or w <= 0.0:
        return 0.0
    phi = math.atan(tan_phi)
    lo, hi = 1e-6, 0.5 * math.pi - phi - 1e-6
    g = 0.5 * (math.sqrt(5.0) - 1.0)
    a = hi - g * (hi - lo)
    b = lo + g * (hi - lo)
    fa = _wedge_3d(gamma, c, phi, d, w, a)
    fb = _wedge_3d(gamma, c, phi, d, w, b)
    for _ in range(80):
        if fa < fb:
            hi, b, fb = b, a, fa
            a = hi - g * (hi - lo)
            fa = _wedge_3d(gamma, c, phi, d, w, a)
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = _wedge_3d(gamma, c, phi, d, w, b)
    return min(fa, fb)


@njit(cache=True, nogil=True)
def side_force(
    prm: np.ndarray,
    ground: Ground,
    cols: Columns,
    c0: int,
    ncw: int,
    jw0: int,
    nyw: int,
    zw: float,
    dx: float,
    t: float,
) -> float:
    """The soil's force on the wheel's leading side along the axle (+y) [N] (module doc) at
    axle height ``zw`` [m] and time ``t`` [s]; 0 for a wheel driven straight."""
    v_lat = prm[P_VLAT]
    if v_lat == 0.0:
        return 0.0
    j = jw0 + nyw if v_lat > 0.0 else jw0 - 1  # the row the side moves into
    h0, sp, hl = ground.h0, ground.sp, ground.hl
    if j < 0 or j >= h0.shape[1]:
        return 0.0
    s1 = 0.0  # Sum h, Sum h^2 over the wall's columns [m, m^2]
    s2 = 0.0
    for k in range(ncw):
        bottom = cols.eb[k]
        if not np.isfinite(bottom):
            continue
        c = c0 + k
        # the wall is the disc: at most its height in this column, from eb to -eb
        depth = min(h0[c, j] - sp[c, j] + hl[c, j] - (zw + bottom), -2.0 * bottom)
        if depth > 0.0:
            s1 += depth
            s2 += depth * depth
    if s1 <= 0.0:
        return 0.0
    total = passive_force_3d(prm[P_GAMMA], prm[P_C], prm[P_TANPHI], s2 / s1, dx * s1 * s1 / s2)
    slide = abs(v_lat) * prm[P_SLIPV]
    travel = slide * t if prm[P_SHEARDISP] > 0.5 else slide
    mobilised = 1.0 - math.exp(-travel / prm[P_J])
    return -math.copysign(total * mobilised, v_lat)  # against the sliding
