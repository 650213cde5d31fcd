"""The files of a ``scm-calib calibrate`` results folder: its outputs, its stages (kept once,
in its database) and reading them back (``predict``, ``export``, an update).

Layout::

    DIR/study.db                       the study's database (services.cli.folder_store): its
                                       stages and samples, the one copy (results_stages)
    DIR/samples/stage_NN.csv           samples of every stage: parameters, log_likelihood,
                                       log_prior, simulated responses F/T/z/Fy per dataset
    DIR/posterior.csv                  the final stage's samples (same columns)
    DIR/summary.json                   posterior summary, evidence, diagnostics, settings
    DIR/figures/prior_posterior.png    Figure 5-like
    DIR/figures/posterior_pairs.png    Figures 6-8-like
    DIR/figures/fit_map.png            measured vs simulated at the MAP sample (Figure 3-like)

A folder written before folders held a database kept its stages as
``DIR/checkpoints/stage_NNN.json`` with a ``manifest.json``: read (never written) by
:class:`LegacyCheckpoints` and :func:`results_stages`, so such a folder still resumes,
predicts and updates; ``scm-calib export DIR --to stages`` writes that JSON form on demand.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from scm_core.calibration import CaseDefinition, CaseError, StudyModel, study_summary
from scm_core.inference import LOG_SCALE_KINDS, StageState, TMCMCResult
from scm_core.jsondoc import finite_or_none
from scm_core.signals import SWTDataset
from scm_core.signals.responses import keys_for
from services.stages import (
    DatabaseStages,
    FolderStages,
    StageStore,
    StageStoreError,
    stage_states,
)
from services.stages.folder import write_json
from services.store import NotFoundError, Store
from services.studies.kinds.update import UPDATABLE

from .common import CLIError
from .folder_store import DB_FILE, FolderStore, open_folder_store

CHECKPOINT_FORMAT = "scm-calib-checkpoints"

# ---------------------------------------------------------------------- checkpoints


class LegacyCheckpoints:
    """The checkpoints of a folder written before folders held a database (read only): the
    stages (:class:`~services.stages.FolderStages`) and the manifest saying what study they
    belong to (case, datasets, the study updated), which the study run on the folder must be
    to take them over."""

    def __init__(
        self,
        out: Path,
        case: CaseDefinition,
        datasets: Sequence[SWTDataset],
        update_of: dict[str, Any] | None = None,
    ):
        self.stages = FolderStages(out)
        self.dir = self.stages.dir
        self.manifest = checkpoint_manifest(case, datasets, update_of)

    def load(self) -> list[StageState]:
        """Saved stages (consecutive from 0); none without a manifest; refuses another
        study's."""
        path = self.dir / "manifest.json"
        if not path.is_file():
            return []
        try:
            saved = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise CLIError(f"{path}: unreadable checkpoint manifest ({exc})") from None
        if saved.get("format") != CHECKPOINT_FORMAT:
            raise CLIError(f"{path}: not a scm-calib checkpoint manifest")
        what = []
        if saved.get("case_hash") != self.manifest["case_hash"]:
            what.append("the case (priors, nominal values, simulator or sampler settings)")
        if saved.get("data_hashes") != self.manifest["data_hashes"]:
            what.append("the datasets")
        if saved.get("update_of") != self.manifest.get("update_of"):
            what.append("the study updated (--update-of)")
        if what:
            raise CLIError(
                f"{self.dir} holds checkpoints of another study: {' and '.join(what)} changed "
                "since; use another --out directory or delete the checkpoints to start over"
            )
        try:
            return stage_states(self.stages)
        except StageStoreError as exc:
            raise CLIError(str(exc)) from None


