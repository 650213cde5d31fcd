"""Packing of the three parameter types into the flat float64 vector the numba kernel reads."""

from __future__ import annotations

import math

import numpy as np

from .params import GRAVITY, RigConfig, SoilParams, WheelGeometry
from .rig import ResolvedRig, resolve_rig

# the packed vector's slots: one declaration, each name its index in order (a new slot goes
# at the end, so every older index stays)
(
    # soil
    P_N,
    P_KC,
    P_KPHI,
    P_C,
    P_TANPHI,
    P_DSOIL,
    P_J,
    P_K,
    P_TANREPOSE,
    P_COMPACTION,
    P_FLOWDEPTH,
    P_SLIPFLOW,
    # wheel
    P_R,
    P_B,
    P_NGROUSERS,
    P_HG,
    P_TG,
    # rig and numerics
    P_W,
    P_MASS,
    P_V,
    P_OMEGA,
    P_DURATION,
    P_DT,
    P_DX,
    P_OUTEVERY,
    P_TAPER,
    P_BULLDOZE,
    P_SHEARDISP,
    P_MAXSINK,
    P_MARGIN,
    P_OFF_F,
    P_OFF_T,
    P_OFF_Z,
    P_DYDX,
    P_INCL,  # exponent of the bearing-capacity inclination factor (0: off)
    P_PLOUGH,  # fraction of a skidding wheel's path pushed ahead (0: off)
    P_DIGMOB,  # drive digging: 1 mobilised (dug depth d f), 0 thinning
    P_FACEPLOUGH,  # skid ploughing: 1 the front face's sliding zone (derived), 0 kappa
    P_EROSIONEVERY,  # steps between erosion passes
    P_SETTLE,  # early stop once the steady means are settled (fraction of W, W R, R; 0: off)
    P_POCKET,  # depth of the soil trapped between grousers, carried at the rim speed [m] (0: off)
    P_TANDELTA,  # friction of the soil on the wheel's surface, tan(delta) (eq. (8) on the wheel)
    P_POCKETFILL,  # how full the grouser pockets leave the contact (0: continuity, 1: full)
    P_ZDATUM,  # depth of the sinkage datum below the contact envelope's first contact [m]
    P_SHEARSCALE,  # radius of the surface shearing the soil / the contact envelope's (1: same)
    P_SLIPV,  # carriage speed the shearing surface's slip sees / the carriage's (1: the same)
    P_STUCKSOIL,  # 1: where the wheel's surface sticks to the soil, the soil shears (at phi)
    P_POCKETKEEP,  # 1: the pockets carry off only the soil they keep (pocket_fill), no floor
    P_GAMMA,  # unit weight of the soil, rho g [N/m^3] (0: weightless deposits, SCM)
    P_VLAT,  # the axle's velocity along the axle (+y), -v sin(beta) [m/s] (0: straight)
    N_PARAMS,
) = range(51)

STATUS_NAMES = ("ok", "bottomed_out", "nonpositive_stiffness", "unstable")
STATUS_OK = 0
STATUS_BOTTOMED_OUT = 1
STATUS_NONPOSITIVE_STIFFNESS = 2
STATUS_UNSTABLE = 3


def _slip_velocity_scale(kin: float, r: float, rig: ResolvedRig) -> float:
    """sv, what the carriage speed counts for in the slip of a rim-bearing grousered wheel's
    shearing surface, which turns at omega and lies kin = r_s / r times farther out than the rim
    of radius r [m]: its slip at the bottom is kin omega r - sv v. 'tips': sv = 1 (the tips' own
    velocity); 'rim': sv = kin (kin times the rim's slip velocity, Ding et al. 2011);
    'rim_drive': kin in drive, and in skid 1 + (kin - 1) omega r / v, so the slip is the rim's
    own, omega r - v (the carriage speed at lock), continuous through zero slip."""
    if rig.grouser_slip == "rim":
        return kin
    if rig.grouser_slip == "rim_drive":
        return 1.0 + (kin - 1.0) * min(rig.omega * r / rig.carriage_speed, 1.0)
    return 1.0


def pack(soil: SoilParams, wheel: WheelGeometry, rig: RigConfig) -> np.ndarray:
    """Flat parameter vector for :func:`scm_core.simulator.kernel.run_swt` (the rig resolved by
    :func:`scm_core.simulator.rig.resolve_rig`; raises its ValueError)."""
    return pack_resolved(soil, wheel, resolve_rig(wheel, rig))


