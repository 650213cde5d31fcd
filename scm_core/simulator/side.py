"""The side of a steered wheel pushing soil: passive earth pressure on its leading side.

A wheel at a slip angle slides along its axle (``P_VLAT``); below the ground its leading side is
a wall pushed into the soil beside the rut, which fails in passive shear ahead of it and resists
with the passive earth pressure: Bekker's and Hegedus's bulldozing resistance of a blade, which
Ishigami et al. (2007, J. Field Robotics 24(3)) apply to a steered wheel's side. Per unit length
of a smooth vertical wall of depth h in level soil of unit weight gamma, cohesion c and friction
angle phi, Rankine's passive force is

    P_p = 1/2 gamma h^2 K_p + 2 c h sqrt(K_p),   K_p = tan^2(45 deg + phi / 2)

(Coulomb's wedge gives the same for a smooth wall, which the wheel's side is taken to be: it
slides along the soil as the wheel turns). Summed over the window's columns where the side's
lower edge, the circle through the grouser tips, is below the level of the row the side moves
into (ground, plastic sinkage and the loose soil heaped there), times the column width dx.
Mobilised like the shear of eq. (8): 1 - exp(-|v_y| / J) (velocity form), 1 - exp(-|v_y| t / J)
(displacement form, the wall's travel into the soil). Rankine's two-dimensional wedge; a short
wall's failure spreads sideways beyond its length and resists more (Hettiaratchi & Reece 1974;
McKyes 1985), which this leaves out (no new parameter without evidence for it).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .deformation import passive_coefficient
from .layout import P_C, P_GAMMA, P_J, P_SHEARDISP, P_SLIPV, P_TANPHI, P_VLAT
from .state import Columns, Ground

__all__ = ["passive_force_per_length", "side_force"]


@njit(cache=True)
def passive_force_per_length(gamma: float, c: float, tan_phi: float, h: float) -> float:
    """Rankine's passive force [N/m] on a smooth vertical wall of depth ``h`` [m] pushed into
    level soil of unit weight ``gamma`` [N/m^3], cohesion ``c`` [Pa] and friction tan(phi)."""
    if h <= 0.0:
        return 0.0
    kp = passive_coefficient(tan_phi)
    return 0.5 * gamma * h * h * kp + 2.0 * c * h * math.sqrt(kp)


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
    total = 0.0
    for k in range(ncw):
        bottom = cols.eb[k]
        if not np.isfinite(bottom):
            continue
        c = c0 + k
        depth = h0[c, j] - sp[c, j] + hl[c, j] - (zw + bottom)
        total += passive_force_per_length(prm[P_GAMMA], prm[P_C], prm[P_TANPHI], depth) * dx
    slide = abs(v_lat) * prm[P_SLIPV]
    travel = slide * t if prm[P_SHEARDISP] > 0.5 else slide
    mobilised = 1.0 - math.exp(-travel / prm[P_J])
    return -math.copysign(total * mobilised, v_lat)  # against the sliding
