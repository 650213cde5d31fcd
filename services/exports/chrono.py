"""A calibrated soil as Chrono's SCM terrain takes it (``SCMTerrain::SetSoilParameters``).

Chrono (``chrono_vehicle/terrain/SCMTerrain.h``)::

    SetSoilParameters(Bekker_Kphi, Bekker_Kc, Bekker_n, Mohr_cohesion, Mohr_friction,
                      Janosi_shear, elastic_K, damping_R)
    SetBulldozingParameters(erosion_angle, flow_factor, ...)

Conversions (this tool's units on the left, Chrono's on the right):

* k_phi [N/m^(n+2)] = Bekker_Kphi [Pa/m^n]; k_c [N/m^(n+1)] = Bekker_Kc [Pa/m^(n-1)]; n = Bekker_n
  (the same numbers: 1 N/m^(n+2) is 1 Pa/m^n);
* c [Pa] = Mohr_cohesion [Pa]; phi [deg] = Mohr_friction [deg];
* J [m] = Janosi_shear [m] only in the displacement form of eq. (8) (``shear = "displacement"``):
  the velocity form's J [m/s] (SCM's, the paper's) has no length equivalent (the shear
  displacement a node accumulates depends on the test: slip velocity times contact time);
* K [Pa/m] = elastic_K [Pa/m], which Chrono requires to be above Bekker_Kphi;
* D_soil [N s/m^3] = damping_R [Pa s/m];
* repose_angle [deg] = erosion_angle [deg]; 1 - compaction = flow_factor (the displaced volume
  that flows out of the rut, relative to the pressed volume).

What Chrono cannot represent is refused (:class:`ChronoExportError`) unless ``lossy``, which
lists it as dropped: the velocity-form J, the inclination factor (``bearing_inclination`` > 0),
a skidding wheel's ploughing (``ploughing`` > 0, ``skid_ploughing = "sliding_face"``), the
bow wave's passive pressure (``bulk_density`` > 0), the mobilised-depth digging of a driven
wheel (``drive_digging = "mobilised"``) and the trapped soil of a grousered wheel
(``grouser_contact = "tip_circle"``), and a wheel surface whose friction is below the soil's
(``interface_friction`` < 1). The rim-dragged
layer (``shear_band``, ``slip_flow``) is this tool's flow model; Chrono's bulldozing has none.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

from scm_core.simulator import RigConfig, SoilParams

__all__ = [
    "ChronoExportError",
    "ChronoSoil",
    "chrono_soil",
    "cpp_call",
    "python_call",
    "soils_document",
]

#: Chrono's parameters in call order, with their units
SOIL_ARGS = (
    ("Bekker_Kphi", "Pa/m^n"),
    ("Bekker_Kc", "Pa/m^(n-1)"),
    ("Bekker_n", "-"),
    ("Mohr_cohesion", "Pa"),
    ("Mohr_friction", "deg"),
    ("Janosi_shear", "m"),
    ("elastic_K", "Pa/m"),
    ("damping_R", "Pa s/m"),
)


class ChronoExportError(ValueError):
    """The soil holds what Chrono's SCM cannot represent (one line naming it)."""


@dataclass(frozen=True)
class ChronoSoil:
    """Arguments of ``SetSoilParameters`` and ``SetBulldozingParameters`` (Chrono's units;
    ``Janosi_shear`` None when a velocity-form J was dropped)."""

    Bekker_Kphi: float
    Bekker_Kc: float
    Bekker_n: float
    Mohr_cohesion: float
    Mohr_friction: float
    Janosi_shear: float | None
    elastic_K: float
    damping_R: float
    erosion_angle: float
    flow_factor: float

    def to_dict(self) -> dict[str, float | None]:
        return asdict(self)


def _extensions(soil: SoilParams, rig: RigConfig) -> list[str]:
    """What of ``soil`` and ``rig`` Chrono's SCM has no counterpart for (besides J)."""
    out = []
    if soil.bearing_inclination > 0:
        out.append(f"bearing_inclination = {soil.bearing_inclination:g} (inclination factor)")
    if soil.ploughing > 0:
        out.append(f"ploughing = {soil.ploughing:g} (a skidding wheel's blade)")
    if soil.bulk_density > 0:
        out.append(
            f"bulk_density = {soil.bulk_density:g} kg/m^3 (the bow wave's passive pressure on "
            "the wheel)"
        )
    if rig.skid_ploughing == "sliding_face":
        out.append('skid_ploughing = "sliding_face" (a skidding wheel\'s dragged layer)')
    if rig.drive_digging == "mobilised":
        out.append('drive_digging = "mobilised" (a driven wheel digging in)')
    if soil.interface_friction < 1.0:
        delta = math.degrees(math.atan(soil.interface_friction * soil.tan_phi))
        out.append(
            f"interface_friction = {soil.interface_friction:g} (the rim's friction angle delta "
            f"{delta:.4g} deg; Chrono shears the soil at Mohr_friction on any wheel)"
        )
    if rig.grouser_contact != "faces":
        out.append(
            f'grouser_contact = "{rig.grouser_contact}" (soil trapped between grousers; in '
            "Chrono a grousered wheel's mesh presses with its grouser faces)"
        )
    return out


