"""Synthetic lab logs: a simulated SWT dressed up as a measured one (no file I/O here).

:func:`synthesize_log` simulates a single-wheel test with known parameters for the length of a
real SWT (paper section 4.3: about 180 s), then

1. prepends the state at t = 0 (wheel at rest on the surface, no force);
2. adds a start-up transient: the drive spins up, so drawbar pull and torque follow the simulated
   signals times a smooth ramp sin^2(pi t / (2 t_ramp)) over the first ``ramp_s`` seconds
   (sinkage is the simulated one, its own transient);
3. resamples linearly to the lab rate (default 50 Hz) on a uniform time axis from 0 s;
4. adds sensor noise per channel: white Gaussian noise plus a low-frequency drift (an
   Ornstein-Uhlenbeck process of correlation time ``drift_time_s``, stationary from t = 0),
   all drawn from ``numpy.random.SeedSequence(seed)``, so a seed gives the same log.

A steered rig (``slip_angle``) also gives the lateral force Fy, whose noise is drawn after the
other channels' (a straight log's numbers do not change). The result carries the arrays, the test
conditions (metadata for :func:`scm_core.signals.write_log`) and the true parameters. The lab's
nominal radius in the metadata is the rig's ``slip_radius`` (the rim radius R of the truth may
differ: cases 2).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scm_core.signals.responses import RESPONSE_KEYS, keys_of
from scm_core.simulator import RigConfig, SoilParams, SWTResult, WheelGeometry, simulate_swt

__all__ = ["NoiseModel", "SyntheticError", "SyntheticLog", "synthesize_log"]

#: a straight log's channels in the order their noise is drawn, then a steered wheel's
STRAIGHT = (*keys_of(steered=False), "normal_force")
CHANNELS = (*STRAIGHT, *(k for k in RESPONSE_KEYS if k not in STRAIGHT))


class SyntheticError(ValueError):
    """The simulation behind a synthetic log failed (e.g. the wheel bottomed out)."""


@dataclass(frozen=True)
class NoiseModel:
    """Sensor noise per channel (SI: N, N m, m, N): white sd and drift sd.

    Defaults are typical of an SWT rig's force-torque sensor and sinkage potentiometer: a few N
    of white noise on F and Fy, 0.2 N m on T, 0.2 mm on z; drift of about 1 % of the steady
    values.
    ``scale`` multiplies every level (0: a noise-free log).
    """

    white: dict[str, float] = field(
        default_factory=lambda: {"F": 2.0, "T": 0.2, "z": 2.0e-4, "normal_force": 2.0, "Fy": 2.0}
    )
    drift: dict[str, float] = field(
        default_factory=lambda: {"F": 0.5, "T": 0.05, "z": 1.0e-4, "normal_force": 1.0, "Fy": 0.5}
    )
    drift_time_s: float = 30.0
    scale: float = 1.0

    def __post_init__(self) -> None:
        for label, levels in (("white", self.white), ("drift", self.drift)):
            unknown = set(levels) - set(CHANNELS)
            if unknown:
                raise ValueError(f"NoiseModel.{label}: unknown channel(s) {sorted(unknown)}")
            if any(not (math.isfinite(v) and v >= 0) for v in levels.values()):
                raise ValueError(f"NoiseModel.{label}: levels must be finite and >= 0")
        if not self.drift_time_s > 0:
            raise ValueError("NoiseModel.drift_time_s must be > 0")
        if not (math.isfinite(self.scale) and self.scale >= 0):
            raise ValueError("NoiseModel.scale must be finite and >= 0")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True, eq=False)
class SyntheticLog:
    """A synthetic SWT log: series in SI (t s, F N, T N m, z m, normal_force N, slip -; Fy N
    for a steered rig, else None), ``metadata`` (test conditions and provenance with the true
    parameters, ready for :func:`scm_core.signals.write_log`), ``truth`` (soil, wheel and rig
    dicts) and the clean simulation it was made from."""

    t: NDArray[np.float64]
    F: NDArray[np.float64]
    T: NDArray[np.float64]
    z: NDArray[np.float64]
    normal_force: NDArray[np.float64]
    slip: NDArray[np.float64]
    metadata: dict[str, Any]
    truth: dict[str, dict[str, Any]]
    simulation: SWTResult
    Fy: NDArray[np.float64] | None = None

    @property
    def rate_hz(self) -> float:
        return 1.0 / float(self.t[1] - self.t[0])


def _ramp(t: NDArray[np.float64], ramp_s: float) -> NDArray[np.float64]:
    if ramp_s <= 0:
        return np.ones_like(t)
    x = np.clip(t / ramp_s, 0.0, 1.0)
    return np.sin(0.5 * np.pi * x) ** 2


def _ou(rng: np.random.Generator, n: int, dt: float, tau: float, sd: float) -> NDArray:
    """Stationary Ornstein-Uhlenbeck samples (sd, correlation time tau) at spacing dt."""
    a = math.exp(-dt / tau)
    e = rng.standard_normal(n)
    out = np.empty(n)
    x = e[0]
    out[0] = x
    b = math.sqrt(1.0 - a * a)
    for i in range(1, n):
        x = a * x + b * e[i]
        out[i] = x
    return sd * out


def synthesize_log(
    soil: SoilParams | None = None,
    wheel: WheelGeometry | None = None,
    rig: RigConfig | None = None,
    *,
    duration: float = 180.0,
    rate_hz: float = 50.0,
    ramp_s: float = 5.0,
    noise: NoiseModel | None = None,
    seed: int = 0,
    name: str | None = None,
) -> SyntheticLog:
    """Simulate ``duration`` s of an SWT with known parameters and turn it into a lab log.

    ``rig``'s numerics (dt, dx) and conditions (W, kinematics, slip_radius) are used; its
    duration and averaging offsets are replaced (``duration``; offsets play no role here). The
    log's slip column holds the symmetric lab slip.
    Raises :class:`SyntheticError` if the run does not finish with status "ok".
    """
    soil = soil or SoilParams()
    wheel = wheel or WheelGeometry()
    rig = rig or RigConfig()
    noise = noise or NoiseModel()
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"'duration' must be > 0, got {duration!r}")
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"'rate_hz' must be > 0, got {rate_hz!r}")
    if int(seed) < 0:
        raise ValueError(f"'seed' must be >= 0, got {seed!r}")
    if rate_hz * duration < 10:
        raise ValueError("fewer than 10 samples: raise 'duration' or 'rate_hz'")
    sim_rig = rig.replace(duration=duration, offset_F=0.0, offset_T=0.0, offset_z=0.0)
    result = simulate_swt(soil, wheel, sim_rig)
    if not result.ok:
        raise SyntheticError(
            f"the simulation behind the synthetic log failed: {result.status} at "
            f"t = {float(result.series['t'][-1]) if result.series['t'].size else 0.0:g} s"
        )

    s = result.series
    t_sim = np.concatenate([[0.0], s["t"]])
    steered = bool(rig.slip_angle)
    channels = CHANNELS if steered else STRAIGHT
    clean = {ch: np.concatenate([[0.0], s[ch]]) for ch in channels}
    n = int(math.floor(duration * rate_hz + 1e-9)) + 1
    t = np.arange(n) / rate_hz
    ramp = _ramp(t, ramp_s)
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(int(seed))))
    out: dict[str, NDArray[np.float64]] = {}
    for ch in channels:
        x = np.interp(t, t_sim, clean[ch])
        if ch in ("F", "T"):
            x = x * ramp
        white = noise.scale * noise.white.get(ch, 0.0)
        drift = noise.scale * noise.drift.get(ch, 0.0)
        x = x + white * rng.standard_normal(n)
        x = x + _ou(rng, n, 1.0 / rate_hz, noise.drift_time_s, drift)
        out[ch] = x

    res = result.rig
    if rig.slip is not None:  # the slip as given, in its convention
        slip, convention = rig.slip, rig.slip_convention or "drive"
    elif res.slip >= 0:
        slip, convention = res.slip, "drive"
    else:
        slip, convention = res.slip_symmetric, "symmetric"
    conditions = {
        "W": rig.W,
        "slip": slip,
        "R": res.slip_radius,
        "b": wheel.b,
        "n_grousers": wheel.n_grousers,
        "grouser_height": wheel.grouser_height,
    }
    if convention != "drive" or slip < 0:
        conditions["slip_convention"] = convention
    if steered:
        conditions["slip_angle"] = rig.slip_angle
    if res.omega > 0:
        conditions["omega"] = res.omega
    else:
        conditions["carriage_speed"] = res.carriage_speed
    truth = {"soil": soil.model_dump(), "wheel": wheel.model_dump(), "rig": sim_rig.model_dump()}
    provenance = {
        "name": name or f"synthetic s={slip:g}",
        "soil": "synthetic",
        "generator": "scm_core.calibration.synthesize_log",
        "seed": int(seed),
        "true_parameters": {**truth["soil"], "R": wheel.R},
        "simulator_numerics": {"dt": res.dt, "dx": res.dx, "duration": duration},
        "noise": {**noise.to_dict(), "ramp_s": ramp_s, "rate_hz": rate_hz},
    }
    return SyntheticLog(
        t=t,
        F=out["F"],
        T=out["T"],
        z=out["z"],
        normal_force=out["normal_force"],
        slip=np.full(n, slip if convention == "symmetric" or slip >= 0 else res.slip_symmetric),
        metadata={**conditions, **provenance},
        truth=truth,
        simulation=result,
        Fy=out.get("Fy"),
    )
