"""Migrations: empty -> head -> base on SQLite and PostgreSQL, the migrated schema equals the
models, the store refuses a database at the wrong revision, and the ``scm-calib db`` commands."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import sqlalchemy as sa
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from click.testing import CliRunner

from scm_core.calibration import CaseDefinition, MorrisSettings, load_case, sensitivity_design
from services.cli.main import cli
from services.store import SchemaVersionError, Store, current_revision, downgrade, upgrade
from services.store.engine import make_engine
from services.store.migrate import head_revision, migrations_dir
from services.store.models import Base
from services.studies.kinds import study_terms

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

TABLES = {
    "datasets",
    "dataset_uploads",
    "dataset_chunks",
    "studies",
    "study_datasets",
    "stages",
    "work_batches",
    "samples",
    "events",
    "heartbeats",
}


def _tables(url: str) -> set[str]:
    engine = make_engine(url)
    try:
        return set(sa.inspect(engine).get_table_names()) - {"alembic_version"}
    finally:
        engine.dispose()


def test_migrations_directory_is_found() -> None:
    assert (migrations_dir() / "versions" / "0001_initial.py").is_file()
    assert (migrations_dir() / "versions" / "0004_kind_payload.py").is_file()
    assert head_revision() == "0012"


def test_upgrade_to_head_and_downgrade_to_base(empty_url: str) -> None:
    assert current_revision(empty_url) is None
    assert _tables(empty_url) == set()

    upgrade(empty_url)
    assert current_revision(empty_url) == head_revision()
    assert _tables(empty_url) == TABLES
    engine = make_engine(empty_url)
    try:
        with engine.connect() as conn:
            ctx = MigrationContext.configure(conn, opts={"compare_type": True})
            assert compare_metadata(ctx, Base.metadata) == []  # migrations == models
    finally:
        engine.dispose()
    upgrade(empty_url)  # idempotent at head

    downgrade(empty_url, "base")
    assert current_revision(empty_url) is None
    assert _tables(empty_url) == set()
    upgrade(empty_url)  # and back up again
    assert _tables(empty_url) == TABLES


def test_store_refuses_a_database_at_the_wrong_revision(empty_url: str) -> None:
    message = re.escape(f"at revision base (empty), code needs {head_revision()}: ") + (
        r"run `scm-calib db upgrade`"
    )
    with pytest.raises(SchemaVersionError, match=message):
        Store.open(empty_url)

    upgrade(empty_url)
    engine = make_engine(empty_url)
    try:
        with engine.begin() as conn:
            conn.execute(sa.text("UPDATE alembic_version SET version_num = 'ffff'"))
    finally:
        engine.dispose()
    with pytest.raises(SchemaVersionError, match="at revision ffff, code needs 0012") as info:
        Store.open(empty_url)
    assert info.value.current == "ffff" and info.value.head == "0012"

    engine = make_engine(empty_url)
    try:
        with engine.begin() as conn:
            conn.execute(sa.text(f"UPDATE alembic_version SET version_num = '{head_revision()}'"))
    finally:
        engine.dispose()
    with Store.open(empty_url) as store:
        assert store.studies.list().total == 0


def test_cli_db_commands(empty_url: str) -> None:
    runner = CliRunner()

    res = runner.invoke(cli, ["db", "current", "--url", empty_url])
    assert res.exit_code == 1 and "revision base" in res.output and "db upgrade" in res.output

    res = runner.invoke(cli, ["db", "upgrade", "--url", empty_url])
    assert res.exit_code == 0, res.output
    assert f"base -> {head_revision()}" in res.output

    res = runner.invoke(cli, ["db", "current", "--url", empty_url])
    assert (
        res.exit_code == 0
        and f"revision {head_revision()}" in res.output
        and "up to date" in res.output
    )

    res = runner.invoke(cli, ["db", "downgrade", "base", "--url", empty_url])
    assert res.exit_code == 0 and f"{head_revision()} -> base" in res.output
    assert current_revision(empty_url) is None


def test_cli_db_upgrade_uses_settings_url(tmp_path, monkeypatch) -> None:
    from services.config import get_settings

    url = f"sqlite:///{tmp_path / 'from-env.db'}"
    monkeypatch.setenv("SCM_CALIB_DATABASE_URL", url)
    get_settings.cache_clear()
    try:
        res = CliRunner().invoke(cli, ["db", "upgrade"])
        assert res.exit_code == 0, res.output
        assert current_revision(url) == "0012"
    finally:
        get_settings.cache_clear()


def test_upgrade_0001_to_0002_keeps_studies_as_calibrations(empty_url: str) -> None:
    """Studies stored before sensitivity studies existed become kind "tmcmc" (0011 names it
    "calibration"); the downgrade keeps them too."""
    upgrade(empty_url, "0001")
    engine = make_engine(empty_url)
    insert = sa.text(
        "INSERT INTO studies (name, status, case_spec, priors, sampler, simulator, seed, "
        "n_samples, model_runs, failed_runs, created_at, updated_at) VALUES ('old', 'completed', "
        "'{}', '{}', '{}', '{}', 3, 10, 0, 0, :t, :t)"
    )
    try:
        with engine.begin() as conn:
            conn.execute(insert, {"t": "2025-01-01 00:00:00"})
        upgrade(empty_url, "0010")
        with engine.connect() as conn:
            row = conn.execute(sa.text("SELECT name, kind, result FROM studies")).one()
        assert tuple(row) == ("old", "tmcmc", None)
        upgrade(empty_url)
        with engine.connect() as conn:
            assert conn.execute(sa.text("SELECT kind FROM studies")).scalar() == "calibration"
        downgrade(empty_url, "0001")
        with engine.connect() as conn:
            assert conn.execute(sa.text("SELECT name FROM studies")).scalars().all() == ["old"]
    finally:
        engine.dispose()


def test_upgrade_0002_to_0003_moves_raw_bytes_into_chunks_and_back(empty_url: str) -> None:
    """A dataset stored at 0002 with 2.5 MiB of raw bytes keeps them at 0003 (three chunks,
    read back whole by the store) and again after a downgrade to 0002."""
    upgrade(empty_url, "0002")
    raw = bytes(range(256)) * (10 * 1024)  # 2.5 MiB
    engine = make_engine(empty_url)
    insert = sa.text(
        "INSERT INTO datasets (content_hash, name, source_kind, size_bytes, raw, meta, processed,"
        " created_at) VALUES ('h', 'old', 'timeseries', :n, :raw, '{}', '{}', :t)"
    )
    try:
        with engine.begin() as conn:
            conn.execute(insert, {"n": len(raw), "raw": raw, "t": "2025-01-01 00:00:00"})
        upgrade(empty_url)
        with engine.connect() as conn:
            seqs = conn.execute(sa.text("SELECT seq FROM dataset_chunks ORDER BY seq")).scalars()
            assert list(seqs) == [0, 1, 2]
        with Store.open(empty_url) as store:
            assert store.datasets.raw(1) == raw
        downgrade(empty_url, "0002")
        with engine.connect() as conn:
            assert conn.execute(sa.text("SELECT raw FROM datasets")).scalar_one() == raw
    finally:
        engine.dispose()


def test_0004_accepts_any_registered_kind_and_refuses_to_downgrade_over_new_ones(
    empty_url: str,
) -> None:
    """From 0004 the kind is the registry's business (no CHECK): a study of a new kind can be
    stored with its payload; going back to 0003 refuses while it exists, then works once it is
    deleted, and 0003's CHECK is back."""
    upgrade(empty_url, "0005")
    engine = make_engine(empty_url)
    insert = sa.text(
        "INSERT INTO studies (name, kind, status, case_spec, priors, sampler, simulator, seed, "
        "n_samples, model_runs, failed_runs, created_at, updated_at, payload) VALUES "
        "(:n, :k, 'queued', '{}', '{}', '{}', '{}', 3, 10, 0, 0, :t, :t, :p)"
    )
    row = {"t": "2025-01-01 00:00:00", "p": '{"update_of": 1}'}
    try:
        with engine.begin() as conn:
            conn.execute(insert, {**row, "n": "old", "k": "tmcmc"})
            conn.execute(insert, {**row, "n": "new", "k": "update"})
        with pytest.raises(RuntimeError, match=r"1 studies are of kinds .* \(update\)"):
            downgrade(empty_url, "0003")
        assert current_revision(empty_url) == "0004"  # 0005 -> 0004 went, 0004 -> 0003 refused
        with engine.begin() as conn:
            conn.execute(sa.text("DELETE FROM studies WHERE kind = 'update'"))
        downgrade(empty_url, "0003")
        with engine.connect() as conn:
            assert conn.execute(sa.text("SELECT name FROM studies")).scalars().all() == ["old"]
        old_insert = sa.text(
            "INSERT INTO studies (name, kind, status, case_spec, priors, sampler, simulator, "
            "seed, n_samples, model_runs, failed_runs, created_at, updated_at) VALUES "
            "('x', 'update', 'queued', '{}', '{}', '{}', '{}', 3, 10, 0, 0, :t, :t)"
        )
        with pytest.raises(sa.exc.IntegrityError), engine.begin() as conn:
            conn.execute(old_insert, {"t": row["t"]})
    finally:
        engine.dispose()


