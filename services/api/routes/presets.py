"""The presets (the quick case, the paper's cases 1, 2a and 2b with Table 2 priors) as case
documents, with what a study of each is expected to cost."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Depends, HTTPException

from scm_core.calibration import PRESETS, CaseError, preset_case, preset_cost

from ..deps import require_read
from ..schemas import PresetOut
from . import errors

router = APIRouter(prefix="/presets", tags=["presets"], dependencies=[Depends(require_read)])


def preset_or_404(name: str):
    try:
        return preset_case(name)
    except CaseError as exc:
        raise HTTPException(404, f"preset: {exc}") from None


@router.get("", response_model=list[PresetOut], summary="List presets", responses=errors(401))
def list_presets() -> list[PresetOut]:
    out = []
    for key in PRESETS:
        case, cost = preset_case(key), preset_cost(key)
        out.append(
            PresetOut(
                name=key,
                case_name=case.name,
                description=case.description,
                seed=case.seed,
                parameters=list(case.parameter_names),
                n_samples=case.sampler.n_samples,
                moves=case.sampler.moves,
                expected_model_runs=cost.model_runs,
                expected_minutes=round(cost.minutes, 1),
            )
        )
    return out


@router.get("/{name}", summary="One preset as a case document", responses=errors(401, 404))
def get_preset(name: str) -> dict[str, Any]:
    """The full case document (the same form ``POST /studies`` accepts as ``case``)."""
    return preset_or_404(name).to_dict()
