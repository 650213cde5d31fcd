"""Public entry points: one SWT (:func:`simulate_swt`) and many (:func:`simulate_batch`)."""

from __future__ import annotations

import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numba
import numpy as np

from . import kernel, outputs
from .jit_cache import ensure_fresh_cache
from .layout import P_V, STATUS_NAMES, STATUS_OK, pack_resolved
from .params import RigConfig, SoilParams, WheelGeometry
from .rig import ResolvedRig, resolve_rig


@dataclass(frozen=True)
class SteadyMeans:
    """Steady means over the averaging windows (paper section 4.3), as
    :func:`outputs.steady_means` gives them (the fields in the order of
    :data:`scm_core.signals.responses.RESPONSES`)."""

    F: float  # drawbar pull [N]
    T: float  # driving torque [N m]
    z: float  # sinkage [m]
    Fy: float = 0.0  # lateral force along the axle [N] (a steered wheel), F's window


@dataclass(frozen=True)
class ForceBudget:
    """Where the steady drawbar pull and lateral force come from [N], means over F's window
    (the output series' columns ``outputs.S_F_NORMAL`` .. ``S_P_COMPACTION``): F = F_normal +
    F_shear + F_cap + F_heap, Fy = Fy_shear + Fy_side (to rounding). F_normal: eq. (9)'s
    normal stresses along the heading (compaction and bulldozing resistance on the rim's
    faces, with the heap's surcharge on the front); F_shear: its shear stresses (eq. (8):
    thrust, or a skid's drag); F_cap: the Coulomb cap's cut of the thrust (Micklethwaite's
    c A + W tan(phi)), <= 0; F_heap: the bow wave's own wedge on the rim (``bulk_density`` >
    0), <= 0; Fy_shear: the shear along the axle; Fy_side: the leading side's passive force
    (a steered wheel, side.py).

    And the energy the soil's compaction takes: ``compaction_power`` [W], the plastic work done
    on the nodes per second (each yielding node's stress times its plastic sinkage's
    increment). The normal stresses pay for it where they push against the motion: a wheel
    driven straight and pressing soil only (no flows) has -F_normal v close to it
    (:attr:`compaction_paid`, docs/simulator.md, "The force budget")."""

    F_normal: float
    F_shear: float
    F_cap: float
    F_heap: float
    Fy_shear: float
    Fy_side: float
    compaction_power: float = 0.0
    #: the carriage's velocity along the heading [m/s] (the power of F_normal is F_normal v)
    v_heading: float = 0.0

    @classmethod
    def from_window(cls, parts: np.ndarray, Fy: float, v_heading: float) -> ForceBudget:
        """From :func:`outputs.budget_means`, the steady lateral force and the carriage's
        velocity along the heading [m/s]."""
        normal, shear, cap, heap, side, power = map(float, parts)
        return cls(normal, shear, cap, heap, Fy - side, side, power, v_heading)

    @property
    def compaction_paid(self) -> float:
        """The share of the compaction's energy the normal stresses along the heading pay,
        -F_normal v / compaction_power [-] (NaN without compaction)."""
        if self.compaction_power <= 0.0:
            return float("nan")
        return -self.F_normal * self.v_heading / self.compaction_power


@dataclass(frozen=True)
class Terrain:
    """Final DEM: x (nx,) and y (ny,) node coordinates [m], heights h (nx, ny) [m]."""

    x: np.ndarray
    y: np.ndarray
    h: np.ndarray


@dataclass(frozen=True)
class SWTResult:
    """Outcome of one simulated single-wheel test.

    ``series`` has the keys t [s], F [N] (drawbar pull, + forward), T [N m] (driving torque),
    z [m] (sinkage), normal_force [N], slip [-] (symmetric convention (omega r - v)/max(v, omega r),
    equal to 1 - v/(omega r) when driving), b_eff [m], Fy [N] (lateral force along the axle,
    + for a wheel sliding toward -y: RigConfig.slip_angle > 0). ``means`` is None unless
    status == "ok".
    ``rig`` is the resolved rig (kinematics, both slips, numerics). ``budget``: the steady
    forces by mechanism (None unless status == "ok").
    """

    status: str
    series: dict[str, np.ndarray]
    means: SteadyMeans | None
    terrain: Terrain
    wall_time_s: float
    rig: ResolvedRig
    diagnostics: dict[str, float] = field(default_factory=dict)
    budget: ForceBudget | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def simulate_swt(
    soil: SoilParams | None = None,
    wheel: WheelGeometry | None = None,
    rig: RigConfig | None = None,
) -> SWTResult:
    """Simulate a single-wheel test with SCM (paper section 3); defaults give the paper's SWT."""
    soil = soil or SoilParams()
    wheel = wheel or WheelGeometry()
    rig = rig or RigConfig()
    resolved = resolve_rig(wheel, rig)
    prm = pack_resolved(soil, wheel, resolved)
    ensure_fresh_cache()
    t0 = time.perf_counter()
    series, n_out, status, h, diag = kernel.run_swt(prm)
    means_arr = outputs.steady_means(series, prm)
    wall = time.perf_counter() - t0
    status_name = STATUS_NAMES[status]
    means = SteadyMeans(*map(float, means_arr)) if status == STATUS_OK else None
    budget = (
        ForceBudget.from_window(outputs.budget_means(series, prm), means.Fy, float(prm[P_V]))
        if means
        else None
    )
    d = {name: float(diag[i]) for i, name in enumerate(_DIAG_NAMES)}
    dy = d["dy"]
    ny = h.shape[1]
    jw0 = int(d["jw0"])
    y = (np.arange(ny) - jw0 - 0.5 * d["nyw"] + 0.5) * dy
    x = d["x0"] + np.arange(h.shape[0]) * resolved.dx
    out = {
        "t": series[:, outputs.S_T].copy(),
        "F": series[:, outputs.S_F].copy(),
        "T": series[:, outputs.S_TORQUE].copy(),
        "z": series[:, outputs.S_Z].copy(),
        "normal_force": series[:, outputs.S_FN].copy(),
        "slip": np.full(n_out, resolved.slip_symmetric),
        "b_eff": series[:, outputs.S_BEFF].copy(),
        "Fy": series[:, outputs.S_FY].copy(),
    }
    return SWTResult(
        status=status_name,
        series=out,
        means=means,
        terrain=Terrain(x=x, y=y, h=h),
        wall_time_s=wall,
        rig=resolved,
        diagnostics=d,
        budget=budget,
    )