def test_0005_gives_existing_studies_version_0_and_events_raise_it(empty_url: str) -> None:
    """A study stored at 0004 reads version 0 at 0005; an event appended for it raises the
    version by one (the ETag's source); going back to 0004 drops the column."""
    upgrade(empty_url, "0004")
    engine = make_engine(empty_url)
    try:
        with engine.begin() as conn:
            conn.execute(
                sa.text(
                    "INSERT INTO studies (name, kind, status, case_spec, priors, sampler, "
                    "simulator, seed, n_samples, model_runs, failed_runs, created_at, "
                    "updated_at) VALUES ('old', 'tmcmc', 'queued', '{}', '{}', '{}', '{}', 3, "
                    "10, 0, 0, '2025-01-01 00:00:00', '2025-01-01 00:00:00')"
                )
            )
        upgrade(empty_url)
        with Store.open(empty_url) as store:
            (study,) = store.studies.list().items
            assert study.version == 0 and store.studies.version(study.id) == 0
            store.events.append(study.id, "note", {"why": "test"})
            assert store.studies.version(study.id) == 1
            assert store.studies.get(study.id).updated_at > study.updated_at
        downgrade(empty_url, "0004")
        cols = {c["name"] for c in sa.inspect(engine).get_columns("studies")}
        assert "version" not in cols and "payload" in cols
    finally:
        engine.dispose()


