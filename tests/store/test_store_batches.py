"""Work batches: leases, heartbeats, expiry, the attempt cap, the reaper, idempotent results,
concurrent leasing and cancellation."""

from __future__ import annotations

import threading
from datetime import timedelta

import numpy as np
import pytest

from scm_core.inference.tmcmc.stage import PointEvaluation, evaluate_points
from services.store import BatchKey, BatchOutput, NotFoundError, Store
from services.store.codec import decode


def started_study(store: Store, toy, n_batches: int = 3) -> int:
    study = store.studies.create(toy.spec())
    size = toy.n_samples // n_batches
    batches = [range(i * size, (i + 1) * size) for i in range(n_batches)]
    assert store.studies.start(study.id, batches) is not None
    return study.id


def point_result(toy, study_id: int, store: Store, lease_or_key):
    key = getattr(lease_or_key, "key", lease_or_key)
    rec = store.batches.get(key)
    X = toy.initial_points(store.studies.get(study_id).seed)[rec.chain_start : rec.chain_stop]
    return toy.output(
        evaluate_points(X, toy.log_likelihood), key, range(rec.chain_start, rec.chain_stop)
    )


def test_lease_order_heartbeat_and_expiry(store: Store, toy, clock) -> None:
    sid = started_study(store, toy)
    a = store.batches.lease("w-a")
    b = store.batches.lease("w-b")
    assert (a.key.batch_index, b.key.batch_index) == (0, 1)
    assert a.attempt == 1 and a.chains == range(0, 16)
    assert a.expires_at == clock.now + timedelta(seconds=store.db.lease_seconds)
    assert store.stages.get(sid, 0).status == "running"  # first lease starts the stage
    rec = store.batches.get(a.key)
    assert rec.status == "leased" and rec.worker_id == "w-a" and rec.attempts == 1

    clock.advance(store.db.lease_seconds * 0.75)
    assert store.batches.heartbeat(a)  # a keeps its lease alive, b does not
    clock.advance(store.db.lease_seconds * 0.5)
    # b expired: the next lease takes it (lowest key first) before the pending batch 2
    c = store.batches.lease("w-c")
    assert c.key == b.key and c.attempt == 2 and c.worker_id == "w-c"
    assert not store.batches.heartbeat(b)  # b's holder lost the lease
    assert store.batches.heartbeat(a)
    d = store.batches.lease("w-d")
    assert d.key.batch_index == 2
    assert store.batches.lease("w-e") is None  # nothing left to lease
    kinds = [e.kind for e in store.events.list(sid)]
    assert kinds.count("batch_retry") == 1


def test_claim_specific_batch_once(store: Store, toy, clock) -> None:
    sid = started_study(store, toy)
    key = BatchKey(sid, 0, 1)
    first = store.batches.claim(key, "task-1")
    assert first is not None and first.key == key
    assert store.batches.claim(key, "task-2") is None  # duplicate delivery while leased
    clock.advance(store.db.lease_seconds + 1)
    again = store.batches.claim(key, "task-2")  # lease expired: re-claimable
    assert again is not None and again.attempt == 2
    with pytest.raises(NotFoundError):
        store.batches.get(BatchKey(sid, 0, 99))
    assert store.batches.claim(BatchKey(sid, 0, 99), "x") is None


def test_attempt_cap_fails_the_study_via_reaper(store: Store, toy, clock) -> None:
    sid = started_study(store, toy, n_batches=1)
    for attempt in range(1, store.db.max_attempts + 1):
        lease = store.batches.lease("w")
        assert lease is not None and lease.attempt == attempt
        clock.advance(store.db.lease_seconds + 1)
        report = store.batches.reap()
        if attempt < store.db.max_attempts:
            assert report.requeued == [lease.key] and report.to_dispatch == [lease.key]
            assert report.failed == [] and store.studies.get(sid).status == "running"
            assert store.batches.get(lease.key).status == "pending"
    assert report.failed == [lease.key] and report.failed_studies == [sid]
    study = store.studies.get(sid)
    assert study.status == "failed"
    assert f"after {store.db.max_attempts} attempts" in study.error
    assert study.finished_at == clock.now
    assert store.batches.get(lease.key).status == "failed"
    assert store.batches.lease("w") is None
    kinds = [e.kind for e in store.events.list(sid)]
    assert kinds[-4:] == ["lease_expired", "batch_retry", "batch_failed", "study_failed"]
    # a late result of the failed batch is refused
    res = store.batches.complete(lease.key, point_result(toy, sid, store, lease))
    assert res.status == "rejected"


