"""A finished ``calibrate`` results folder's posterior: what ``--update-of DIR`` starts from and
what ``scm-calib predict DIR`` simulates.

A results folder holds what they need: the case (``summary.json``), the final population bit for
bit (its study's stages in the folder's database; in a folder written before folders held one,
the last ``checkpoints/stage_NNN.json``), the datasets behind the posterior (their files,
recorded in ``summary.json`` with their content hashes), the log evidence (the total one if the
folder is itself an update) and the study's id.
:func:`stored_posterior` gives the posterior as a completed study of a folder's database.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from scm_core.calibration import CaseDefinition, CaseError
from scm_core.inference import StageState
from scm_core.signals import SWTDataset
from services.stages import StageStoreError, stage_states
from services.store import NotFoundError, StudyRecord
from services.studies import calibration_spec
from services.studies.kinds.calibration import KIND as CALIBRATION

from .common import CLIError, read_datasets
from .folder_store import FolderStore
from .results import results_stages
from .runs import group_folders


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
    study_id: int | None = None
    summary: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    def datasets(self, option: str = "--update-of") -> list[SWTDataset]:
        """The datasets behind the posterior, read again from their files with the case's
        data settings; a one-line error (naming ``option``) if a file is gone or changed."""
        for path in self.dataset_paths:
            if not path.is_file():
                raise CLIError(
                    f"{option} {self.results}: its dataset {path} is gone; this needs the data "
                    "behind the earlier posterior"
                )
        found = read_datasets(self.case, self.dataset_paths)
        for d, path, digest in zip(found, self.dataset_paths, self.dataset_hashes, strict=True):
            if d.content_hash != digest:
                raise CLIError(
                    f"{option} {self.results}: {path} changed since that study was calibrated"
                )
        return found

    @property
    def identity(self) -> dict[str, Any]:
        """The earlier study an update is of (its folder, case, data and final population), as
        an update's folder from before folders held a database names it in its checkpoint
        manifest, which must match to be taken over."""
        return {
            "results": str(self.results.resolve()),
            "case_hash": self.case.fingerprint(),
            "data_hashes": list(self.dataset_hashes),
            "population_sha256": hashlib.sha256(self.final.samples.tobytes()).hexdigest(),
        }


def load_parent(results: Path, option: str = "--update-of") -> ParentStudy:
    """The completed study in the ``calibrate`` results folder ``results``; CLIError naming
    the file (and ``option``) for anything missing or unfinished."""
    summary_path = results / "summary.json"
    if not summary_path.is_file() and group_folders(results) is not None:
        raise CLIError(
            f"{option} {results}: a group of runs (`calibrate --runs`); give one run's folder, "
            f"e.g. {results / 'run_1'} (a prediction or an update starts from one study)"
        )
    if not summary_path.is_file():
        raise CLIError(
            f"{option} {results}: no summary.json; give the output folder of a finished "
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
            f"{option} {results}: the study is {status}; only a completed calibration has a "
            "posterior"
        )
    paths = [d.get("path") for d in datasets]
    if not paths or any(p is None for p in paths):
        raise CLIError(
            f"{summary_path}: the dataset files are not recorded (a summary written before "
            "updates existed); run that calibration again to update it"
        )
    try:
        with results_stages(results, summary, option=option) as stages:
            final = stages.state(n_stages)
    except StageStoreError as exc:
        raise CLIError(f"{option} {results}: its final stage: {exc}") from None
    update = summary.get("update") or {}
    log_z = update.get("log_evidence_total", summary.get("log_evidence"))
    return ParentStudy(
        results=results,
        case=case,
        final=final,
        dataset_paths=[Path(p) for p in paths],
        dataset_hashes=[str(d.get("content_hash")) for d in datasets],
        log_evidence=float("nan") if log_z is None else float(log_z),
        study_id=(summary.get("study") or {}).get("id"),
        summary=summary,
    )


def load_parents(results: Path, option: str) -> list[ParentStudy]:
    """The completed studies of ``results``: a run group's runs (``calibrate --runs``, in
    order), or the one study of a results folder (:func:`load_parent`)."""
    runs = group_folders(results)
    if runs is None or (results / "summary.json").is_file():
        return [load_parent(results, option)]
    return [load_parent(run, option) for run in runs]


def stored_posterior(
    folder: FolderStore,
    parent: ParentStudy,
    option: str = "--update-of",
    datasets: Sequence[SWTDataset] | None = None,
) -> StudyRecord:
    """``parent``'s posterior as a completed study of ``folder``'s database: the folder's own
    study when ``parent`` is the folder and its summary names it; else a calibration on all
    the datasets behind the posterior (read again from their files, likelihood order) whose
    stages are ``parent``'s (:func:`~services.cli.results.results_stages`), bit for bit, and
    whose result holds the total log evidence of its data (an update's parent, a folder
    written before folders held a database). ``datasets``: those already read by
    :meth:`ParentStudy.datasets`, if any."""
    store = folder.store
    if parent.study_id is not None and folder.out.resolve() == parent.results.resolve():
        with contextlib.suppress(NotFoundError):
            own = store.studies.get(int(parent.study_id))
            if own.status == "completed":
                return own
    found_data = parent.datasets(option) if datasets is None else datasets
    ids = folder.add_datasets(found_data, parent.dataset_paths)
    spec = calibration_spec(store, folder.settings, parent.case, ids)
    spec = replace(spec, name=f"{parent.case.name} ({parent.results.resolve()})"[:200])
    found = folder.find(spec)
    if found is not None and found.status == "completed":
        return found
    record = store.studies.create(spec)
    try:
        with results_stages(parent.results, parent.summary, folder, option) as stages:
            states = stage_states(stages)
        total = {"log_evidence_total": parent.log_evidence, "results": str(parent.results)}
        CALIBRATION.build(store, record).adopt(store, record, states, result=total)
    except (StageStoreError, ValueError) as exc:
        raise CLIError(f"{parent.results}: {exc}") from None
    record = store.studies.get(record.id)
    if record.status != "completed":
        raise CLIError(f"{parent.results}: its stages do not end the calibration")
    return record
