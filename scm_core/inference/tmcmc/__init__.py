"""Transitional MCMC (Ching & Chen 2007), one package:

* :mod:`.types`: the data (settings, a stage's population, plan and batch result);
* :mod:`.weights`: plausibility weights, resampling, the evidence and its variance;
* :mod:`.moves`: the move schemes (resample-move, leader, waste-free);
* :mod:`.evaluate`, :mod:`.steps`, :mod:`.chains`: a batch of Metropolis chains;
* :mod:`.stage0`, :mod:`.stage`: the stage functions; :mod:`.loop`: the stage loop;
* :mod:`.driver`: the in-memory driver :func:`run_tmcmc`, exported here.
"""

from scm_core.inference.tmcmc.driver import (
    PopulationStart,
    Resume,
    StageHooks,
    StageStart,
    TMCMCResult,
    result_of,
    rowwise,
    run_tmcmc,
)

__all__ = [
    "PopulationStart",
    "Resume",
    "StageHooks",
    "StageStart",
    "TMCMCResult",
    "result_of",
    "rowwise",
    "run_tmcmc",
]
