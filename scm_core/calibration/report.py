"""JSON-ready summaries of a finished (or stopped) calibration study (pure, no file I/O)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scm_core.inference.posterior import credible_interval, summarize_result
from scm_core.inference.tmcmc import TMCMCResult
from scm_core.jsondoc import finite_or_none

from .case import RESPONSE_KEYS, CaseDefinition
from .model import StudyModel

__all__ = ["not_a_posterior", "stage_table", "study_summary"]

#: what to do about a run that stopped before the posterior, by status
_NEXT = {
    "max_stages": "re-run the same command with a larger --max-stages to go on",
    "stalled": "the tempering exponent stopped increasing (see summary.json's stages)",
    "cancelled": "the study was cancelled",
}


def not_a_posterior(status: str, exponent: float | None) -> str:
    """A one-line warning for a run that ended before the posterior ("" if it completed):
    its samples are those of the tempered target prior x L^p with p < 1."""
    if status == "completed":
        return ""
    p = "?" if exponent is None else f"{exponent:.3g}"
    why = _NEXT.get(status, f"status {status}")
    return (
        f"NOT A POSTERIOR: the run ended '{status}' at tempering exponent p = {p} < 1, so the "
        f"samples are of prior x L^p; {why}"
    )


def _by_name(names: Sequence[str], values: NDArray[np.float64]) -> dict[str, float | None]:
    return {n: finite_or_none(v) for n, v in zip(names, values, strict=True)}


def stage_table(
    result: TMCMCResult, wall_times: Sequence[float] | None = None
) -> list[dict[str, Any]]:
    """One row per stage: stage, exponent, beta, acceptance, ESS, unique samples, model runs,
    failed runs (and by reason), proposals outside the support, part runs (simulator runs),
    early rejections, part runs saved, log evidence so far, wall time [s]."""
    rows = []
    for i, row in enumerate(result.diagnostics()):
        out = {k: (int(v) if isinstance(v, int) else finite_or_none(v)) for k, v in row.items()}
        out["failed_by"] = result.stages[i].failed_by.to_dict()
        if wall_times is not None and i < len(wall_times):
            out["wall_time_s"] = finite_or_none(wall_times[i])
        rows.append(out)
    return rows


def study_summary(
    result: TMCMCResult,
    case: CaseDefinition,
    model: StudyModel,
    wall_times: Sequence[float] | None = None,
    extra_settings: dict[str, Any] | None = None,
    map_responses: dict[str, dict[str, float | None]] | None = None,
) -> dict[str, Any]:
    """Posterior summary (mean, sd, quantiles, 95 % interval, correlations, MAP), evidence,
    per-stage diagnostics, totals, settings and datasets, as one JSON-compatible dict."""
    names = result.names
    post = summarize_result(result)
    ci = credible_interval(result.samples, 0.95)
    settings = {
        "n_samples": int(result.final.n_samples),
        "seed": int(case.seed),
        "likelihood": case.likelihood,
        "responses": list(case.responses),
        "tmcmc": case.tmcmc_settings().to_dict(),
        **(extra_settings or {}),
    }
    datasets = []
    for k, d in enumerate(model.datasets):
        datasets.append(
            {
                "name": d.name,
                "content_hash": d.content_hash,
                "conditions": d.conditions,
                "means": {
                    r: finite_or_none(x) for r, x in zip(RESPONSE_KEYS, model.x_exp[k], strict=True)
                },
                "standard_errors": {
                    r: finite_or_none(x)
                    for r, x in zip(RESPONSE_KEYS, d.standard_errors, strict=True)
                },
            }
        )
    summary: dict[str, Any] = {
        "format": "scm-calib-study-summary",
        "version": 1,
        "case": case.to_dict(),
        "case_hash": case.fingerprint(),
        "status": result.status,
        "parameters": list(names),
        "units": dict(case.prior().units or {}),
        "posterior": {
            "mean": _by_name(names, post.mean),
            "sd": _by_name(names, post.sd),
            "quantiles": {
                f"{q:g}": _by_name(names, post.quantiles[i])
                for i, q in enumerate(post.quantile_levels)
            },
            "credible_interval_95": {
                n: [finite_or_none(ci[j, 0]), finite_or_none(ci[j, 1])] for j, n in enumerate(names)
            },
            "correlation": {
                "names": list(names),
                "matrix": [[finite_or_none(v) for v in row] for row in post.correlation],
            },
            "map": None if post.map_sample is None else _by_name(names, post.map_sample),
            "map_log_posterior": finite_or_none(post.map_log_posterior),
            "n_unique": int(result.final.n_unique),
        },
        "log_evidence": finite_or_none(result.log_evidence),
        "log_evidence_se": finite_or_none(result.log_evidence_se),
        "log_evidence_se_stagewise": finite_or_none(result.log_evidence_se_stagewise),
        "final_exponent": finite_or_none(result.final.exponent),
        "is_posterior": result.status == "completed",
        "stages": stage_table(result, wall_times),
        "n_stages": len(result.stages) - 1,
        "model_runs": int(result.n_model_runs),
        "simulations": int(sum(s.part_runs for s in result.stages)),
        "simulations_saved": int(sum(s.part_runs_saved for s in result.stages)),
        "failed_runs": int(result.n_failed_runs),
        "failed_by": result.failed_by.to_dict(),
        "wall_time_s": finite_or_none(sum(wall_times)) if wall_times else None,
        "settings": settings,
        "datasets": datasets,
    }
    if map_responses is not None:
        summary["map_responses"] = map_responses
    return summary
