"""Named model classes: the simulator's physics options as a lab picks them, by one name.

A case's ``[simulator] model = NAME`` (``RigConfig.model``) sets each of the options below that
the case does not set itself; an option the case sets wins, so a variant of a class is the name
and the one line that differs. The options are the physics of docs/simulator.md; numerics
(grid, time step, averaging windows, early stop) and the lab's conventions (``sinkage_datum``)
are not part of a class. docs/simulator.md, "Model classes", tabulates them with the evidence.

* ``scm``: the paper's Soil Contact Model (Gallina et al., section 3; Chrono's SCMTerrain):
  Janosi & Hanamoto's shear in the slip velocity's form, grousers as faces in the z-buffer,
  the plastic flows of section 3.2 with the digging and ploughing of the SCM. The paper's
  presets are this class (the simulator's defaults).
* ``scm_flow``: the SCM with the soil a wheel drags flowing as the CMU wheels in dry sand show
  it, the class their log evidence favours (docs/cmu-record.md, "Model classes on the joint
  data"): shear in displacement (Janosi & Hanamoto 1961), a driven rim carrying off its layer
  where its shear is mobilised (slip sinkage), a skid ploughing what its sliding face meets,
  grousers that trap soil with the rim bearing (Wong & Reece 1967; Ding et al. 2011's
  shearing radius, at the rim's slip while driving), the soil shearing at phi where the rim
  sticks, and grouser pockets carrying off what they keep. No option adds a parameter beyond
  the soil's ``interface_friction``, ``pocket_fill`` and ``bulk_density`` where a case
  calibrates or states them.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

__all__ = ["MODEL_CLASSES", "MODEL_NAMES", "with_model_class"]

_SCM: dict[str, Any] = {
    "bulldozing": True,
    "border_taper": True,
    "shear": "velocity",
    "drive_digging": "thinning",
    "skid_ploughing": "kappa",
    "grouser_contact": "faces",
    "grouser_slip": "tips",
    "stuck_shear": "interface",
    "pocket_carry": "continuity",
}

#: name -> the RigConfig options the class sets (read-only)
MODEL_CLASSES: Mapping[str, Mapping[str, Any]] = MappingProxyType(
    {
        "scm": MappingProxyType(_SCM),
        "scm_flow": MappingProxyType(
            {
                **_SCM,
                "shear": "displacement",
                "drive_digging": "mobilised",
                "skid_ploughing": "sliding_face",
                "grouser_contact": "rim_bearing",
                "grouser_slip": "rim_drive",
                "stuck_shear": "soil",
                "pocket_carry": "kept",
            }
        ),
    }
)
MODEL_NAMES = tuple(MODEL_CLASSES)


def with_model_class(options: Mapping[str, Any]) -> dict[str, Any]:
    """``options`` (a rig's settings) with the options of its ``model`` class filled in where
    it does not set them; unchanged without a model or with an unknown name (the field's own
    validation names it)."""
    preset = MODEL_CLASSES.get(options.get("model"))
    if preset is None:
        return dict(options)
    return {**preset, **options}
