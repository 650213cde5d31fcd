"""The size of one run before it is made: time steps, DEM cells and output samples.

What a service checks against its limits before it accepts a study (a run's time is about
proportional to steps x contact cells, its memory to the DEM cells).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kernel import grid_shape
from .layout import P_DT, P_DURATION, P_OUTEVERY


@dataclass(frozen=True)
class RunSize:
    steps: int  # time steps: duration / dt, as the kernel counts them
    grid_cells: int  # DEM nodes nx * ny (each holds several float64 fields)
    output_samples: int  # recorded samples: steps / output_every


def run_size(prm: np.ndarray) -> RunSize:
    """Size of the run of a packed parameter row (:func:`scm_core.simulator.layout.pack`);
    pure Python, nothing is allocated or compiled."""
    nx, ny = grid_shape.py_func(prm)[:2]
    steps = int(round(prm[P_DURATION] / prm[P_DT]))
    every = max(1, int(prm[P_OUTEVERY]))
    return RunSize(steps=steps, grid_cells=int(nx) * int(ny), output_samples=steps // every)
