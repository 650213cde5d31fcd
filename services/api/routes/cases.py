"""Case files: a TOML case file checked and turned into the case document that ``POST
/studies`` and ``POST /sensitivity`` take (the dashboard's case-file form; lab scripts)."""

from __future__ import annotations

from fastapi import APIRouter, Depends

from services.studies import case_from_toml

from ..deps import require_read
from ..schemas import CaseFileIn, CaseFileOut
from . import errors

router = APIRouter(prefix="/cases", tags=["cases"], dependencies=[Depends(require_read)])


@router.post(
    "/check",
    response_model=CaseFileOut,
    summary="Check a TOML case file",
    responses=errors(401, 413, 422),
)
def check_case_file(body: CaseFileIn) -> CaseFileOut:
    """Parse and validate a case file as ``scm-calib calibrate`` does; answers its case
    document (every default filled in), or 422 with the CLI's one-line message under
    ``toml``. Nothing is stored. ``[data]`` files are not read: a study takes stored
    datasets by id."""
    return CaseFileOut(case=case_from_toml(body.toml).to_dict())
