"""Ready-made cases: the quick case (``examples/quick.toml``) and the paper's cases 1, 2a and 2b
(section 5, Table 2), with what a study of each costs.

:func:`preset_case` gives a preset as a :class:`~scm_core.calibration.case.CaseDefinition`
(``examples/quick.toml`` and ``examples/case1.toml`` ... are these with their data files);
:func:`preset_cost` the expected model runs and wall time of one study on two cores, from the
sampler's own plan of a stage and the measured cost of a run (``benchmarks/bench_presets.py``).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from scm_core.inference.priors import TABLE2_NOMINAL, table2_prior
from scm_core.inference.tmcmc.moves import move_of

from .case import CaseDefinition, CaseError

__all__ = ["PRESETS", "WF34_REFERENCE", "PresetCost", "preset_case", "preset_cost"]

#: bevameter measurements of WF34 (paper section 4.1), drawn on the figures
WF34_REFERENCE = {"k_star": 1.0e7, "n": 1.1, "phi": 30.0, "c": 0.0}

#: the quick case (``examples/quick.toml`` without its data): k_phi, n, phi and J with coarse,
#: short simulations (10 mm grid, 40 ms steps, 25 s runs) and fixed sigmas sized for the coarse
#: model's error; the study default's sampler
QUICK: dict[str, Any] = {
    "name": "quick",
    "seed": 7,
    "description": "Quick case: k_phi, n, phi, J on coarse 25 s runs (about a minute)",
    "likelihood": "gaussian",
    "parameters": {
        "k_phi": {"dist": "log_uniform", "lower": 1e6, "upper": 1e8, "unit": "N/m^(n+2)"},
        "n": {"dist": "normal", "mean": 1.1, "sd": 0.2, "lower": 0.8, "upper": 2.0, "unit": "-"},
        "phi": {
            "dist": "normal",
            "mean": 30.0,
            "sd": 5.7,
            "lower": 11.5,
            "upper": 37.3,
            "unit": "deg",
        },
        "J": {"dist": "uniform", "lower": 0.001, "upper": 0.02, "unit": "m/s"},
    },
    "nominal": {"k_c": 0.0, "sigma_F": 5.0, "sigma_T": 0.5, "sigma_z": 0.001},
    "simulator": {
        "duration": 25.0,
        "dx": 0.01,
        "dt": 0.04,
        "offset_F": 10.0,
        "offset_T": 10.0,
        "offset_z": 10.0,
    },
    "sampler": {"n_samples": 500},
    "data": {"offset": 40.0},
    "reference": {"k_star": 1.0e7, "n": 1.1, "phi": 30.0},
}


@dataclass(frozen=True)
class _Preset:
    """A preset: its seed and description (the paper's cases), or its whole case document
    (``doc``), and what its studies were measured to cost on two cores
    (``benchmarks/bench_presets.py``): ``stages`` after the prior's, ``share`` of the planned
    runs of a later stage that were made (a proposal outside the prior's support, or one early
    rejection turns down, costs no simulation) and ``run_s`` wall seconds per simulation."""

    description: str
    seed: int
    stages: int
    share: float
    run_s: float
    doc: dict[str, Any] | None = None


#: the presets, the quick one first (what the dashboard offers first). Measured 2026-12-06 on
#: two cores (bench_presets.py): quick at its 500 samples 6 stages, 2900 runs, 8.7 ms per
#: simulation; case 1 at 500 samples 6 stages, 2408 runs (64 % of the leader form's one run per
#: sample), 29 ms; cases 2a and 2b take case 1's (the same simulator settings and priors but R).
PRESETS: dict[str, _Preset] = {
    "quick": _Preset(QUICK["description"], QUICK["seed"], 6, 1.0, 0.0087, doc=QUICK),
    "1": _Preset("Gallina et al. case 1: k_c, k_phi, n, phi, J + sigmas", 1, 6, 0.64, 0.029),
    "2a": _Preset("Gallina et al. case 2a: k_c, k_phi, n, phi, R + sigmas", 2, 6, 0.64, 0.029),
    "2b": _Preset("Gallina et al. case 2b: as 2a, another seed", 3, 6, 0.64, 0.029),
}


def preset_case(case: str, data_files: tuple[str, ...] = ()) -> CaseDefinition:
    """The preset ``case`` with ``data_files``: "quick" (:data:`QUICK`), or the paper's case
    "1", "2a" or "2b": Table 2 priors and nominal values, 2000 samples per stage with leader
    moves (one model run per sample and stage, the paper's budget), the paper's simulator
    settings (50 s runs; offsets 20 s for F and T, 1 s for z; experimental offset 40 s) and
    the normalised likelihood eq. (12)-(15)."""
    key = str(case).strip()
    if key not in PRESETS:
        raise CaseError(f"unknown preset {case!r}; presets: {', '.join(PRESETS)}")
    preset = PRESETS[key]
    if preset.doc is not None:
        data = {**preset.doc["data"], "files": list(data_files)}
        return CaseDefinition.from_dict({**preset.doc, "data": data})
    prior = table2_prior(key)
    params = {}
    for entry in prior.to_dict()["parameters"]:
        entry = dict(entry)
        name = entry.pop("name")
        if entry["dist"] == "truncated_normal":
            entry["dist"] = "normal"
        params[name] = entry
    nominal = {k: v for k, v in TABLE2_NOMINAL.items() if k not in params}
    doc = {
        "name": f"case{key}",
        "seed": preset.seed,
        "description": preset.description,
        "likelihood": "normalized",
        "parameters": params,
        "nominal": nominal,
        "simulator": {"duration": 50.0, "offset_F": 20.0, "offset_T": 20.0, "offset_z": 1.0},
        "sampler": {"n_samples": 2000, "moves": "leader"},
        "data": {"files": list(data_files), "offset": 40.0},
        "reference": dict(WF34_REFERENCE),
    }
    return CaseDefinition.from_dict(doc)


@dataclass(frozen=True)
class PresetCost:
    """What one study of a preset is expected to cost: ``model_runs`` (likelihood
    evaluations) and ``minutes`` of wall time on two cores per dataset."""

    model_runs: int
    minutes: float

    def text(self) -> str:
        """E.g. "about 2,900 model runs, 25 s on 2 cores per dataset"."""
        seconds = self.minutes * 60.0
        shown = f"{self.minutes:.0f} min" if seconds >= 90 else f"{max(seconds, 1):.0f} s"
        return f"about {self.model_runs:,} model runs, {shown} on 2 cores per dataset"


def stage_runs(case: CaseDefinition) -> int:
    """Model runs of one stage after the first as the case's moves plan it (at the sampler's
    initial step count; an adapted resample-move stage may take more)."""
    settings = case.tmcmc_settings()
    move = move_of(settings.moves)
    n = case.sampler.n_samples
    parent = np.arange(move.resample_size(n, settings), dtype=np.int64)
    _, lengths = move.chains(parent, n, math.nan, settings)
    return int(np.sum(lengths))


@functools.cache  # the presets do not change: the dashboard's form asks on every load
def preset_cost(key: str, n_samples: int | None = None) -> PresetCost:
    """The expected cost of a study of preset ``key`` (:class:`PresetCost`), at its own
    samples per stage or ``n_samples``: the first stage's n runs plus the measured stages
    times the measured share of :func:`stage_runs`, at the measured seconds per simulation."""
    preset = PRESETS[key]
    case = preset_case(key)
    if n_samples is not None:
        case = case.with_changes(sampler={"n_samples": n_samples})
    n = case.sampler.n_samples
    runs = n + round(preset.stages * preset.share * stage_runs(case))
    return PresetCost(model_runs=runs, minutes=runs * preset.run_s / 60.0)