def pack_resolved(soil: SoilParams, wheel: WheelGeometry, rig: ResolvedRig) -> np.ndarray:
    """:func:`pack` for an already resolved rig."""
    p = np.zeros(N_PARAMS)
    h_g = wheel.grouser_height if wheel.has_grousers else 0.0
    trapped = rig.grouser_contact != "faces" and h_g > 0.0
    # rim bearing: the thin grousers penetrate and the rim bears; the trapped soil shears at
    # the tips. tip circle: the trapped soil bears and shears at the tips
    rim_bearing = trapped and rig.grouser_contact == "rim_bearing"
    envelope = wheel.R if rim_bearing or not trapped else wheel.R + h_g  # contact circle [m]
    p[P_N] = soil.n
    p[P_KC] = soil.k_c
    p[P_KPHI] = soil.k_phi
    p[P_C] = soil.c
    p[P_TANPHI] = soil.tan_phi
    # the wheel's surface shears the soil at delta; the tip circle is soil on soil
    p[P_TANDELTA] = soil.tan_phi * (1.0 if trapped else soil.interface_friction)
    p[P_DSOIL] = soil.D_soil
    p[P_J] = soil.J
    p[P_K] = soil.K
    p[P_TANREPOSE] = math.tan(math.radians(soil.repose_angle))
    p[P_COMPACTION] = soil.compaction
    # tip circle: the grousers' soil is the pocket layer (P_POCKET), the dragged band lies below
    p[P_FLOWDEPTH] = (0.0 if trapped else h_g) + soil.shear_band
    p[P_SLIPFLOW] = soil.slip_flow
    # trapped soil: the wheel's contact is a circle (no faces), the tips' or the rim's
    p[P_R] = envelope
    p[P_B] = wheel.b
    p[P_NGROUSERS] = 0 if trapped else (wheel.n_grousers if wheel.has_grousers else 0)
    p[P_HG] = 0.0 if trapped else h_g
    p[P_POCKET] = h_g if trapped else 0.0
    p[P_POCKETFILL] = soil.pocket_fill
    p[P_TG] = wheel.grouser_thickness
    p[P_W] = rig.W
    p[P_MASS] = rig.mass
    # a steered wheel (slip angle beta): the carriage's velocity along the heading, which the
    # wheel's plane sees, and along the axle, which slides the wheel sideways (exactly v and 0
    # at beta = 0; the heading's component exactly 0 at 90 deg)
    beta = math.radians(rig.slip_angle)
    along = math.cos(beta)
    p[P_V] = rig.carriage_speed * (along if abs(along) > 1e-12 else 0.0)
    p[P_VLAT] = -rig.carriage_speed * math.sin(beta) if beta else 0.0
    p[P_OMEGA] = rig.omega
    p[P_DURATION] = rig.duration
    p[P_DT] = rig.dt
    p[P_DX] = rig.dx
    p[P_OUTEVERY] = rig.output_every
    p[P_TAPER] = 1.0 if rig.border_taper else 0.0
    p[P_BULLDOZE] = 1.0 if rig.bulldozing else 0.0
    p[P_SHEARDISP] = 1.0 if rig.shear == "displacement" else 0.0
    p[P_MAXSINK] = rig.max_sinkage
    p[P_MARGIN] = rig.side_margin
    p[P_OFF_F] = rig.offset_F
    p[P_OFF_T] = rig.offset_T
    p[P_OFF_Z] = rig.offset_z
    p[P_DYDX] = rig.dy_over_dx
    p[P_INCL] = soil.bearing_inclination
    p[P_PLOUGH] = soil.ploughing
    p[P_DIGMOB] = 1.0 if rig.drive_digging == "mobilised" else 0.0
    p[P_FACEPLOUGH] = 1.0 if rig.skid_ploughing == "sliding_face" else 0.0
    p[P_EROSIONEVERY] = rig.erosion_every
    p[P_SETTLE] = rig.steady_tolerance
    outer = envelope + p[P_HG]  # the kernel's zero of z: first contact of this radius
    p[P_ZDATUM] = outer - (wheel.R if rig.sinkage_datum == "rim" else wheel.R + h_g)
    p[P_SHEARSCALE] = (wheel.R + h_g) / wheel.R if rim_bearing else 1.0
    p[P_SLIPV] = _slip_velocity_scale(p[P_SHEARSCALE], wheel.R, rig) if rim_bearing else 1.0
    p[P_STUCKSOIL] = 1.0 if rig.stuck_shear == "soil" else 0.0
    p[P_POCKETKEEP] = 1.0 if rig.pocket_carry == "kept" else 0.0
    p[P_GAMMA] = soil.bulk_density * GRAVITY
    return p
