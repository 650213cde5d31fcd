"""Wheel lower surface as a z-buffer over DEM columns (paper section 3.1, contact detection).

Straight grousers make the wheel's lower surface independent of y across the width, so the z-buffer
is a per-column envelope (one value per DEM column x) of the rim circle and the grouser rectangles.
Each column stores the cell-averaged height of the envelope relative to the axle, and the unit
direction of the soil's normal force on the wheel there (the inward face normal, eq. (9)).

Angles: ``psi`` is measured from straight down towards +x (forward). A wheel driving forward turns
so that material points move from the front (psi > 0) down to the bottom, so psi_k(t) = psi_k0 -
omega t.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

N_SUB = 8  # sub-samples per column where a grouser crosses it (cell average of the envelope)
_VISIBLE_COS = 0.25  # grousers whose direction is within ~75 deg of straight down can touch soil


@njit(cache=True)
def _rim_point(x: float, R: float):
    """Lowest rim point at relative x: (z, fx, fz), z = +inf where the rim does not reach."""
    if abs(x) >= R:
        return np.inf, 0.0, 1.0
    z = -math.sqrt(R * R - x * x)
    return z, -x / R, -z / R


@njit(cache=True)
def _grouser_point(x: float, s_psi: float, c_psi: float, r_in: float, r_out: float, half_t: float):
    """Lowest point of one grouser rectangle at relative x: (z, fx, fz), +inf if not covered.

    The rectangle is {r u + s w : r in [r_in, r_out], |s| <= half_t} with u = (sin psi, -cos psi)
    (outward along the grouser) and w = (cos psi, sin psi). Only the tip and the two side faces can
    be lowest; (fx, fz) is the inward normal of the face hit, i.e. the direction of the soil's
    normal force on the wheel.
    """
    best = np.inf
    fx = 0.0
    fz = 1.0
    if c_psi > 1e-12:  # tip face r = r_out
        s = (x - r_out * s_psi) / c_psi
        if abs(s) <= half_t:
            z = -r_out * c_psi + s * s_psi
            if z < best:
                best = z
                fx = -s_psi
                fz = c_psi
    if abs(s_psi) > 1e-12:  # side faces s = +-half_t
        for sgn in (1.0, -1.0):
            r = (x - sgn * half_t * c_psi) / s_psi
            if r_in <= r <= r_out:
                z = -r * c_psi + sgn * half_t * s_psi
                if z < best:
                    best = z
                    fx = -sgn * c_psi
                    fz = -sgn * s_psi
    return best, fx, fz


@njit(cache=True)
def _lowest_point(x, R, vis_s, vis_c, n_vis, r_in, r_out, half_t):
    """Lowest point of rim and visible grousers at relative x: (z, fx, fz)."""
    zb, bfx, bfz = _rim_point(x, R)
    for g in range(n_vis):
        zg, gfx, gfz = _grouser_point(x, vis_s[g], vis_c[g], r_in, r_out, half_t)
        if zg < zb:
            zb = zg
            bfx = gfx
            bfz = gfz
    return zb, bfx, bfz


@njit(cache=True)
def wheel_envelope(
    xi: np.ndarray,
    dx: float,
    R: float,
    n_grousers: int,
    grouser_height: float,
    grouser_thickness: float,
    theta: float,
    e_out: np.ndarray,
    fx_out: np.ndarray,
    fz_out: np.ndarray,
    vis: np.ndarray,
) -> None:
    """Fill the z-buffer of columns at relative positions ``xi`` (m from the axle).

    e_out: cell-averaged envelope height relative to the axle [m] (+inf: no wheel above the cell);
    (fx_out, fz_out): unit direction of the normal soil force on the wheel. ``theta`` is the wheel's
    rotation angle [rad]; grouser k sits at psi = 2 pi k / N - theta. Columns that a grouser crosses
    are averaged over N_SUB sub-points, so a grouser thinner than dx still displaces its volume.
    ``vis`` (2, >= n_grousers) is scratch space for the visible grousers' sin and cos.
    """
    ncol = xi.shape[0]
    for k in range(ncol):
        z, fx, fz = _rim_point(xi[k], R)
        e_out[k] = z
        fx_out[k] = fx
        fz_out[k] = fz
    if n_grousers == 0 or grouser_height <= 0.0:
        return
    r_out = R + grouser_height
    r_in = R - grouser_height
    half_t = 0.5 * grouser_thickness
    pitch = 2.0 * math.pi / n_grousers
    vis_s = vis[0]
    vis_c = vis[1]
    n_vis = np.int64(0)  # a value: a literal 0 compiles _lowest_point twice
    for g in range(n_grousers):
        psi = (g * pitch - theta + math.pi) % (2.0 * math.pi) - math.pi
        c_psi = math.cos(psi)
        if c_psi >= _VISIBLE_COS:
            vis_s[n_vis] = math.sin(psi)
            vis_c[n_vis] = c_psi
            n_vis += 1
    x0 = xi[0] - 0.5 * dx
    for g in range(n_vis):
        s_psi = vis_s[g]
        c_psi = vis_c[g]
        # horizontal span of the rectangle's outer half (the inner part hides inside the rim)
        xs_lo = np.inf
        xs_hi = -np.inf
        for r in (R, r_out):
            for sgn in (1.0, -1.0):
                xc = r * s_psi + sgn * half_t * c_psi
                xs_lo = min(xs_lo, xc)
                xs_hi = max(xs_hi, xc)
        k_lo = max(0, int(math.floor((xs_lo - x0) / dx)))
        k_hi = min(ncol - 1, int(math.floor((xs_hi - x0) / dx)))
        for k in range(k_lo, k_hi + 1):
            zsum = 0.0
            zmin = np.inf
            fxs = 0.0
            fzs = 0.0
            n_cov = 0
            for q in range(N_SUB):
                xq = xi[k] + dx * ((q + 0.5) / N_SUB - 0.5)
                zb, bfx, bfz = _lowest_point(xq, R, vis_s, vis_c, n_vis, r_in, r_out, half_t)
                if np.isfinite(zb):
                    zsum += zb
                    zmin = min(zmin, zb)
                    fxs += bfx
                    fzs += bfz
                    n_cov += 1
            if n_cov == 0:
                continue
            # partly covered cells (wheel edge) keep the lowest covered point
            e_out[k] = zsum / N_SUB if n_cov == N_SUB else zmin
            nrm = math.sqrt(fxs * fxs + fzs * fzs)
            if nrm > 0.0:
                fx_out[k] = fxs / nrm
                fz_out[k] = fzs / nrm


@njit(cache=True)
def tip_circle(xi: np.ndarray, r_out: float, eb_out: np.ndarray) -> None:
    """Lowest point of the circle through the grouser tips at relative positions ``xi`` [m].

    eb_out: height relative to the axle [m] (+inf beyond the circle). For a smooth wheel r_out = R
    and this is the rim of ``wheel_envelope`` exactly. Bekker's plate width is taken on this
    envelope (see contact.evaluate_contact).
    """
    for k in range(xi.shape[0]):
        eb_out[k] = _rim_point(xi[k], r_out)[0]
