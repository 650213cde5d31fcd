"""The layer a slipping rim drags, along one direction (paper section 3.2 and
:mod:`.deformation`'s account): how much of its shear is mobilised over a row, the flux it
carries (drive: thinned by continuity, or carried off where mobilised; skid: pushed ahead), the
height of a skidding rim's sliding face, and the slip a steered wheel's layer sees along its
travel."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def row_mobilised(u: float, v: float, length: float, J: float, disp_form: bool) -> float:
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
def conveyed(depth: float, f: float, u: float, v: float, mobilised: bool) -> float:
    """Flux [m^2/s] of the layer of ``depth`` the rim drags at the mean slip velocity ``u``
    over ground (< 0: backwards, a driven wheel), f the dragged fraction (slip_flow times the
    mobilised shear of eq. (8)), v the carriage speed.

    Drive, ``mobilised`` False (thinning): continuity in the wheel's frame; the ground enters
    the footprint at v, a layer accelerated backwards to v + f|u| thins to depth v / (v + f|u|),
    and the wheel sinks by the difference, depth f|u| / (v + f|u|), at most depth * slip.
    Drive, ``mobilised`` True: the rim carries off the layer to the fraction f of its depth in
    which its shear is mobilised (f from the row's slip, :func:`row_mobilised`: the soil in the
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


@njit(cache=True, inline="always")
def travel_slip(u: float, vty: float, v: float, v_lat: float) -> float:
    """A steered wheel's slip [m/s] along its travel: the slip vector (u along the heading,
    ``vty`` along the axle; the surface over the ground) projected on the carriage's velocity
    (``v`` along the heading, ``v_lat`` along the axle). Positive where the surface slides ahead
    of the ground along the travel (skid-like: a locked wheel's slip is the carriage speed at
    every angle), negative where the rim drives it back (drive-like); 0 where the rim's speed
    along the travel, omega r cos(beta), equals the carriage's. The straight wheel's u."""
    return (u * v + vty * v_lat) / math.hypot(v, v_lat)