def checkpoint_manifest(
    case: CaseDefinition,
    datasets: Sequence[SWTDataset],
    update_of: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """What a folder's stages in JSON belong to: case, datasets, the study updated."""
    manifest: dict[str, Any] = {
        "format": CHECKPOINT_FORMAT,
        "version": 1,
        "case": case.name,
        "case_hash": case.fingerprint(),
        "data_hashes": [d.content_hash for d in datasets],
        "parameters": list(case.parameter_names),
        "n_samples": case.sampler.n_samples,
        "seed": case.seed,
    }
    if update_of is not None:  # the earlier posterior an update starts from
        manifest["update_of"] = update_of
    return manifest


@contextlib.contextmanager
def results_stages(
    results: Path,
    summary: dict[str, Any],
    folder: FolderStore | None = None,
    option: str = "RESULTS",
) -> Iterator[StageStore]:
    """The stages of the ``calibrate`` results folder ``results`` (its ``summary``): the
    study of its database that the summary names, or, in a folder written before folders
    held a database, its checkpoints (read only). ``folder``: this command's open store, if
    it is that folder's; else the folder's store is opened (locked) while the block runs."""
    study_id = (summary.get("study") or {}).get("id")
    if study_id is None or not (results / DB_FILE).is_file():
        yield FolderStages(results)
    elif folder is not None and folder.out.resolve() == results.resolve():
        yield _kept(folder.store, int(study_id), results)
    else:
        with open_folder_store(results, option=option) as opened:
            yield _kept(opened.store, int(study_id), results)


def _kept(store: Store, study_id: int, results: Path) -> StageStore:
    """The stages of the summary's study in ``store`` if it holds them (a calibration or an
    update of that id with stages), else the folder's checkpoints (a folder from before
    databases, which a command has given a database since)."""
    try:
        record = store.studies.get(study_id)
    except NotFoundError:
        return FolderStages(results)
    stages = DatabaseStages(store, study_id)
    return stages if record.kind in UPDATABLE and stages.count() else FolderStages(results)


# ---------------------------------------------------------------------- outputs


def _fmt(v: float) -> str:
    return "nan" if not math.isfinite(v) else repr(float(v))


def write_stage_csv(
    path: Path, state: StageState, names: Sequence[str], response_names: Sequence[str]
) -> None:
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        resp = state.responses
        header = [*names, "log_likelihood", "log_prior"]
        if resp is not None:
            header += list(response_names)
        w.writerow(header)
        for i in range(state.n_samples):
            row = [_fmt(v) for v in state.samples[i]]
            row += [_fmt(state.log_likelihood[i]), _fmt(state.log_prior[i])]
            if resp is not None:
                row += [_fmt(v) for v in resp[i]]
            w.writerow(row)


def write_outputs(
    out: Path,
    result: TMCMCResult,
    case: CaseDefinition,
    model: StudyModel,
    datasets: Sequence[SWTDataset],
    wall_times: Sequence[float],
    extra_settings: dict[str, Any],
    plots: bool = True,
    paths: Sequence[Path] | None = None,
    sections: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Stage CSVs, posterior.csv, summary.json and the figures; returns the summary.

    ``paths``: the datasets' files, recorded (absolute) in the summary so that an update can
    read them again; ``sections``: more top-level entries of the summary (e.g. ``update``)."""
    samples_dir = out / "samples"
    samples_dir.mkdir(parents=True, exist_ok=True)
    for old in samples_dir.glob("stage_*.csv"):  # left by an earlier study in this directory
        old.unlink()
    names = result.names
    for st in result.stages:
        write_stage_csv(samples_dir / f"stage_{st.stage:02d}.csv", st, names, model.response_names)
    write_stage_csv(out / "posterior.csv", result.final, names, model.response_names)

    # the MAP sample's simulations, for the fit figure and the summary
    lp = result.final.log_prior + result.final.log_likelihood
    theta = result.final.samples[int(np.argmax(np.where(np.isnan(lp), -np.inf, lp)))]
    sims, map_responses = [], {}
    offsets = model.measurement_offsets(theta)
    for k, ds in enumerate(datasets):
        try:
            sim = model.simulate_at(theta, k)
        except (ValidationError, ValueError):
            sim = None
        sims.append(sim)
        m = sim.means if sim is not None else None
        keys = keys_for(bool(ds.conditions.slip_angle), case.responses, ds.responses)
        map_responses[ds.name] = {
            "status": None if sim is None else sim.status,
            "simulated": {
                r: finite_or_none(getattr(m, r) + offsets.get(r, 0.0)) if m else None for r in keys
            },
            "measured": {r: float(ds.responses[r].mean) for r in keys if r in ds.responses},
        }
    summary = study_summary(result, case, model, wall_times, extra_settings, map_responses)
    for entry, path in zip(summary["datasets"], paths or (), strict=False):
        entry["path"] = str(Path(path).resolve())
    summary.update(sections or {})
    write_json(out / "summary.json", summary, indent=2)

    if plots:
        from services.plots.choices import mean_b_eff
        from services.plots.fit import fits_against_slip, plot_fit, plot_slip_fit
        from services.plots.posterior import plot_pairs, plot_prior_posterior

        fig_dir = out / "figures"
        fig_dir.mkdir(exist_ok=True)
        prior = case.prior()
        units = dict(prior.units or {})
        log_params = {n for n, d in prior.dists.items() if d.kind in LOG_SCALE_KINDS}
        updated = bool(sections and "update" in sections)
        stopped = "" if result.status == "completed" else f" - NOT A POSTERIOR ({result.status})"
        plot_prior_posterior(
            names,
            result.stages[0].samples,
            result.samples,
            fig_dir / "prior_posterior.png",
            bounds=prior.bounds,
            units=units,
            map_sample=theta,
            reference=case.reference,
            title=f"{case.name}: {'earlier' if updated else 'prior'} "
            f"and posterior ({result.status}){stopped}",
            log_params=log_params,
            labels=("earlier posterior", "updated posterior")
            if updated
            else ("prior", "posterior"),
        )
        b_eff = mean_b_eff(sims[0])
        k_star = case.reference.get("k_star")
        plot_pairs(
            names,
            result.samples,
            fig_dir / "posterior_pairs.png",
            units=units,
            reference=case.reference,
            k_star_line=(k_star, b_eff) if k_star and b_eff else None,
            title=f"{case.name}: bivariate posterior densities{stopped}",
            log_params=log_params,
        )
        fit = {"responses": case.responses, "offsets": model.measurement_offsets(theta)}
        at = f"at the MAP sample{stopped}"
        if fits_against_slip(datasets):  # a steered study: a column per slip angle
            plot_slip_fit(
                datasets,
                sims,
                fig_dir / "fit_map.png",
                title=f"{case.name}: measured vs simulated steady means {at}, per slip angle",
                sigmas=_sigmas_at(case, model, theta),
                **fit,
            )
        else:
            plot_fit(
                datasets,
                sims,
                fig_dir / "fit_map.png",
                title=f"{case.name}: measured vs simulated {at}",
                **fit,
            )
    return summary


def _sigmas_at(case: CaseDefinition, model: StudyModel, theta: np.ndarray) -> dict | None:
    """The prediction-error sigma of each response at ``theta`` (SI), or None where the
    likelihood has none (the paper's eq. (12)-(15))."""
    try:
        sigmas = [float(s) for s in model.sigmas(theta)[0]]
    except (TypeError, ValueError):
        return None
    return dict(zip(case.responses, sigmas, strict=True)) if sigmas else None


# ---------------------------------------------------------------------- reading back


def read_population(path: Path, names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(samples (n, d), log_likelihood (n,), log_prior (n,)) of a stage CSV of a results
    folder (``posterior.csv``, ``samples/stage_NN.csv``), exactly as written."""
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise CLIError(f"{path}: {exc.strerror or exc}") from None
    if not rows:
        raise CLIError(f"{path}: empty file")
    header = rows[0]
    wanted = [*names, "log_likelihood", "log_prior"]
    missing = [c for c in wanted if c not in header]
    if missing:
        raise CLIError(f"{path}: no column {', '.join(missing)}; is this a results folder?")
    cols = [header.index(c) for c in wanted]
    try:
        table = np.array([[float(r[c]) for c in cols] for r in rows[1:]], dtype=float)
    except (ValueError, IndexError) as exc:
        raise CLIError(f"{path}: unreadable row ({exc})") from None
    table = table.reshape(-1, len(wanted))
    d = len(names)
    return table[:, :d], table[:, d], table[:, d + 1]


def load_summary(results: Path) -> tuple[CaseDefinition, dict[str, Any]]:
    """(case, summary) of a ``calibrate`` results folder, without its samples."""
    summary_path = results / "summary.json"
    _require(results, summary_path)
    try:
        summary = json.loads(summary_path.read_text(encoding="utf-8"))
        case = CaseDefinition.from_stored(summary["case"], base_dir=results)
    except (OSError, json.JSONDecodeError, KeyError, TypeError) as exc:
        raise CLIError(f"{summary_path}: unreadable study summary ({exc})") from None
    except CaseError as exc:
        raise CLIError(f"{summary_path}: {exc}") from None
    return case, summary


def _require(results: Path, path: Path) -> None:
    if not path.is_file():
        raise CLIError(
            f"{results}: no {path.name}; give the output folder of `scm-calib calibrate`"
        )


def load_results(results: Path) -> tuple[CaseDefinition, np.ndarray, dict[str, Any]]:
    """(case, posterior samples (n, d), summary) of a ``calibrate`` results folder."""
    post_path = results / "posterior.csv"
    _require(results, results / "summary.json")
    _require(results, post_path)
    case, summary = load_summary(results)
    samples, _, _ = read_population(post_path, list(case.parameter_names))
    if samples.size == 0:
        raise CLIError(f"{post_path}: no samples")
    return case, samples, summary