def chrono_soil(
    soil: SoilParams, rig: RigConfig, *, lossy: bool = False
) -> tuple[ChronoSoil, list[str]]:
    """(Chrono's soil, what was dropped) for ``soil`` under the model options of ``rig``;
    :class:`ChronoExportError` for what Chrono cannot take (see the module docstring)."""
    dropped = _extensions(soil, rig)
    janosi: float | None = soil.J
    if rig.shear != "displacement":
        janosi = None
        dropped.insert(
            0,
            f"J = {soil.J:g} m/s (velocity form of eq. (8); Chrono's Janosi_shear is a shear "
            "displacement in m, which you must choose)",
        )
    if dropped and not lossy:
        raise ChronoExportError(
            f"Chrono's SCM cannot represent {'; '.join(dropped)}: give --lossy to export the "
            "rest and list what was dropped"
        )
    if soil.k_phi >= soil.K:
        raise ChronoExportError(
            f"K = {soil.K:g} Pa/m is not above k_phi = {soil.k_phi:g}: Chrono requires "
            "elastic_K > Bekker_Kphi"
        )
    out = ChronoSoil(
        Bekker_Kphi=soil.k_phi,
        Bekker_Kc=soil.k_c,
        Bekker_n=soil.n,
        Mohr_cohesion=soil.c,
        Mohr_friction=soil.phi,
        Janosi_shear=janosi,
        elastic_K=soil.K,
        damping_R=soil.D_soil,
        erosion_angle=soil.repose_angle,
        flow_factor=1.0 - soil.compaction,
    )
    return out, dropped


_CHOOSE_J = (
    "janosi_shear [m]: not calibrated (the study used the velocity form of J, dropped): "
    "define it before these calls"
)


def _calls(s: ChronoSoil, terrain: str, comment: str, mark: str, end: str) -> str:
    """The two calls in a language whose line comments start with ``mark`` and whose
    statements end with ``end`` (a trailing comma after the last argument only where the
    language allows it: Python)."""
    values = s.to_dict()
    lines = []
    for k, (name, unit) in enumerate(SOIL_ARGS):
        v = values[name]
        text = "janosi_shear" if v is None else repr(float(v))
        comma = "," if k < len(SOIL_ARGS) - 1 or not end else " "
        lines.append(f"    {text}{comma}  {mark} {name} [{unit}]")
    head = f"{mark} {comment}\n" if comment else ""
    if s.Janosi_shear is None:
        head += f"{mark} {_CHOOSE_J}\n"
    body = "\n".join(lines)
    return (
        f"{head}{terrain}.SetSoilParameters(\n{body}\n){end}\n"
        f"{terrain}.SetBulldozingParameters({s.erosion_angle!r}, {s.flow_factor!r}){end}"
        f"  {mark} erosion_angle [deg], flow_factor [-]\n"
    )


def cpp_call(s: ChronoSoil, terrain: str = "terrain", comment: str = "") -> str:
    """The C++ calls for ``s`` (``janosi_shear`` a variable to define where J was dropped)."""
    return _calls(s, terrain, comment, "//", ";")


def python_call(s: ChronoSoil, terrain: str = "terrain", comment: str = "") -> str:
    """The PyChrono calls for ``s``."""
    return _calls(s, terrain, comment, "#", "")


def soils_document(
    sets: Mapping[str, ChronoSoil], dropped: Sequence[str], draws: Sequence[ChronoSoil] = ()
) -> dict:
    """The JSON block: each named set, the draws, the units and what was dropped."""
    return {
        "format": "scm-calib-chrono-soil",
        "version": 1,
        "units": {**dict(SOIL_ARGS), "erosion_angle": "deg", "flow_factor": "-"},
        "call": "SCMTerrain::SetSoilParameters(" + ", ".join(n for n, _ in SOIL_ARGS) + ")",
        "sets": {k: v.to_dict() for k, v in sets.items()},
        "draws": [d.to_dict() for d in draws],
        "dropped": list(dropped),
    }
