"""A results folder's database: the study a command runs here, kept next to its files.

A command that runs a study (``scm-calib sensitivity`` ...) keeps it in ``OUT/study.db``, a
SQLite store at the code's schema revision, with the datasets it reads: the same store, kinds
and batches as the service (:func:`worker.here.run_here`), so the files it writes come from
what the service would have stored, and running the command again resumes the study where it
stopped (stored batches are not run again). ``scm-calib serve`` with
``SCM_CALIB_DATABASE_URL=sqlite:///OUT/study.db`` shows it on the dashboard.

One command at a time uses a folder (a lock file, released when the process ends, however
it ends). Keep results folders on a local disk: SQLite's locking is not reliable on network
file systems.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from scm_core.calibration import CaseDefinition
from scm_core.signals import SWTDataset, read_sidecar
from services.config import Settings
from services.store import Store, StudyRecord, StudySpec

from .common import CLIError

__all__ = ["DB_FILE", "FolderStore", "open_folder_store"]

DB_FILE = "study.db"
LOCK_FILE = ".scm-calib.lock"


@dataclass(frozen=True)
class FolderStore:
    """The store of the results folder ``out`` and the settings it runs under."""

    out: Path
    store: Store
    settings: Settings

    def add_datasets(self, datasets: Sequence[SWTDataset], paths: Sequence[Path]) -> list[int]:
        """Store the datasets read from ``paths`` (as read: processed with the case's
        settings, with the file's bytes); their ids, in order. A dataset already held (the
        same content) keeps its id."""
        ids = []
        for dataset, path in zip(datasets, paths, strict=True):
            meta = read_sidecar(Path(path))
            with open(path, "rb") as raw:
                rec, _ = self.store.datasets.add(dataset, raw, meta=meta, filename=Path(path).name)
            ids.append(rec.id)
        return ids

    def find(self, spec: StudySpec, what: str | None = None) -> StudyRecord | None:
        """The newest study of the folder with ``spec``'s inputs (see :func:`_identity`).
        With ``what`` (the command's word for it: "a sensitivity study"), a folder holding a
        study of the kind with other inputs is refused in one line: a results folder never
        mixes inputs."""
        mine = _identity(self.store, spec)
        found = None
        for study in self.store.studies.list(kind=spec.kind, limit=1000).items:
            if _identity(self.store, study) != mine:
                if what is not None:
                    raise CLIError(
                        f"--out {self.out} holds {what} of other inputs (case, datasets, seed "
                        f"or settings); give another --out, or remove {self.out / DB_FILE} to "
                        "start over"
                    )
            elif found is None:
                found = study  # the listing is newest first
        return found

    def study_for(self, spec: StudySpec, what: str) -> StudyRecord:
        """The folder's study of ``spec``: the one stored (a run to resume or already done)
        or a new one; refuses a folder holding another (see :meth:`find`)."""
        return self.find(spec, what) or self.store.studies.create(spec)


def _identity(store: Store, study: StudySpec | StudyRecord) -> str:
    """What decides a study's results: kind, the case's fingerprint (not its name, data file
    names, batch size or ``max_stages``: a stopped run can go on), the datasets' contents,
    seed, size and the kind's settings."""
    hashes = [store.datasets.get(int(d)).content_hash for d in study.dataset_ids]
    doc: dict[str, Any] = {
        "kind": study.kind,
        "case": CaseDefinition.from_stored(dict(study.case)).fingerprint(),
        "datasets": hashes,
        "seed": int(study.seed),
        "n_samples": int(study.n_samples),
        "payload": study.payload or {},
    }
    return json.dumps(doc, sort_keys=True, allow_nan=True)


@contextlib.contextmanager
def open_folder_store(
    out: Path, workers: int | None = None, option: str = "--out"
) -> Iterator[FolderStore]:
    """The store of results folder ``out`` (created, or migrated to the code's revision),
    locked for this process; a one-line error (naming the folder as ``option``, the command
    line's word for it) if the folder cannot be made or is in use. A
    folder this call made is removed again if the command fails before storing a study (a
    refused input leaves nothing behind)."""
    from services.store import migrate

    made = [p for p in (out, *out.parents) if not p.exists()]
    db_path = out / DB_FILE
    new_db = not db_path.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        lock = open(out / LOCK_FILE, "a+b")  # noqa: SIM115 (held while the store is open)
    except OSError as exc:
        raise CLIError(f"{option} {out}: {exc.strerror or exc}") from None
    store = None
    try:
        try:
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise CLIError(
                f"{option} {out}: another scm-calib command is using this folder"
            ) from None
        url = f"sqlite:///{db_path.resolve().as_posix()}"
        settings = Settings(
            database_url=url, broker_url=None, worker_concurrency=workers or 1, dashboard=False
        )
        migrate.upgrade(url)
        store = Store.from_settings(settings)
        yield FolderStore(out, store, settings)
    except BaseException:
        if new_db and store is not None and store.studies.list(limit=1).total == 0:
            store.close()
            store = None
            _remove_new(out, db_path, made)
        raise
    finally:
        if store is not None:
            store.close()
        lock.close()


def _remove_new(out: Path, db_path: Path, made: list[Path]) -> None:
    """Remove a database that holds no study, and the folders made for it if empty."""
    for path in (db_path, *(db_path.with_name(db_path.name + s) for s in ("-wal", "-shm"))):
        path.unlink(missing_ok=True)
    (out / LOCK_FILE).unlink(missing_ok=True)
    for folder in made:  # innermost first
        with contextlib.suppress(OSError):
            folder.rmdir()