def test_lease_skips_expired_batch_at_the_cap(store: Store, toy, clock) -> None:
    sid = started_study(store, toy, n_batches=1)
    for _ in range(store.db.max_attempts):
        assert store.batches.lease("w") is not None
        clock.advance(store.db.lease_seconds + 1)
    assert store.batches.lease("w") is None  # left for the reaper to fail
    assert store.studies.get(sid).status == "running"
    assert store.batches.reap().failed_studies == [sid]


def test_release_requeues_then_fails(store: Store, toy) -> None:
    sid = started_study(store, toy, n_batches=1)
    lease = store.batches.lease("w")
    assert store.batches.release(lease, "boom") == "requeued"
    assert store.batches.release(lease, "boom") == "lost"  # no longer held
    rec = store.batches.get(lease.key)
    assert rec.status == "pending" and rec.error == "boom" and rec.worker_id is None
    lease2 = store.batches.lease("w")
    assert lease2.attempt == 2
    assert store.batches.release(lease2, "boom again") == "failed"
    study = store.studies.get(sid)
    assert study.status == "failed" and "boom again" in study.error


def test_batch_result_is_stored_once(store: Store, toy, open_store) -> None:
    sid = started_study(store, toy)
    lease = store.batches.lease("w1")
    result = point_result(toy, sid, store, lease)
    first = store.batches.complete(lease.key, result, event={"worker": "w1", "model_s": 0.5})
    assert (first.status, first.done, first.total) == ("stored", 1, 3)
    assert not first.stage_complete

    other = open_store()  # a second process delivering the same task again
    altered = toy.output(
        evaluate_points(toy.initial_points(toy.seed)[16:32], toy.log_likelihood),
        lease.key,
        lease.chains,
    )  # wrong content for batch 0 must not overwrite the first result
    again = other.batches.complete(lease.key, result, event={"worker": "w2", "model_s": 0.4})
    assert (again.status, again.done, again.total) == ("duplicate", 1, 3)
    assert other.batches.complete(lease.key, altered).status == "duplicate"
    # the "batch_done" event is written with the first result only, in its transaction
    done = store.events.list(sid, kinds=["batch_done"])
    assert [e.payload for e in done] == [{"stage": 0, "batch": 0, "worker": "w1", "model_s": 0.5}]
    stored = store.batches.results(sid, 0)
    assert len(stored) == 1
    assert stored[0] == result.blob
    assert decode(stored[0], PointEvaluation).log_likelihood.tobytes() == (
        decode(result.blob, PointEvaluation).log_likelihood.tobytes()
    )
    assert store.batches.counts(sid, 0) == {"pending": 2, "leased": 0, "done": 1, "failed": 0}
    assert store.batches.count_done(sid, 0) == 1
    assert store.batches.claim(lease.key, "w2") is None  # done: not leasable any more
    assert not store.batches.heartbeat(lease)

    # a result for the wrong number of points is refused outright
    with pytest.raises(ValueError, match=r"result of chains 0\.\.3 for batch"):
        store.batches.complete(
            BatchKey(sid, 0, 1),
            toy.output(evaluate_points(np.zeros((3, 2)), toy.log_likelihood), lease.key, range(3)),
        )
    with pytest.raises(ValueError, match="result of stage 1"):
        store.batches.complete(BatchKey(sid, 0, 1), BatchOutput(1, 16, 32, result.blob))


def test_concurrent_duplicate_deliveries_store_once(store: Store, toy, open_store) -> None:
    sid = started_study(store, toy)
    key = BatchKey(sid, 0, 0)
    result = point_result(toy, sid, store, key)
    stores = [open_store() for _ in range(4)]
    barrier = threading.Barrier(len(stores))
    outcomes: list[str] = []

    def deliver(s: Store) -> None:
        barrier.wait()
        outcomes.append(s.batches.complete(key, result).status)

    threads = [threading.Thread(target=deliver, args=(s,)) for s in stores]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(outcomes) == ["duplicate"] * 3 + ["stored"]
    assert store.batches.count_done(sid, 0) == 1


