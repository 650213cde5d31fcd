"""Migrations: empty -> head -> base on SQLite and PostgreSQL, the migrated schema equals the
models, the store refuses a database at the wrong revision, and the ``scm-calib db`` commands."""

from __future__ import annotations

import re

import pytest
import sqlalchemy as sa
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from click.testing import CliRunner

from services.cli.main import cli
from services.store import SchemaVersionError, Store, current_revision, downgrade, upgrade
from services.store.engine import make_engine
from services.store.migrate import head_revision, migrations_dir
from services.store.models import Base

TABLES = {"datasets", "studies", "study_datasets", "stages", "work_batches", "samples", "events"}


def _tables(url: str) -> set[str]:
    engine = make_engine(url)
    try:
        return set(sa.inspect(engine).get_table_names()) - {"alembic_version"}
    finally:
        engine.dispose()


def test_migrations_directory_is_found() -> None:
    assert (migrations_dir() / "versions" / "0001_initial.py").is_file()
    assert head_revision() == "0001"


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
    with pytest.raises(SchemaVersionError, match="at revision ffff, code needs 0001") as info:
        Store.open(empty_url)
    assert info.value.current == "ffff" and info.value.head == "0001"

    engine = make_engine(empty_url)
    try:
        with engine.begin() as conn:
            conn.execute(sa.text("UPDATE alembic_version SET version_num = '0001'"))
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
    assert "base -> 0001" in res.output

    res = runner.invoke(cli, ["db", "current", "--url", empty_url])
    assert res.exit_code == 0 and "revision 0001" in res.output and "up to date" in res.output

    res = runner.invoke(cli, ["db", "downgrade", "base", "--url", empty_url])
    assert res.exit_code == 0 and "0001 -> base" in res.output
    assert current_revision(empty_url) is None


def test_cli_db_upgrade_uses_settings_url(tmp_path, monkeypatch) -> None:
    from services.config import get_settings

    url = f"sqlite:///{tmp_path / 'from-env.db'}"
    monkeypatch.setenv("SCM_CALIB_DATABASE_URL", url)
    get_settings.cache_clear()
    try:
        res = CliRunner().invoke(cli, ["db", "upgrade"])
        assert res.exit_code == 0, res.output
        assert current_revision(url) == "0001"
    finally:
        get_settings.cache_clear()
