"""Bayesian inference core: priors, likelihoods, TMCMC, Morris screening, posterior summaries.

Pure numerics (numpy/scipy), no I/O. See :mod:`scm_core.inference.tmcmc_stage` for the stage
functions a distributed orchestrator calls step by step.
"""

from scm_core.inference.likelihood import (
    LIKELIHOODS,
    log_likelihood_gaussian,
    log_likelihood_normalized,
    standardized_residuals,
)
from scm_core.inference.morris import (
    MorrisDesign,
    MorrisResult,
    design_from_points,
    morris,
    morris_analyze,
    morris_design,
)
from scm_core.inference.posterior import (
    PosteriorSummary,
    credible_interval,
    kde_1d,
    kde_2d,
    map_sample,
    pool_samples,
    summarize,
    summarize_result,
)
from scm_core.inference.priors import (
    LOG_SCALE_KINDS,
    TABLE2_NOMINAL,
    JointPrior,
    LogNormal,
    LogUniform,
    TruncatedNormal,
    Uniform,
    distribution_from_dict,
    table2_prior,
)
from scm_core.inference.tmcmc import TMCMCResult, rowwise, run_tmcmc
from scm_core.inference.tmcmc_stage import (
    ChainBatchResult,
    StagePlan,
    StageState,
    TMCMCSettings,
    chain_batches,
    evaluate_points,
    initial_samples,
    initial_state,
    next_exponent,
    plan_stage,
    reduce_stage,
    run_chains,
    stage_status,
)

__all__ = [
    "LIKELIHOODS",
    "LOG_SCALE_KINDS",
    "TABLE2_NOMINAL",
    "ChainBatchResult",
    "JointPrior",
    "LogNormal",
    "LogUniform",
    "MorrisDesign",
    "MorrisResult",
    "PosteriorSummary",
    "StagePlan",
    "StageState",
    "TMCMCResult",
    "TMCMCSettings",
    "TruncatedNormal",
    "Uniform",
    "chain_batches",
    "credible_interval",
    "design_from_points",
    "distribution_from_dict",
    "evaluate_points",
    "initial_samples",
    "initial_state",
    "kde_1d",
    "kde_2d",
    "log_likelihood_gaussian",
    "log_likelihood_normalized",
    "map_sample",
    "morris",
    "morris_analyze",
    "morris_design",
    "next_exponent",
    "plan_stage",
    "pool_samples",
    "reduce_stage",
    "rowwise",
    "run_chains",
    "run_tmcmc",
    "stage_status",
    "standardized_residuals",
    "summarize",
    "summarize_result",
    "table2_prior",
]
