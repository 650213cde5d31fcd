"""The earlier study a ``scm-calib calibrate --update-of DIR`` run starts from.

A ``calibrate`` results folder holds what an update needs: the case (``summary.json``), the final
population bit for bit (the last ``checkpoints/stage_NNN.json``), the datasets behind the
posterior (their files, recorded in ``summary.json`` with their content hashes) and the log
evidence (the total one if the folder is itself an update).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from scm_core.calibration import CaseDefinition, CaseError
from scm_core.inference import StageState
from services.stages import FolderStages, StageStoreError

from .common import CLIError


@dataclass(frozen=True)
class ParentStudy:
    """A finished ``calibrate`` study: ``case`` (its seed is the study's), ``final`` stage,
    ``dataset_paths`` with their ``dataset_hashes`` (likelihood order) and the total
    ``log_evidence`` of all its data."""

    results: Path
    case: CaseDefinition
    final: StageState
    dataset_paths: list[Path]
    dataset_hashes: list[str]
    log_evidence: float

    @property
    def identity(self) -> dict[str, Any]:
        """What the update's checkpoints belong to (refused if the parent changes)."""
        return {
            "results": str(self.results.resolve()),
            "case_hash": self.case.fingerprint(),
            "data_hashes": list(self.dataset_hashes),
            "population_sha256": hashlib.sha256(self.final.samples.tobytes()).hexdigest(),
        }


def load_parent(results: Path) -> ParentStudy:
    """The completed study in the ``calibrate`` results folder ``results``; CLIError naming
    the file for anything missing or unfinished."""
    summary_path = results / "summary.json"
    if not summary_path.is_file():
        raise CLIError(
            f"--update-of {results}: no summary.json; give the output folder of a finished "
            "`scm-calib calibrate`"
        )
    try:
        summary = json.loads(summary_path.read_text(encoding="utf-8"))
        case = CaseDefinition.from_stored(summary["case"], base_dir=results)
        status = summary["status"]
        n_stages = int(summary["n_stages"])
        datasets = list(summary["datasets"])
    except (OSError, json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
        raise CLIError(f"{summary_path}: unreadable study summary ({exc})") from None
    except CaseError as exc:
        raise CLIError(f"{summary_path}: {exc}") from None
    if status != "completed":
        raise CLIError(
            f"--update-of {results}: the study is {status}; only a completed calibration can "
            "be updated"
        )
    paths = [d.get("path") for d in datasets]
    if not paths or any(p is None for p in paths):
        raise CLIError(
            f"{summary_path}: the dataset files are not recorded (a summary written before "
            "updates existed); run that calibration again to update it"
        )
    try:
        final = FolderStages(results).state(n_stages)
    except StageStoreError as exc:
        raise CLIError(f"--update-of {results}: its final stage: {exc}") from None
    update = summary.get("update") or {}
    log_z = update.get("log_evidence_total", summary.get("log_evidence"))
    return ParentStudy(
        results=results,
        case=case,
        final=final,
        dataset_paths=[Path(p) for p in paths],
        dataset_hashes=[str(d.get("content_hash")) for d in datasets],
        log_evidence=float("nan") if log_z is None else float(log_z),
    )