def test_0006_derives_the_study_documents_from_the_case_and_back(empty_url: str) -> None:
    """0006 drops the copies of the case (priors, sampler, simulator) and moves a screening's
    design settings into its payload: what the API shows of both studies is what 0005 had
    stored; the downgrade puts the same documents back."""
    case = load_case(EXAMPLES / "quick.toml")
    design = sensitivity_design(case, MorrisSettings(3, 4, 9))
    settings = {
        "method": "morris",
        "r": 3,
        "levels": 4,
        "joint_k": True,
        "bounds": {p["name"]: [p["lower"], p["upper"]] for p in design.factor_box()["parameters"]},
    }
    stored = {
        "tmcmc": (case.prior().to_dict(), case.tmcmc_settings().to_dict(), None),
        "morris": (design.factor_box(), settings, None),
    }
    upgrade(empty_url, "0005")
    engine = make_engine(empty_url)
    insert = sa.text(
        "INSERT INTO studies (name, kind, status, case_spec, priors, sampler, simulator, seed, "
        "n_samples, model_runs, failed_runs, created_at, updated_at, payload) VALUES "
        "(:k, :k, 'queued', :c, :pr, :sa, :si, 9, 21, 0, 0, :t, :t, :p)"
    )
    try:
        with engine.begin() as conn:
            for kind, (priors, sampler, payload) in stored.items():
                conn.execute(
                    insert,
                    {
                        "k": kind,
                        "c": json.dumps(case.to_dict()),
                        "pr": json.dumps(priors),
                        "sa": json.dumps(sampler),
                        "si": json.dumps(dict(case.simulator)),
                        "t": "2025-01-01 00:00:00",
                        "p": payload,
                    },
                )
        upgrade(empty_url)
        with Store.open(empty_url) as store:
            for study in store.studies.list().items:
                priors, sampler, _ = stored[study.name]  # the name is the kind as stored
                terms = study_terms(study)
                assert (terms.priors, terms.sampler) == (priors, sampler)
                assert terms.simulator == dict(case.simulator)
                assert study.kind == {"tmcmc": "calibration", "morris": "sensitivity"}[study.name]
                assert study.payload == ({"design": settings} if study.name == "morris" else None)
        downgrade(empty_url, "0005")
        with engine.connect() as conn:
            rows = conn.execute(sa.text("SELECT kind, priors, sampler, payload FROM studies"))
            for kind, priors, sampler, payload in rows:
                assert (_json(priors), _json(sampler)) == stored[kind][:2]
                assert _json(payload) is None
    finally:
        engine.dispose()


