"""Validated, immutable inputs of a single-wheel-test (SWT) simulation.

Three types, each defaulting to the set-up of Gallina et al. (paper section 4.1, Table 1):

* :class:`SoilParams`: the SCM soil parameters of Table 1 plus the elastic unloading modulus ``K``,
  the angle of repose and the two plastic-flow constants of section 3.2;
* :class:`WheelGeometry`: rigid rim with straight grousers;
* :class:`RigConfig`: the test rig (load, imposed slip and angular velocity) and the numerics.

All values are SI (m, N, s, Pa) except angles, which are in degrees.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from scm_core.slip import CONVENTION_HELP, SlipError, canonical_convention

from .models import MODEL_NAMES, with_model_class

GRAVITY = 9.81  # m/s^2


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", validate_default=True)

    def replace(self, **changes: Any):
        """A validated copy with some fields changed."""
        return type(self).model_validate({**self.model_dump(), **changes})


class SoilParams(_Frozen):
    """SCM soil parameters (paper Table 1, eq. (7)-(8)); defaults: WF34 quartz sand (sec. 4.1)."""

    n: float = Field(1.1, gt=0.0, le=5.0, description="Exponent of sinkage n [-] (eq. 7)")
    k_c: float = Field(0.0, description="Cohesive modulus k_c [N/m^(n+1)] (eq. 7)")
    k_phi: float = Field(1.0e7, description="Frictional modulus k_phi [N/m^(n+2)] (eq. 7)")
    c: float = Field(0.0, ge=0.0, description="Cohesion c [Pa] (eq. 8)")
    phi: float = Field(
        30.0, ge=0.0, lt=90.0, description="Angle of internal friction [deg] (eq. 8)"
    )
    D_soil: float = Field(
        0.0, ge=0.0, description="Areal damping coefficient D_soil [N s/m^3] (eq. 7, compressive)"
    )
    J: float = Field(
        0.001,
        gt=0.0,
        description="Janosi coefficient J: reference velocity [m/s] (eq. 8), or shear "
        "displacement [m] when RigConfig.shear == 'displacement'",
    )
    K: float = Field(5.0e7, gt=0.0, description="Elastic unloading/reloading modulus K [Pa/m]")
    repose_angle: float = Field(
        30.0, gt=0.0, lt=90.0, description="Angle of repose kept by erosion [deg] (section 3.2)"
    )
    compaction: float = Field(
        0.5,
        ge=0.0,
        le=1.0,
        description="Fraction of plastically displaced volume lost to compaction [-]; the rest "
        "flows out of the footprint (radial flow, section 3.2)",
    )
    shear_band: float = Field(
        0.002,
        ge=0.0,
        description="Thickness of soil dragged by the slipping rim [m]; the layer carried by the "
        "parallel flow is grouser_height + shear_band (section 3.2)",
    )
    slip_flow: float = Field(
        1.0,
        ge=0.0,
        le=1.0,
        description="Fraction of the rim's slip velocity at which that layer is carried once "
        "the shear is fully mobilised [-] (scaled by 1 - exp(-v_t/J), eq. (8))",
    )

    bearing_inclination: float = Field(
        0.0,
        ge=0.0,
        le=10.0,
        description="Exponent m of the inclination factor (1 - alpha/90 deg)^m that scales the "
        "Bekker yield stress when the soil's resultant force on the wheel is inclined by alpha "
        "from the vertical (Meyerhof 1953: m = 2); 0 = off, the paper's SCM",
    )

    ploughing: float = Field(
        0.0,
        ge=0.0,
        lt=1.0,
        description="Fraction of a skidding wheel's path above its lowest point that the front "
        "face pushes ahead as a blade, of the part the rim does not roll under (flux "
        "h (v - omega r) per width for a path of height h) [-]; taken from under the wheel "
        "like the dragged layer (bulldozing, Wong & Reece 1967 part II); 0 = off, the paper's "
        "SCM",
    )

    interface_friction: float = Field(
        1.0,
        gt=0.0,
        le=1.0,
        description="Friction of the soil on the wheel's surface relative to its internal "
        "friction, tan(delta) / tan(phi) [-]: the shear of eq. (8) on a rim or grouser face "
        "(and the friction cone of the sliding face); soil trapped between grousers "
        "(grouser_contact 'tip_circle', 'rim_bearing') shears on soil, at phi; 1 = SCM",
    )

    pocket_fill: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="How full the pockets between grousers leave a driven wheel's contact, "
        "between what continuity brings them (0: the ground's top layer h_g, accelerated to "
        "the rim speed, thins; dug depth h_g s_p) and full at every pass (1: net excavation "
        "h_g (omega r_p - v) per width and time) [-]; trapped soil only (grouser_contact "
        "'tip_circle' or 'rim_bearing')",
    )

    bulk_density: float = Field(
        0.0,
        ge=0.0,
        le=5000.0,
        description="Bulk density of the soil [kg/m^3], for the weight of the bow wave: the loose "
        "soil heaped ahead of the wheel resists with its Rankine passive pressure, its own "
        "wedge on the face above the ground (Bekker's bulldozing resistance with c = 0, "
        "0.5 K_p gamma h^2 per width, K_p at the angle of repose) and its weight as a "
        "surcharge on the face below (K_p gamma h, K_p at phi); 0 = weightless deposits, the "
        "paper's SCM",
    )

    @property
    def tan_phi(self) -> float:
        return math.tan(math.radians(self.phi))


class WheelGeometry(_Frozen):
    """Rigid wheel: rim radius R, width b, straight grousers (paper section 4.1)."""

    R: float = Field(0.125, gt=0.01, le=2.0, description="Rim radius R [m]")
    b: float = Field(0.112, gt=0.005, le=2.0, description="Wheel width b [m]")
    n_grousers: int = Field(12, ge=0, le=200, description="Number of straight grousers [-]")
    grouser_height: float = Field(0.009, ge=0.0, description="Grouser height h_g [m]")
    grouser_thickness: float = Field(0.002, gt=0.0, description="Grouser thickness [m]")

    @model_validator(mode="after")
    def _check(self) -> WheelGeometry:
        if self.grouser_height > 0.5 * self.R:
            raise ValueError("grouser_height must be at most half the rim radius R")
        if self.n_grousers > 0 and self.grouser_thickness >= 2 * math.pi * self.R / self.n_grousers:
            raise ValueError("grouser_thickness must be smaller than the grouser pitch 2*pi*R/N")
        return self

    @property
    def has_grousers(self) -> bool:
        return self.n_grousers > 0 and self.grouser_height > 0.0

    @property
    def outer_radius(self) -> float:
        """Radius of the grouser tips (the rim radius for a smooth wheel) [m]."""
        return self.R + (self.grouser_height if self.has_grousers else 0.0)


class RigConfig(_Frozen):
    """Single-wheel test rig and numerics.

    Kinematics: the carriage moves the axle at ``carriage_speed`` v, the wheel turns at ``omega``
    (0: locked), so the rim speed is omega * slip_radius. Any two of ``slip``, ``omega`` and
    ``carriage_speed`` fix the rig (see :func:`scm_core.slip.resolve_speeds`); a slip alone moves
    the faster of rim and carriage at 0.1 rad/s times the slip radius (the paper's set-up: slip
    0.2, omega 0.1 rad/s, v = 1 cm/s). ``slip`` is in ``slip_convention``: ``drive``
    (1 - v/(omega r), the default for slip >= 0) or ``symmetric`` ((omega r - v)/max(v, omega r),
    -1 = locked); a negative slip must name its convention. ``slip_radius`` (the lab's nominal
    radius; default: the rim radius R) defines slip, not the model's rigid radius, so that an
    identified R (cases 2) changes the effective slip as a flexible wheel would. The axle is free
    vertically and loaded by W through the mass m = W / g.

    Numerics left as None are derived from the wheel and the rig by :func:`resolve_rig` (the
    paper's 0.125 m wheel at 1 cm/s gets dx 5 mm, dt 20 ms, 50 s, offsets 20/20/1 s, max_sinkage
    0.1 m).
    """

    W: float = Field(315.0, gt=0.0, description="Normal load W [N]")
    slip: float | None = Field(
        None, lt=1.0, description="Imposed slip [-] in slip_convention (default 0.2)"
    )
    slip_convention: str | None = Field(
        None,
        description="'drive' (1 - v/(omega r)) or 'symmetric' ((omega r - v)/max(v, omega r)); "
        "needed for a negative slip",
    )
    omega: float | None = Field(None, ge=0.0, description="Wheel angular velocity [rad/s]")
    carriage_speed: float | None = Field(None, gt=0.0, description="Carriage speed v [m/s]")
    slip_radius: float | None = Field(
        None, gt=0.0, description="Radius defining slip [m]; default the rim radius R"
    )
    slip_angle: float = Field(
        0.0,
        ge=-90.0,
        le=90.0,
        description="Slip angle beta [deg] between the wheel's heading and the carriage's "
        "travel (0: straight; 90: dragged along its axle); the wheel then slides along its "
        "axle at v sin(beta), toward -y for beta > 0, and the soil pushes it back (Fy > 0)",
    )
    mass: float | None = Field(None, gt=0.0, description="Vertical mass [kg]; default W/g")
    duration: float | None = Field(
        None,
        gt=0.0,
        description="Simulated time [s]; default 4 r/v, in skid 4 r (1 + |s|)/v with s the "
        "symmetric slip (a locked wheel travels 8 r)",
    )
    dt: float | None = Field(
        None, gt=0.0, le=0.1, description="Time step [s] (implicit vertical step); derived"
    )
    dx: float | None = Field(
        None, ge=0.0005, le=0.05, description="DEM grid spacing [m]; default r/25"
    )
    dy_over_dx: float = Field(
        2.0,
        ge=0.25,
        le=10.0,
        description="Lateral grid spacing as a multiple of dx; the wheel surface does not vary "
        "across y, so y resolution only matters at the track's edges",
    )
    output_rate: float = Field(
        100.0, gt=0.0, description="Output sample rate [Hz]; at most one sample per step"
    )
    offset_F: float | None = Field(
        None, ge=0.0, description="Averaging offset for drawbar pull [s]; default 0.4 duration"
    )
    offset_T: float | None = Field(
        None, ge=0.0, description="Averaging offset for torque [s]; default 0.4 duration"
    )
    offset_z: float | None = Field(
        None,
        ge=0.0,
        description="Averaging offset for sinkage [s]; default offset_z_fraction * duration",
    )
    offset_z_fraction: float = Field(
        0.02,
        ge=0.0,
        lt=1.0,
        description="Default sinkage offset as a fraction of the duration: the paper's 1 s of "
        "50 s suits a wheel whose sinkage settles at once; 0.4 (the window of F and T) for "
        "one that digs in or skids",
    )
    steady_tolerance: float | None = Field(
        None,
        gt=0.0,
        lt=1.0,
        description="Stop a run once its steady means are settled: at a quarter, a half and "
        "three quarters of the averaging window of F and T, the run ends if each mean so far, "
        "extrapolated linearly to the whole window (from the difference of its two halves), "
        "moves by at most this fraction of W (F), W R (T) and R (z); None: average the whole "
        "window (the paper's set-up). An approximation: the case records it",
    )
    border_taper: bool = Field(True, description="Pressure border taper gamma_i of eq. (7)")
    bulldozing: bool = Field(True, description="Plastic soil flow and erosion (section 3.2)")
    shear: Literal["velocity", "displacement"] = Field(
        "velocity", description="Janosi form of eq. (8): velocity (SCM) or displacement"
    )
    drive_digging: Literal["thinning", "mobilised"] = Field(
        "thinning",
        description="How deep a driven wheel digs itself in through the layer its rim drags "
        "(section 3.2 flow fields, docs/simulator.md step 5): 'thinning' (the layer, "
        "accelerated to f u, thins by continuity: d f u / (v + f u)) or 'mobilised' (the "
        "layer is carried off to the fraction f of its depth where its shear is mobilised: "
        "d f; f = slip_flow times the mean mobilised shear of eq. (8))",
    )
    skid_ploughing: Literal["kappa", "sliding_face"] = Field(
        "kappa",
        description="What a skidding wheel's front face ploughs from under it (docs/simulator.md "
        "step 5): 'kappa' (the fraction SoilParams.ploughing of its path, 0 = off, the paper's "
        "SCM) or 'sliding_face' (no parameter: the soil met by the part of the face where the "
        "rim slides over the soil, outside the friction cone of angle phi, sets the depth of "
        "the layer a skidding rim drags instead of grouser height + shear_band)",
    )
    grouser_contact: Literal["faces", "tip_circle", "rim_bearing"] = Field(
        "faces",
        description="How grousers meet the soil (docs/simulator.md step 1): 'faces' (the grouser "
        "rectangles in the wheel's z-buffer, SCM; the paper's presets), 'tip_circle' (the "
        "soil between grousers is trapped and moves with the wheel, Wong & Reece's effective "
        "radius r + h_g: pressure and shear act on the circle through the grouser tips, and "
        "the trapped soil is carried backwards at the rim speed, digging a driven wheel in by "
        "continuity) or 'rim_bearing' (the thin grousers penetrate and the rim bears, its "
        "pressure carried through the trapped soil to the circle through the tips, where it "
        "shears: the rim's contact with the tips' slip velocity and moment arm, the pockets "
        "as in 'tip_circle'; Ding et al. 2011's shearing radius r + h_g); a smooth wheel is "
        "the same under all three",
    )
    grouser_slip: Literal["tips", "rim", "rim_drive"] = Field(
        "tips",
        description="With grouser_contact 'rim_bearing', the slip of the surface through the "
        "grouser tips over the soil below (docs/simulator.md step 1): 'tips' (the tips' own "
        "velocity, omega (r + h_g) - v at the bottom: the trapped soil slides over the ground "
        "even at zero rim slip), 'rim' (Ding et al. 2011, J. Terramechanics 48: shear "
        "displacement j = r_s [(theta_1 - theta) - (1 - s)(sin theta_1 - sin theta)] with "
        "r_s = r + h_g and s the rim's slip, i.e. the rim's slip velocity times r_s / r: the "
        "soil below the tips moves with them until the rim slips) or 'rim_drive' (that while "
        "driving, where Ding et al. measured it; in skid the rim's own slip velocity, so a "
        "locked wheel slides over the ground at the carriage speed, as a rigid body "
        "translating at v does whatever the radius of its shearing surface); ignored otherwise",
    )
    stuck_shear: Literal["interface", "soil"] = Field(
        "interface",
        description="What shears where the wheel's surface does not slide over the soil, i.e. "
        "where its velocity relative to the ground lies inside the friction cone of the "
        "rim-soil interface (tangential speed <= tan(delta) times the speed into the soil; "
        "docs/simulator.md step 2): 'interface' (the rim's own friction delta, as where it "
        "slides; SCM) or 'soil' (the soil there moves with the rim, a dead wedge as ahead of "
        "a skidding wheel or a blunt blade, and fails in the soil, at phi); the same unless "
        "SoilParams.interface_friction < 1",
    )
    pocket_carry: Literal["continuity", "kept"] = Field(
        "continuity",
        description="What a driven grousered wheel's pockets carry out of the contact "
        "(grouser_contact 'tip_circle' or 'rim_bearing'; docs/simulator.md step 1), per width "
        "and time with u_p the pockets' speed over the ground and f = SoilParams.pocket_fill: "
        "'continuity' (at least the trapped layer thinned by continuity, h_g u_p (f + (1 - f) "
        "v / (v + u_p)), up to full pockets) or 'kept' (only the soil the pockets keep as "
        "they leave the contact, h_g u_p f; what they spill falls back under the wheel); "
        "a smooth wheel is the same under both",
    )
    sinkage_datum: Literal["outer", "rim"] = Field(
        "outer",
        description="Where the reported sinkage z is zero: 'outer' (the axle height at which "
        "the wheel's outermost surface, the grouser tips, first touches the undisturbed "
        "surface; SCM's) or 'rim' (where the rim of radius R, measured to the grouser base, "
        "would touch it: z less the grouser height, as a rig reports it that logs every "
        "wheel's axle from one datum set for the rim radius); a smooth wheel is the same "
        "under both",
    )
    max_sinkage: float | None = Field(
        None,
        gt=0.0,
        description="Sinkage that counts as bottomed out [m]; default min(0.1 m, outer radius), "
        "at a slip angle min(0.1 m, outer diameter)",
    )
    side_margin: float = Field(0.04, ge=0.0, description="Soil beside the wheel track [m]")
    model: Literal[MODEL_NAMES] | None = Field(  # type: ignore[valid-type]
        None,
        description="Named model class (scm_core.simulator.models; docs/simulator.md, 'Model "
        "classes'): sets the physics options above that are not given ('scm': the paper's SCM, "
        "the defaults; 'scm_flow': the soil a wheel drags flowing, favoured on the CMU wheels)",
    )

    @model_validator(mode="before")
    @classmethod
    def _model_class(cls, data: Any) -> Any:
        return with_model_class(data) if isinstance(data, Mapping) else data

    @model_validator(mode="after")
    def _check(self) -> RigConfig:
        if self.slip_convention is not None:
            try:
                canonical = canonical_convention(self.slip_convention)
            except SlipError as exc:
                raise ValueError(str(exc)) from None
            object.__setattr__(self, "slip_convention", canonical)
        if self.slip is not None and self.slip < 0.0 and self.slip_convention is None:
            raise ValueError(
                f"slip {self.slip:g} is negative (a skidding wheel) but its convention is not "
                f"named: set slip_convention to {CONVENTION_HELP}"
            )
        if self.duration is not None:
            offsets = [o for o in (self.offset_F, self.offset_T, self.offset_z) if o is not None]
            if offsets and self.duration <= max(offsets):
                raise ValueError(
                    f"duration {self.duration:g} s is not longer than the averaging offset "
                    f"{max(offsets):g} s: the steady window would be empty"
                )
            if self.dt is not None and self.dt > self.duration / 10:
                raise ValueError("dt must be at most a tenth of the duration")
        return self

    @property
    def vertical_mass(self) -> float:
        return self.mass if self.mass is not None else self.W / GRAVITY