def test_concurrent_leases_are_exclusive(store: Store, toy, open_store) -> None:
    study = store.studies.create(toy.spec())
    store.studies.start(study.id, [range(i * 4, (i + 1) * 4) for i in range(12)])
    stores = [open_store() for _ in range(4)]
    barrier = threading.Barrier(len(stores))
    leased: list[BatchKey] = []
    lock = threading.Lock()

    def work(s: Store, name: str) -> None:
        barrier.wait()
        while (lease := s.batches.lease(name)) is not None:
            with lock:
                leased.append(lease.key)

    threads = [threading.Thread(target=work, args=(s, f"w{i}")) for i, s in enumerate(stores)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(k.batch_index for k in leased) == list(range(12))  # each exactly once


def test_reaper_redispatches_pending_batches_not_picked_up(store: Store, toy, clock) -> None:
    sid = started_study(store, toy)
    keys = [BatchKey(sid, 0, i) for i in range(3)]
    assert store.batches.reap().to_dispatch == []  # just created: not stale yet
    store.batches.mark_dispatched(keys[:2])
    clock.advance(store.db.lease_seconds / 2)
    assert store.batches.reap().to_dispatch == []
    store.batches.lease("w")  # takes batch 0
    clock.advance(store.db.lease_seconds / 2 + 1)
    report = store.batches.reap()
    # batch 0 is leased (live lease); 1 and 2 were never picked up
    assert report.to_dispatch == keys[1:] and report.requeued == []
    assert store.batches.get(keys[1]).dispatched_at == clock.now
    assert store.batches.reap().to_dispatch == []  # just re-dispatched
    assert store.batches.reap(redispatch_after=0.0).to_dispatch == []  # strictly older only
    clock.advance(1)
    assert store.batches.reap(redispatch_after=0.5).to_dispatch == keys[1:]


def test_reaper_lists_stages_ready_to_advance(store: Store, toy) -> None:
    sid = started_study(store, toy)
    for i in range(3):
        key = BatchKey(sid, 0, i)
        store.batches.complete(key, point_result(toy, sid, store, key))  # without a lease too
    assert store.batches.reap().ready_stages == [(sid, 0)]
    assert store.stages.ready() == [(sid, 0)]
    assert store.stages.advance(sid, 0, toy.reduce).status == "advanced"
    assert store.stages.ready() == []


def test_cancel_stops_leases_heartbeats_and_results(store: Store, toy) -> None:
    sid = started_study(store, toy)
    lease = store.batches.lease("w")
    assert store.studies.cancel(sid, "user asked")
    assert not store.studies.cancel(sid)  # once
    study = store.studies.get(sid)
    assert study.status == "cancelled" and study.error == "user asked"
    assert study.finished_at is not None
    assert not store.batches.heartbeat(lease)
    assert store.batches.lease("w") is None
    assert store.batches.claim(BatchKey(sid, 0, 1), "w") is None
    res = store.batches.complete(lease.key, point_result(toy, sid, store, lease))
    assert res.status == "rejected" and res.done == 0
    assert store.stages.advance(sid, 0, toy.reduce).status == "inactive"
    assert store.batches.reap().to_dispatch == []
    assert [e.kind for e in store.events.list(sid)][-1] == "study_cancelled"
    assert store.events.list(sid)[-1].payload == {"reason": "user asked"}
    assert not store.studies.fail(sid, "too late")


def test_worker_count_of_a_stage(store: Store, toy) -> None:
    """Distinct holders of the stage's done batches (the orchestrator cuts the next stage's
    batches for that many workers)."""
    sid = started_study(store, toy)
    assert store.batches.worker_count(sid, 0) == 0
    for worker in ("w-a", "w-b", "w-a"):
        lease = store.batches.lease(worker)
        store.batches.complete(lease.key, point_result(toy, sid, store, lease))
    assert store.batches.worker_count(sid, 0) == 2


def _deliver_at_once(s: Store, lease, result, barrier: threading.Barrier, out: list) -> None:
    barrier.wait()
    out.append(s.batches.complete(lease.key, result))


def test_exactly_one_of_simultaneous_last_results_completes_the_stage(
    store: Store, toy, open_store
) -> None:
    """The last batches of a stage stored at the same moment by different workers: exactly one
    of them is told the stage is complete (and advances it). Under READ COMMITTED each
    transaction alone would count the other's result as not done yet, and neither would."""
    for _ in range(12):
        sid = started_study(store, toy, n_batches=4)
        stores = [open_store() for _ in range(4)]
        leases = [s.batches.lease(f"w{i}") for i, s in enumerate(stores)]
        results = [point_result(toy, sid, store, lease) for lease in leases]
        barrier = threading.Barrier(len(stores))
        outcomes: list = []
        threads = [
            threading.Thread(target=_deliver_at_once, args=(*args, barrier, outcomes))
            for args in zip(stores, leases, results, strict=True)
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert sorted(o.done for o in outcomes)[-1] == 4
        assert sum(o.stage_complete for o in outcomes) == 1, outcomes
        for s in stores:
            s.close()


def test_reclaim_takes_back_a_dead_owners_leases_only(store: Store, toy, clock) -> None:
    """Worker ids are paths: reclaiming ``local/h/old`` takes back ``local/h/old/12`` but not
    ``local/h/old2/1`` (a prefix of the text only) nor the kept live owner's leases."""
    sid = started_study(store, toy, n_batches=4)
    dead = store.batches.lease("local/h/old/12")
    other = store.batches.lease("local/h/old2/1")
    mine = store.batches.lease("local/h/new/7")
    celery = store.batches.lease("celery-host:33:1")
    with pytest.raises(ValueError, match="owner"):
        store.batches.reclaim("/")
    report = store.batches.reclaim("local/h/old")
    assert report.requeued == [dead.key] and report.to_dispatch == [dead.key]
    assert store.batches.get(dead.key).status == "pending"  # at once, no lease expiry
    assert store.batches.get(other.key).status == "leased"
    # a restarted server on host h: every local/h lease but its own
    report = store.batches.reclaim("local/h", keep="local/h/new")
    assert report.requeued == [other.key]
    assert store.batches.get(mine.key).worker_id == "local/h/new/7"
    assert store.batches.get(celery.key).status == "leased"
    assert not store.batches.heartbeat(other)  # the dead holder lost it
    kinds = [e.kind for e in store.events.list(sid)]
    assert kinds.count("lease_reclaimed") == 2
    # the attempt cap still holds: reclaimed leases count as attempts
    for _ in range(store.db.max_attempts - 1):
        lease = store.batches.claim(dead.key, "local/h/old/13")
        assert lease is not None
        store.batches.reclaim("local/h/old")
    assert store.batches.get(dead.key).status == "failed"
    assert store.studies.get(sid).status == "failed"


def test_stuck_queued_studies_are_listed_after_the_grace(store: Store, toy, clock) -> None:
    queued = store.studies.create(toy.spec()).id
    started = started_study(store, toy)
    assert store.studies.stuck_queued(10.0) == []
    clock.advance(11.0)
    assert store.studies.stuck_queued(10.0) == [queued]
    assert started not in store.studies.stuck_queued(0.0)


def test_reaper_starts_or_fails_studies_left_queued(store: Store, toy, clock) -> None:
    """A submitter that died between storing and starting a study left it queued: the reaper
    pass starts it after the grace period, or fails it with the reason if it cannot start."""
    import sqlalchemy as sa

    from services.store.models import Study
    from worker.orchestrator import QUEUED_GRACE_S, start_stuck_studies

    sent: list = []

    class Collect:
        def dispatch(self, keys) -> None:
            sent.extend(keys)

    ok = store.studies.create(toy.spec()).id
    bad = store.studies.create(toy.spec()).id
    with store.db.write() as s:  # a row no stage can be planned for
        s.execute(sa.update(Study).where(Study.id == bad).values(n_samples=0))
    assert start_stuck_studies(store, Collect()) == []  # within the grace period
    clock.advance(QUEUED_GRACE_S + 1)
    assert start_stuck_studies(store, Collect()) == [ok, bad]
    assert store.studies.get(ok).status == "running"
    assert {k.study_id for k in sent} == {ok} and sent
    failed = store.studies.get(bad)
    assert failed.status == "failed" and "could not start" in failed.error
    assert start_stuck_studies(store, Collect()) == []


def test_give_back_puts_an_interrupted_owners_leases_back_uncounted(
    store: Store, toy, clock
) -> None:
    """A stopped command's leases go back pending with the attempt not counted, so stopping
    and resuming a run any number of times never fails a batch at the attempt cap; other
    owners' leases (a prefix of the text only) stay."""
    sid = started_study(store, toy, n_batches=3)
    with pytest.raises(ValueError, match="owner"):
        store.batches.give_back("//")
    for _ in range(store.db.max_attempts + 2):
        lease = store.batches.lease("here/h/1")
        assert lease is not None and lease.attempt == 1
        assert store.batches.give_back("here/h") == [lease.key]
        assert store.batches.get(lease.key).status == "pending"
        assert not store.batches.heartbeat(lease)  # the stopped holder lost it
    other = store.batches.lease("here/h2/5")
    assert store.batches.give_back("here/h") == []
    assert store.batches.get(other.key).status == "leased"
    assert store.studies.get(sid).status == "running"
    kinds = [e.kind for e in store.events.list(sid)]
    assert kinds.count("lease_given_back") == store.db.max_attempts + 2