def _json(value):
    """A JSON column's value as read by a text query (a string on SQLite, parsed on PG)."""
    return json.loads(value) if isinstance(value, str) else value


def test_0007_writes_the_old_sampler_defaults_into_stored_cases(empty_url: str) -> None:
    """A case stored before 0007 without the form's keys (the old to_dict left out
    ``resampling`` when systematic; older ones ``proposal_scale``, ``delayed_acceptance`` ...)
    meant the old defaults: after the upgrade the study's sampler is still exactly that
    (resample-move, plain steps, linear walk, systematic resampling), not the new study
    defaults, and a case that named its form keeps it."""
    case = load_case(EXAMPLES / "quick.toml").to_dict()
    old = dict(case, sampler={"n_samples": 21, "n_steps": 3})  # form keys left out
    named = dict(
        case,
        sampler={"n_samples": 21, "moves": "waste-free", "resampling": "multinomial"},
    )
    upgrade(empty_url, "0006")
    engine = make_engine(empty_url)
    insert = sa.text(
        "INSERT INTO studies (name, kind, status, case_spec, seed, n_samples, model_runs, "
        "failed_runs, created_at, updated_at) VALUES "
        "(:n, 'tmcmc', 'queued', :c, 9, 21, 0, 0, :t, :t)"
    )
    try:
        with engine.begin() as conn:
            for name, doc in (("old", old), ("named", named)):
                conn.execute(insert, {"n": name, "c": json.dumps(doc), "t": "2025-01-01 00:00:00"})
        upgrade(empty_url)
        with Store.open(empty_url) as store:
            by_name = {s.name: study_terms(s).sampler for s in store.studies.list().items}
        assert by_name["old"]["moves"] == "resample-move" and by_name["old"]["n_steps"] == 3
        assert by_name["old"]["delayed_acceptance"] is False
        assert by_name["old"]["surrogate_steps"] == 1
        assert by_name["old"]["proposal_scale"] == "linear"
        assert by_name["old"]["resampling"] == "systematic"
        # a named form keeps its keys; what it left out is filled with the old meaning too
        assert by_name["named"]["moves"] == "waste-free"
        assert by_name["named"]["resampling"] == "multinomial"
        assert by_name["named"]["delayed_acceptance"] is False
        downgrade(empty_url, "0006")
        upgrade(empty_url)  # the round trip changes nothing more
        with Store.open(empty_url) as store:
            again = {s.name: study_terms(s).sampler for s in store.studies.list().items}
        assert again == by_name
    finally:
        engine.dispose()


