"""Datasets (dedup by content hash), studies (create, list, filter, paginate, cancel) and the
append-only event log."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import sqlalchemy as sa

from scm_core import jsondoc
from services.store import NotFoundError, Store, StudySpec
from services.store.models import Event


def test_dataset_dedup_by_hash(store: Store, make_dataset) -> None:
    ds, raw = make_dataset()
    rec, created = store.datasets.add(
        ds, raw, meta={"operator": "A. Tester"}, filename="run7.csv", media_type="text/csv"
    )
    assert created and rec.content_hash == ds.content_hash and rec.size_bytes == len(raw)
    again, created2 = store.datasets.add(ds, raw, meta={"operator": "someone else"})
    assert not created2 and again.id == rec.id
    assert again.meta == {"operator": "A. Tester"}  # immutable: the first upload stays
    assert store.datasets.get_by_hash(ds.content_hash).id == rec.id
    assert store.datasets.raw(rec.id) == raw
    loaded = store.datasets.load(rec.id)
    assert loaded.content_hash == ds.content_hash and loaded.responses == ds.responses
    assert loaded.conditions == ds.conditions
    assert rec.means == ds.means and rec.standard_errors == ds.standard_errors

    other, created3 = store.datasets.add(*make_dataset(shift=1.0))
    assert created3 and other.id != rec.id
    page = store.datasets.list(limit=1)
    assert page.total == 2 and [d.id for d in page.items] == [other.id]  # newest first
    assert page.next_offset == 1
    assert store.datasets.get_by_hash("0" * 64) is None
    with pytest.raises(NotFoundError):
        store.datasets.get(10_000)
    events = store.events.list(kinds=["dataset_added"])
    assert [e.payload["dataset_id"] for e in events] == [rec.id, other.id]


def test_upload_hashes_point_at_their_dataset(store: Store, make_dataset) -> None:
    """Two uploads as sent (say LF and CRLF) that give one dataset both find it; an unknown
    upload finds nothing; recording an upload twice is harmless."""
    ds, raw = make_dataset(shift=3.0)
    assert store.datasets.find_upload("a" * 64) is None
    rec, created = store.datasets.add(ds, raw, upload_hash="a" * 64)
    assert created
    again, created2 = store.datasets.add(ds, raw.replace(b"\n", b"\r\n"), upload_hash="b" * 64)
    assert not created2 and again.id == rec.id
    store.datasets.add(ds, raw, upload_hash="a" * 64)
    assert store.datasets.find_upload("a" * 64).id == rec.id
    assert store.datasets.find_upload("b" * 64).id == rec.id
    assert store.datasets.find_upload("c" * 64) is None
    assert store.datasets.list().total == 1


def test_concurrent_identical_uploads_make_one_row(store: Store, make_dataset, open_store) -> None:
    ds, raw = make_dataset(shift=2.0)
    stores = [open_store() for _ in range(4)]
    barrier = threading.Barrier(len(stores))
    results: list[tuple[int, bool]] = []

    def upload(s: Store) -> None:
        barrier.wait()
        rec, created = s.datasets.add(ds, raw)
        results.append((rec.id, created))

    threads = [threading.Thread(target=upload, args=(s,)) for s in stores]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len({i for i, _ in results}) == 1
    assert sorted(c for _, c in results) == [False, False, False, True]
    assert store.datasets.list().total == 1


def test_create_and_list_studies(store: Store, toy, make_dataset) -> None:
    d1, _ = store.datasets.add(*make_dataset(0.0))
    d2, _ = store.datasets.add(*make_dataset(1.0))
    study = store.studies.create(toy.spec(dataset_ids=[d2.id, d1.id], name="case 1"))
    assert study.status == "queued" and study.dataset_ids == (d2.id, d1.id)
    assert study.case["priors"] == toy.prior.to_dict() and study.seed == toy.seed
    assert study.case["sampler"] == toy.settings.to_dict() and study.model_runs == 0
    got = store.studies.get(study.id)
    assert got == study

    ids = [study.id]
    for i in range(6):
        ids.append(store.studies.create(toy.spec(name=f"s{i}", seed=i)).id)
    store.studies.start(ids[1], toy.batches(toy.n_samples))
    store.studies.start(ids[2], toy.batches(toy.n_samples))
    store.studies.cancel(ids[3])
    assert store.studies.fail(ids[4], "bad input")

    page = store.studies.list(limit=3)
    assert page.total == 7 and [s.id for s in page.items] == ids[::-1][:3]
    page2 = store.studies.list(limit=3, offset=page.next_offset)
    assert [s.id for s in page2.items] == ids[::-1][3:6]
    assert store.studies.list(limit=3, offset=6).next_offset is None
    running = store.studies.list(status="running")
    assert [s.id for s in running.items] == [ids[2], ids[1]]
    active = store.studies.list(status=["queued", "running"])
    assert active.total == 5
    assert [s.id for s in store.studies.list(status="cancelled").items] == [ids[3]]
    failed = store.studies.list(status="failed").items
    assert [(s.id, s.error) for s in failed] == [(ids[4], "bad input")]
    assert store.studies.list(status="running").items[0].dataset_ids == ()
    assert store.studies.list(limit=1).items[0].name == "s5"
    with pytest.raises(ValueError, match="unknown study status"):
        store.studies.list(status="done")


def test_study_validation(store: Store, toy) -> None:
    with pytest.raises(NotFoundError, match="datasets not found"):
        store.studies.create(toy.spec(dataset_ids=[999]))
    bad_seed = StudySpec(**{**toy.spec().__dict__, "seed": -1})
    with pytest.raises(ValueError, match="seed"):
        store.studies.create(bad_seed)
    big_seed = StudySpec(**{**toy.spec().__dict__, "seed": 2**63 - 1})
    assert store.studies.get(store.studies.create(big_seed).id).seed == 2**63 - 1
    study = store.studies.create(toy.spec())
    with pytest.raises(ValueError, match="consecutively"):
        store.studies.start(study.id, [range(0, 10), range(12, 48)])
    assert store.studies.get(study.id).status == "queued"  # nothing half-done
    assert store.stages.list(study.id) == []
    with pytest.raises(NotFoundError):
        store.studies.get(12345)
    with pytest.raises(NotFoundError):
        store.studies.cancel(12345)


def test_json_columns_take_only_plain_json_values(store: Store, toy) -> None:
    """JSON columns are written by json.dumps(allow_nan=False) without an encoder
    (scm_core.jsondoc.dumps): a numpy array or a nested NaN that slips into a document fails
    where it is written, and nothing is stored; the documents the store builds itself
    (stage rows, events) pass, which the rest of this suite shows on SQLite and PostgreSQL."""
    study = store.studies.create(toy.spec())
    before = store.events.list(study.id)
    for bad in ({"x": np.arange(3)}, {"nested": {"x": float("nan")}}, {"x": np.float32(1.5)}):
        with pytest.raises((TypeError, ValueError, sa.exc.StatementError)):
            store.events.append(study.id, "note", bad)
    assert store.events.list(study.id) == before  # nothing half-written
    assert jsondoc.dumps({"a": [1, 2.5, "nan"], "b": None}) == '{"a":[1,2.5,"nan"],"b":null}'


def test_event_log_is_append_only_and_ordered(store: Store, toy) -> None:
    study = store.studies.create(toy.spec())
    appended = [
        store.events.append(study.id, "note", {"i": i, "x": float("nan") if i == 2 else i})
        for i in range(5)
    ]
    store.events.append(None, "service", {"ok": True})
    events = store.events.list(study.id)
    assert [e.kind for e in events] == ["study_created"] + ["note"] * 5
    assert [e.id for e in events] == sorted(e.id for e in events)
    assert [e.payload["i"] for e in events[1:]] == [0, 1, 2, 3, 4]
    assert events[3].payload["x"] == "nan"  # strict JSON: non-finite floats as strings
    assert events[1].created_at == appended[0].created_at
    after = store.events.list(study.id, after_id=appended[2].id)
    assert [e.payload["i"] for e in after] == [3, 4]
    assert len(store.events.list(study.id, limit=2)) == 2
    assert [e.kind for e in store.events.list(kinds=["service"])] == ["service"]

    with store.db.write() as s:  # the ORM refuses to change or delete an event
        ev = s.get(Event, appended[0].id)
        ev.kind = "changed"
        with pytest.raises(TypeError, match="append-only"):
            s.flush()
        s.rollback()
    with store.db.write() as s:
        ev = s.get(Event, appended[0].id)
        s.delete(ev)
        with pytest.raises(TypeError, match="append-only"):
            s.flush()
        s.rollback()
    with store.db.read() as s:
        assert s.scalar(sa.select(Event.kind).where(Event.id == appended[0].id)) == "note"


def test_timestamps_are_aware_utc_from_the_clock(store: Store, toy, clock) -> None:
    study = store.studies.create(toy.spec())
    assert study.created_at == clock.now
    clock.advance(30)
    store.studies.start(study.id, toy.batches(toy.n_samples))
    got = store.studies.get(study.id)
    assert got.started_at == clock.now and got.created_at.tzinfo is not None
    assert got.started_at.utcoffset().total_seconds() == 0


def test_json_documents_keep_key_order(store: Store, toy) -> None:
    spec = StudySpec(
        **{
            **toy.spec().__dict__,
            "case": {
                "zeta": 1,
                "alpha": {"y": 2, "b": 3},
                "mid": [3, 1],
                "priors": toy.prior.to_dict(),
            },
        }
    )
    study = store.studies.get(store.studies.create(spec).id)
    assert list(study.case) == ["zeta", "alpha", "mid", "priors"]  # the same on SQLite and PG
    assert list(study.case["alpha"]) == ["y", "b"]
    assert [p["name"] for p in study.case["priors"]["parameters"]] == ["a", "b"]
