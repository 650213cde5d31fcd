"""SCM single-wheel-test simulator (paper section 3; DESIGN.md section 3)."""

from .layout import STATUS_NAMES
from .params import RigConfig, SoilParams, WheelGeometry
from .rig import ResolvedRig, resolve_rig
from .swt import (
    BatchResult,
    ForceBudget,
    SteadyMeans,
    SWTResult,
    Terrain,
    pack_many,
    simulate_batch,
    simulate_packed,
    simulate_swt,
    warm_up,
)

__all__ = [
    "STATUS_NAMES",
    "BatchResult",
    "ForceBudget",
    "ResolvedRig",
    "RigConfig",
    "SWTResult",
    "SoilParams",
    "SteadyMeans",
    "Terrain",
    "WheelGeometry",
    "pack_many",
    "resolve_rig",
    "simulate_batch",
    "simulate_packed",
    "simulate_swt",
    "warm_up",
]