def test_0008_writes_no_jumps_into_stored_cases_that_left_them_out(empty_url: str) -> None:
    """A case stored before 0008 without ``surrogate_jumps`` meant none (0.0), also with
    ``moves = "waste-free"``, whose form now has jumps: after the upgrade its sampler still has
    none, its fingerprint is the one it had, and a case that named a share keeps it."""
    case = load_case(EXAMPLES / "quick.toml").to_dict()
    form = {"delayed_acceptance": True, "surrogate_steps": 40, "proposal_scale": "log"}
    old_sampler = {"n_samples": 21, "moves": "waste-free", "resampling": "multinomial", **form}
    old = dict(case, sampler=old_sampler)
    named = dict(case, sampler={**old_sampler, "surrogate_jumps": 0.3})
    before = CaseDefinition.from_dict(dict(old, sampler={**old_sampler, "surrogate_jumps": 0.0}))
    upgrade(empty_url, "0007")
    engine = make_engine(empty_url)
    insert = sa.text(
        "INSERT INTO studies (name, kind, status, case_spec, seed, n_samples, model_runs, "
        "failed_runs, created_at, updated_at) VALUES "
        "(:n, 'tmcmc', 'queued', :c, 9, 21, 0, 0, :t, :t)"
    )
    try:
        with engine.begin() as conn:
            for name, doc in (("old", old), ("named", named)):
                conn.execute(insert, {"n": name, "c": json.dumps(doc), "t": "2025-01-01 00:00:00"})
        upgrade(empty_url)
        with Store.open(empty_url) as store:
            studies = {s.name: s for s in store.studies.list().items}
            by_name = {name: study_terms(s).sampler for name, s in studies.items()}
            stored = CaseDefinition.from_dict(studies["old"].case)
        assert by_name["old"]["surrogate_jumps"] == 0.0
        assert by_name["named"]["surrogate_jumps"] == 0.3
        assert stored.fingerprint() == before.fingerprint()
        downgrade(empty_url, "0007")
        upgrade(empty_url)  # the round trip changes nothing more
        with Store.open(empty_url) as store:
            again = {s.name: study_terms(s).sampler for s in store.studies.list().items}
        assert again == by_name
    finally:
        engine.dispose()


def test_0009_adds_heartbeats_and_batch_run_counts_and_takes_them_back(empty_url: str) -> None:
    upgrade(empty_url, "0008")
    assert "heartbeats" not in _tables(empty_url)
    upgrade(empty_url)
    engine = make_engine(empty_url)
    try:
        columns = {c["name"] for c in sa.inspect(engine).get_columns("work_batches")}
        assert "model_runs" in columns and "heartbeats" in _tables(empty_url)
    finally:
        engine.dispose()
    downgrade(empty_url, "0008")
    engine = make_engine(empty_url)
    try:
        columns = {c["name"] for c in sa.inspect(engine).get_columns("work_batches")}
        assert "model_runs" not in columns and "heartbeats" not in _tables(empty_url)
    finally:
        engine.dispose()


def _study_columns_and_indexes(url: str) -> tuple[set[str], set[str]]:
    engine = make_engine(url)
    try:
        inspector = sa.inspect(engine)
        return (
            {c["name"] for c in inspector.get_columns("studies")},
            {i["name"] for i in inspector.get_indexes("studies")},
        )
    finally:
        engine.dispose()


def test_0010_adds_run_groups_and_takes_them_back(empty_url: str) -> None:
    upgrade(empty_url, "0009")
    assert "run_group" not in _study_columns_and_indexes(empty_url)[0]
    upgrade(empty_url)
    columns, indexes = _study_columns_and_indexes(empty_url)
    assert "run_group" in columns and "ix_studies_run_group" in indexes
    downgrade(empty_url, "0009")
    assert "run_group" not in _study_columns_and_indexes(empty_url)[0]


