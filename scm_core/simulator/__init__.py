"""SCM single-wheel-test simulator (paper section 3; DESIGN.md section 3)."""

from .layout import STATUS_NAMES
from .params import RigConfig, SoilParams, WheelGeometry
from .swt import (
    BatchResult,
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
    "RigConfig",
    "SWTResult",
    "SoilParams",
    "SteadyMeans",
    "Terrain",
    "WheelGeometry",
    "pack_many",
    "simulate_batch",
    "simulate_packed",
    "simulate_swt",
    "warm_up",
]