_DIAG_NAMES = (
    "steps",
    "node_steps",
    "patch_steps",
    "contact_evaluations",
    "compacted_volume",
    "volume_initial",
    "volume_final",
    "dy",
    "x0",
    "jw0",
    "nyw",
    "erosion_visits",
    "volume_spilled",
    "cycles_geometry",
    "cycles_solve",
    "cycles_commit",
    "cycles_flow",
    "cycles_erosion",
    "bow_wave_height",
    "bow_wave_force",
)


@dataclass(frozen=True)
class BatchResult:
    """Steady means (n, outputs.N_MEANS) = F [N], T [N m], z [m], Fy [N] (NaN where status !=
    'ok'; :class:`SteadyMeans`'s fields) and statuses."""

    means: np.ndarray
    status: list[str]
    wall_time_s: float

    @property
    def ok(self) -> np.ndarray:
        return np.array([s == "ok" for s in self.status])


def pack_many(
    soils: Sequence[SoilParams],
    wheels: Sequence[WheelGeometry] | WheelGeometry | None = None,
    rigs: Sequence[RigConfig] | RigConfig | None = None,
) -> np.ndarray:
    """Parameter matrix (one row per run); a single wheel or rig is shared by all runs."""
    n = len(soils)
    wheels = _broadcast(wheels if wheels is not None else WheelGeometry(), n, "wheels")
    rigs = _broadcast(rigs if rigs is not None else RigConfig(), n, "rigs")
    return np.stack(
        [
            pack_resolved(s, w, resolve_rig(w, r))
            for s, w, r in zip(soils, wheels, rigs, strict=True)
        ]
    )


def simulate_batch(
    soils: Sequence[SoilParams],
    wheels: Sequence[WheelGeometry] | WheelGeometry | None = None,
    rigs: Sequence[RigConfig] | RigConfig | None = None,
) -> BatchResult:
    """Run many SWTs in one call on ``numba.get_num_threads()`` threads (``numba.set_num_threads``
    limits them; the embedded runtime and the Celery workers run one thread per process)."""
    prms = pack_many(soils, wheels, rigs)
    return simulate_packed(prms)


def _run_row(prm: np.ndarray) -> tuple[np.ndarray, int]:
    """Steady means (NaN unless ok) and status of one packed run (the kernel releases the GIL)."""
    series, _, status, _, _ = kernel.run_swt(prm)
    if status != STATUS_OK:
        return np.full(outputs.N_MEANS, np.nan), int(status)
    return outputs.steady_means(series, prm), int(status)


def simulate_packed(prms: np.ndarray) -> BatchResult:
    """:func:`simulate_batch` on an already packed parameter matrix.

    The rows run on ``numba.get_num_threads()`` threads, one row per task in order of the rows
    (runs differ in cost up to a hundredfold, so rows are handed out as threads come free); each
    row's result is its own, whatever the thread count. Threads over the single-run kernel, not a
    numba ``prange`` loop: the parallel loop took a second compile of the whole kernel (12 s).
    """
    ensure_fresh_cache()
    rows = np.ascontiguousarray(prms, dtype=np.float64)
    threads = min(numba.get_num_threads(), len(rows))
    t0 = time.perf_counter()
    if threads <= 1:
        out = [_run_row(row) for row in rows]
    else:
        with ThreadPoolExecutor(max_workers=threads) as pool:
            out = list(pool.map(_run_row, rows))
    wall = time.perf_counter() - t0
    means = np.array([m for m, _ in out]).reshape(len(rows), outputs.N_MEANS)
    return BatchResult(means=means, status=[STATUS_NAMES[s] for _, s in out], wall_time_s=wall)


def warm_up() -> float:
    """Load the compiled batch kernel (from numba's disk cache, or compile it) with a ten-step
    run, so that the first real batch starts at once; returns the seconds it took."""
    t0 = time.perf_counter()
    rig = RigConfig(duration=0.2, dt=0.02, offset_F=0.0, offset_T=0.0, offset_z=0.0)
    simulate_batch([SoilParams()], rigs=rig)
    return time.perf_counter() - t0


def _broadcast(item, n: int, name: str) -> list:
    if isinstance(item, WheelGeometry | RigConfig):
        return [item] * n
    items = list(item)
    if len(items) != n:
        raise ValueError(f"{name}: expected {n} entries, got {len(items)}")
    return items