def test_0011_names_the_kinds_as_the_user_meets_them_and_back(empty_url: str) -> None:
    """Studies stored as "tmcmc" and "morris" load as "calibration" and "sensitivity" (the
    store lists them by the new names), a row written without a kind is a calibration, and
    the downgrade gives the old names back."""
    upgrade(empty_url, "0010")
    engine = make_engine(empty_url)
    insert = sa.text(
        "INSERT INTO studies (name, kind, status, case_spec, seed, n_samples, model_runs, "
        "failed_runs, created_at, updated_at) VALUES (:n, :k, 'queued', '{}', 9, 21, 0, 0, :t, :t)"
    )
    t = "2025-01-01 00:00:00"
    try:
        with engine.begin() as conn:
            for kind in ("tmcmc", "morris", "update", "tmcmc"):
                conn.execute(insert, {"n": kind, "k": kind, "t": t})
        upgrade(empty_url)
        with Store.open(empty_url) as store:
            kinds = sorted(s.kind for s in store.studies.list().items)
            assert kinds == ["calibration", "calibration", "sensitivity", "update"]
            assert store.studies.list(kind="calibration").total == 2
            assert store.studies.list(kind="tmcmc").total == 0
        no_kind = sa.text(
            "INSERT INTO studies (name, status, case_spec, seed, n_samples, model_runs, "
            "failed_runs, created_at, updated_at) VALUES ('x', 'queued', '{}', 1, 1, 0, 0, :t, :t)"
        )
        with engine.begin() as conn:
            conn.execute(no_kind, {"t": t})
            assert conn.execute(sa.text("SELECT kind FROM studies WHERE name = 'x'")).scalar() == (
                "calibration"
            )
            conn.execute(sa.text("DELETE FROM studies WHERE name = 'x'"))
        downgrade(empty_url, "0010")
        with engine.connect() as conn:
            rows = conn.execute(sa.text("SELECT name, kind FROM studies")).all()
        assert all(name == kind for name, kind in rows) and len(rows) == 4
    finally:
        engine.dispose()


def test_0012_gives_updates_and_predictions_their_parent_and_takes_it_back(
    empty_url: str,
) -> None:
    """An update's ``update_of`` and a prediction's ``study_id`` become the indexed
    ``parent_id`` the store lists them by; other studies have none; the downgrade drops it."""
    upgrade(empty_url, "0011")
    engine = make_engine(empty_url)
    insert = sa.text(
        "INSERT INTO studies (name, kind, status, case_spec, payload, seed, n_samples, "
        "model_runs, failed_runs, created_at, updated_at) "
        "VALUES (:n, :k, 'completed', '{}', :p, 1, 2, 0, 0, :t, :t)"
    )
    t = "2025-01-01 00:00:00"
    rows = [
        ("c", "calibration", None),
        ("u", "update", {"update_of": 1}),
        ("p", "prediction", {"study_id": 2, "conditions": None, "pooled_with": []}),
        ("s", "sensitivity", {"design": {"study_id": 1}}),
        ("q", "prediction", {"study_id": 1}),
    ]
    try:
        with engine.begin() as conn:
            for name, kind, payload in rows:
                doc = None if payload is None else json.dumps(payload)
                conn.execute(insert, {"n": name, "k": kind, "p": doc, "t": t})
        upgrade(empty_url)
        columns, indexes = _study_columns_and_indexes(empty_url)
        assert "parent_id" in columns and "ix_studies_parent_id" in indexes
        with Store.open(empty_url) as store:
            parents = {s.name: s.parent_id for s in store.studies.list().items}
            assert parents == {"c": None, "u": 1, "p": 2, "s": None, "q": 1}
            made = store.studies.list(kind="prediction", parent=1).items
            assert [s.name for s in made] == ["q"]
            assert store.studies.list_versions(parent=1)[0] == 2
        downgrade(empty_url, "0011")
        assert "parent_id" not in _study_columns_and_indexes(empty_url)[0]
    finally:
        engine.dispose()
