"""The TMCMC driver's hooks and batches: same results as a plain run, exact resume."""

from __future__ import annotations

import numpy as np
import pytest

from scm_core.calibration import (
    CaseDefinition,
    DatasetTerms,
    Resume,
    StageHooks,
    StudyModel,
    run_tmcmc,
)
from scm_core.inference import JointPrior, TMCMCSettings, TruncatedNormal, Uniform
from scm_core.signals.responses import N_RESPONSES

PRIOR = JointPrior({"a": Uniform(-3.0, 3.0), "b": TruncatedNormal(0.5, 1.0, -2.0, 4.0)})


def gauss(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r = (X - np.array([0.7, 1.2])) / np.array([0.1, 0.2])
    return -0.5 * (r[:, 0] ** 2 + r[:, 1] ** 2), r


def same(r1, r2) -> bool:
    return (
        len(r1.stages) == len(r2.stages)
        and all(a.equals(b) for a, b in zip(r1.stages, r2.stages, strict=True))
        and r1.status == r2.status
        and r1.log_evidence == r2.log_evidence
    )


class StopError(Exception):
    pass


@pytest.mark.parametrize("moves", ["leader", "resample-move"])
@pytest.mark.parametrize("batch_size", [None, 37])
def test_hooks_and_batches_do_not_change_results(moves: str, batch_size: int | None) -> None:
    settings = TMCMCSettings(moves=moves, n_steps=3)
    ref = run_tmcmc(gauss, PRIOR, n_samples=300, seed=5, settings=settings)
    starts, batches = [], []
    res = run_tmcmc(
        gauss,
        PRIOR,
        300,
        5,
        settings,
        batch_size=batch_size,
        hooks=StageHooks(on_stage_start=starts.append, on_batch=batches.append),
    )
    assert same(res, ref) and res.status == "completed"
    assert [s.stage for s in starts] == list(range(len(res.stages)))
    assert sum(batches) == sum(s.planned for s in starts)
    assert starts[0].planned == 300
    if moves == "leader":
        assert all(s.planned == 300 for s in starts)


def test_interrupted_run_resumes_bit_identically() -> None:
    settings = TMCMCSettings(moves="resample-move", n_steps=2)
    full = run_tmcmc(gauss, PRIOR, 200, 9, settings)
    saved = []

    def on_stage(state):
        saved.append(state)
        if state.stage == 2:
            raise StopError

    with pytest.raises(StopError):
        run_tmcmc(gauss, PRIOR, 200, 9, settings, hooks=StageHooks(on_stage=on_stage))
    assert [s.stage for s in saved] == [0, 1, 2]
    resumed = run_tmcmc(gauss, PRIOR, 200, 9, settings, batch_size=11, start=Resume(saved))
    assert same(resumed, full)
    with pytest.raises(ValueError, match="seed"):
        run_tmcmc(gauss, PRIOR, 200, 10, settings, start=Resume(saved))


def test_stopped_by_max_stages_then_continued_with_the_model() -> None:
    case = CaseDefinition.from_dict(
        {
            "name": "driver",
            "seed": 2,
            "likelihood": "gaussian",
            "parameters": {"phi": {"dist": "uniform", "lower": 20.0, "upper": 35.0}},
            "nominal": {"J": 0.004, "sigma_F": 3.0, "sigma_T": 0.4, "sigma_z": 8e-4},
            "simulator": {
                "duration": 8.0,
                "dx": 0.015,
                "dt": 0.05,
                "offset_F": 4.0,
                "offset_T": 4.0,
                "offset_z": 4.0,
            },
            "sampler": {"n_samples": 40, "moves": "leader"},
        }
    )
    data = DatasetTerms("d", {"W": 315.0, "slip": 0.2, "R": 0.125}, (50.0, 10.0, 0.019))
    model = StudyModel(case, [data])
    settings = case.tmcmc_settings()
    full = run_tmcmc(model.log_likelihood_batch, case.prior(), 40, case.seed, settings)
    assert full.status == "completed" and len(full.stages) > 2
    part = run_tmcmc(
        model.log_likelihood_batch,
        case.prior(),
        40,
        case.seed,
        TMCMCSettings(moves="leader", max_stages=1),
    )
    assert part.status == "max_stages" and len(part.stages) == 2
    rest = run_tmcmc(
        model.log_likelihood_batch,
        case.prior(),
        40,
        case.seed,
        settings,
        batch_size=9,
        start=Resume(part.stages),
    )
    assert same(rest, full)
    assert rest.final.responses is not None and rest.final.responses.shape == (40, N_RESPONSES)
