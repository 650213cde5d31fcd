"""The rig and numerics of one run, resolved from :class:`RigConfig` and the wheel.

Kinematics (:func:`scm_core.slip.resolve_speeds`): any two of slip, omega and carriage speed fix
the run; a slip alone moves the faster of rim and carriage at ``PAPER_OMEGA`` times the slip
radius r (the paper: omega 0.1 rad/s, slip 0.2, v = 1 cm/s).

Numerics left unset scale with the wheel and the rig as the paper's set-up does (r = 0.125 m,
v = 1 cm/s: dx 5 mm, dt 20 ms, 50 s, offsets 20, 20 and 1 s), rounded to three significant digits:

* dx = r / 25 (five grid cells per 2.5 % of the radius; convergence tables in docs/simulator.md);
* dt: the carriage advances at most dx / 10 per step, and with grouser faces the rim at most dx / 20
  (a grouser must not jump across cells); a smooth rim's angle does not enter the contact, and
  its flows are fluxes per unit time, so only the carriage limits it;
* duration = 4 r / v (the carriage travels two wheel diameters); in skid 4 r (1 + |s|) / v with s
  the symmetric slip, as the bow wave and the slip sinkage build over a longer travel the harder
  the wheel skids (a locked wheel travels 8 r: docs/simulator.md); offsets 0.4 duration for F and
  T, ``offset_z_fraction`` (default 0.02) of it for z (the paper's 20, 20 and 1 s of a 50 s run);
* max_sinkage = min(0.1 m, outer radius): beyond the outer radius the axle would be below the
  undisturbed surface and soil would reach the wheel's upper half, which the z-buffer of the lower
  surface does not model. A steered wheel's leading side is the whole disc below the soil
  (:mod:`.side`, up to the disc's upper edge), and a wheel dragged along its axle digs a trench
  deeper than its radius (the CMU wheels at 90 deg: 62-88 mm on a 58 mm rim), so at a slip
  angle min(0.1 m, the outer diameter); what is still not modelled there is the upper front
  quadrant meeting soil along the heading.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from scm_core.slip import SlipError, drive_to_symmetric, resolve_speeds

from .params import RigConfig, WheelGeometry

PAPER_OMEGA = 0.1  # rad/s: default angular speed of the faster of rim and carriage (per r)
CELLS_PER_RADIUS = 25.0
CARRIAGE_CELL_FRACTION = 10.0  # steps per cell of carriage travel
RIM_CELL_FRACTION = 20.0  # steps per cell of rim travel (grousered wheels)
TRAVEL_RADII = 4.0  # duration: carriage travel in slip radii
OFFSET_FT = 0.4  # averaging offsets as fractions of the duration
MAX_SINKAGE_CAP = 0.1  # m


def _sig3(x: float) -> float:
    return float(f"{x:.3g}")


@dataclass(frozen=True)
class ResolvedRig:
    """Every number one run uses (SI): kinematics, both slips and the numerics."""

    W: float
    mass: float
    carriage_speed: float
    rim_speed: float
    omega: float
    slip_radius: float
    slip: float  # drive convention 1 - v/(omega r); -inf for a locked wheel
    slip_symmetric: float  # (omega r - v)/max(v, omega r)
    duration: float
    dt: float
    dx: float
    dy_over_dx: float
    output_rate: float
    output_every: int
    erosion_every: int  # steps between erosion passes
    steady_tolerance: float  # early stop of a settled run (fraction of W, W R, R; 0: off)
    offset_F: float
    offset_T: float
    offset_z: float
    max_sinkage: float
    side_margin: float
    border_taper: bool
    bulldozing: bool
    shear: str
    drive_digging: str
    skid_ploughing: str
    grouser_contact: str
    sinkage_datum: str
    grouser_slip: str
    stuck_shear: str
    pocket_carry: str
    slip_angle: float = 0.0  # [deg] between heading and travel

    def to_dict(self) -> dict:
        """JSON-compatible dict (a locked wheel's drive slip as None)."""
        out = asdict(self)
        if math.isinf(self.slip):
            out["slip"] = None
        return out


def resolve_rig(wheel: WheelGeometry, rig: RigConfig) -> ResolvedRig:
    """Resolve ``rig`` for ``wheel``; raises ValueError (one line, naming the field) if the
    kinematics are inconsistent or the derived numerics leave no averaging window."""
    r = rig.slip_radius if rig.slip_radius is not None else wheel.R
    rim_given = None if rig.omega is None else rig.omega * r
    try:
        v, v_rim, s_drive = resolve_speeds(
            rig.slip, rig.slip_convention, rig.carriage_speed, rim_given, PAPER_OMEGA * r
        )
    except SlipError as exc:
        raise ValueError(f"slip, omega, carriage_speed: {exc}") from None
    dx = rig.dx if rig.dx is not None else _sig3(r / CELLS_PER_RADIUS)
    s_sym = drive_to_symmetric(s_drive)
    if rig.duration is not None:
        duration = rig.duration
    else:
        duration = _sig3(TRAVEL_RADII * (1.0 + max(0.0, -s_sym)) * r / v)
    dt_carriage = dx / (CARRIAGE_CELL_FRACTION * v)
    if rig.dt is not None:
        dt = rig.dt
    else:
        dt = dt_carriage
        if wheel.has_grousers and rig.grouser_contact == "faces" and v_rim > 0.0:
            dt = min(dt, dx / (RIM_CELL_FRACTION * v_rim))
        dt = _sig3(min(dt, 0.1, duration / 10.0))
    off_F = rig.offset_F if rig.offset_F is not None else _sig3(OFFSET_FT * duration)
    off_T = rig.offset_T if rig.offset_T is not None else _sig3(OFFSET_FT * duration)
    off_z = rig.offset_z if rig.offset_z is not None else _sig3(rig.offset_z_fraction * duration)
    longest = max(off_F, off_T, off_z)
    if duration <= longest:
        raise ValueError(
            f"duration: {duration:g} s is not longer than the averaging offset {longest:g} s: "
            "the steady window would be empty"
        )
    if dt > duration / 10:
        raise ValueError(f"dt: {dt:g} s is more than a tenth of the duration {duration:g} s")
    if rig.max_sinkage is not None:
        max_sink = rig.max_sinkage
    elif rig.slip_angle == 0.0:
        max_sink = min(MAX_SINKAGE_CAP, wheel.outer_radius)
    else:  # a steered wheel's side is a disc (side.py): it may dig in to its diameter
        max_sink = min(MAX_SINKAGE_CAP, 2.0 * wheel.outer_radius)
    return ResolvedRig(
        W=rig.W,
        mass=rig.vertical_mass,
        carriage_speed=v,
        rim_speed=v_rim,
        omega=v_rim / r,
        slip_radius=r,
        slip=s_drive,
        slip_symmetric=s_sym,
        duration=duration,
        dt=dt,
        dx=dx,
        dy_over_dx=rig.dy_over_dx,
        output_rate=rig.output_rate,
        output_every=max(1, round(1.0 / (rig.output_rate * dt))),
        erosion_every=max(1, int(dt_carriage / dt + 1e-9)),
        steady_tolerance=rig.steady_tolerance or 0.0,
        offset_F=off_F,
        offset_T=off_T,
        offset_z=off_z,
        max_sinkage=max_sink,
        side_margin=rig.side_margin,
        border_taper=rig.border_taper,
        bulldozing=rig.bulldozing,
        shear=rig.shear,
        drive_digging=rig.drive_digging,
        skid_ploughing=rig.skid_ploughing,
        grouser_contact=rig.grouser_contact,
        sinkage_datum=rig.sinkage_datum,
        grouser_slip=rig.grouser_slip,
        stuck_shear=rig.stuck_shear,
        pocket_carry=rig.pocket_carry,
        slip_angle=rig.slip_angle,
    )
