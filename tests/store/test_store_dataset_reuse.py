"""A study's datasets as workers read them (``services.studies.datasets.load_datasets``), on
SQLite and PostgreSQL: the processing stored at upload is reused when the case asks for the same
offset and cutoff, and is then bit-identical to processing the raw bytes again; another offset
or cutoff processes the raw log with the case's settings."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from scm_core.calibration import CaseDefinition
from scm_core.signals import load_log, load_summary
from services.store import Store
from services.studies.datasets import load_datasets

ROOT = Path(__file__).resolve().parents[2]
LOG = ROOT / "examples" / "wf34_s020.csv"
SUMMARY = b"""# slip: 0.2
# normal_load: 315 N
# wheel_radius: 125 mm
trial,drawbar_pull [N],torque [N m],sinkage [mm]
1,40.1,12.2,20.5
2,41.3,12.0,21.0
3,39.8,12.4,20.1
"""


def _case(**data) -> CaseDefinition:
    return CaseDefinition.from_dict(
        {
            "name": "x",
            "parameters": {"phi": {"dist": "uniform", "lower": 20, "upper": 35}},
            "nominal": {"sigma_F": 5.0, "sigma_T": 0.5, "sigma_z": 0.001},
            "data": data,
        }
    )


def _numbers(d) -> dict:
    """Everything the likelihood reads, as exact JSON (floats by repr)."""
    doc = d.to_dict(include_series=False)
    doc.pop("name")
    return json.loads(json.dumps(doc))


@pytest.fixture
def stored(store: Store) -> tuple[int, int]:
    raw = LOG.read_bytes()
    meta = json.loads(LOG.with_suffix(".json").read_text())
    log, _ = store.datasets.add(load_log(raw, metadata=meta, offset=40.0), raw, meta=meta)
    summ, _ = store.datasets.add(load_summary(SUMMARY), SUMMARY)
    return log.id, summ.id


def _no_raw(store: Store, monkeypatch) -> None:
    def refuse(dataset_id: int) -> bytes:
        raise AssertionError(f"raw bytes of dataset {dataset_id} read again")

    monkeypatch.setattr(store.datasets, "raw", refuse)


def test_stored_processing_is_reused_bit_for_bit(store: Store, stored, monkeypatch) -> None:
    raw = LOG.read_bytes()
    meta = json.loads(LOG.with_suffix(".json").read_text())
    fresh = load_log(raw, metadata=meta, offset=40.0, keep_series=False)
    _no_raw(store, monkeypatch)
    for case in (_case(offset=40.0), _case(offset=40.0, cutoff_hz=1.0)):
        log, summary = load_datasets(store, case, list(stored))
        assert log.series is None
        assert _numbers(log) == _numbers(fresh)
        assert log.means["F"] == fresh.means["F"]  # the floats themselves, not their repr
        assert _numbers(summary) == _numbers(load_summary(SUMMARY))


@pytest.mark.parametrize("data", [{"offset": 60.0}, {"offset": 40.0, "cutoff_hz": 0.5}])
def test_other_settings_process_the_raw_log(store: Store, stored, data) -> None:
    raw = LOG.read_bytes()
    meta = json.loads(LOG.with_suffix(".json").read_text())
    (log,) = load_datasets(store, _case(**data), [stored[0]])
    want = load_log(raw, metadata=meta, keep_series=False, **data)
    assert _numbers(log) == _numbers(want)
    assert _numbers(log) != _numbers(store.datasets.load(stored[0]))
