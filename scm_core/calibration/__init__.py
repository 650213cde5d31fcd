"""Calibration studies (paper sections 4-5): case definitions, the study likelihood over SWT
datasets, a progress-reporting TMCMC driver, Morris screening of the soil parameters, synthetic
lab logs and study summaries. Pure: no file I/O (the command line reads and writes files).
"""

from scm_core.inference.tmcmc import PopulationStart, Resume, StageHooks, StageStart, run_tmcmc

from .case import (
    CALIBRATABLE,
    RESPONSE_KEYS,
    SIGMA_NAMES,
    CaseDefinition,
    CaseError,
    DataSettings,
    PriorSpec,
    SamplerSettings,
    load_case,
)
from .model import DatasetTerms, StudyModel, build_configs, dataset_terms
from .presets import PRESETS, PresetCost, preset_case, preset_cost
from .report import stage_table, study_summary
from .sensitivity import (
    DEFAULT_BOUNDS,
    FACTOR_UNITS,
    TABLE1_PARAMETERS,
    MorrisModel,
    MorrisSettings,
    SensitivityDesign,
    SensitivityResult,
    analyze_sensitivity,
    run_sensitivity,
    screening_factors,
    sensitivity_design,
)
from .synthetic import NoiseModel, SyntheticError, SyntheticLog, synthesize_log
from .update import UpdateLikelihood

__all__ = [
    "CALIBRATABLE",
    "DEFAULT_BOUNDS",
    "FACTOR_UNITS",
    "PRESETS",
    "RESPONSE_KEYS",
    "SIGMA_NAMES",
    "TABLE1_PARAMETERS",
    "CaseDefinition",
    "CaseError",
    "DataSettings",
    "DatasetTerms",
    "MorrisModel",
    "MorrisSettings",
    "NoiseModel",
    "PopulationStart",
    "PresetCost",
    "PriorSpec",
    "Resume",
    "SamplerSettings",
    "SensitivityDesign",
    "SensitivityResult",
    "StageHooks",
    "StageStart",
    "StudyModel",
    "SyntheticError",
    "SyntheticLog",
    "UpdateLikelihood",
    "analyze_sensitivity",
    "build_configs",
    "dataset_terms",
    "load_case",
    "preset_case",
    "preset_cost",
    "run_sensitivity",
    "run_tmcmc",
    "screening_factors",
    "sensitivity_design",
    "stage_table",
    "study_summary",
    "synthesize_log",
]
