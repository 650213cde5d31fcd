"""Service settings: defaults, environment, .env and TOML sources, tokens; and the store built
from them. Nothing is created on disk by reading the settings."""

from __future__ import annotations

import os

import pytest

from services.config import CONFIG_FILE_ENV, Settings, get_settings, hash_token, new_token
from services.store import SchemaVersionError, Store, upgrade


@pytest.fixture(autouse=True)
def clean_env(monkeypatch, tmp_path):
    for name in list(os.environ):
        if name.startswith("SCM_CALIB_"):
            monkeypatch.delenv(name)
    monkeypatch.chdir(tmp_path)  # no stray .env from the checkout
    get_settings.cache_clear()
    yield
    get_settings.cache_clear()


def test_defaults_are_embedded_sqlite_without_side_effects(tmp_path) -> None:
    s = Settings()
    assert s.database_url == "sqlite:///scm-calib-data/scm-calib.db"
    assert s.broker_url is None and s.embedded  # embedded default: no broker needed
    assert s.api_tokens == [] and not s.read_requires_token
    assert s.worker_concurrency >= 1 and s.lease_seconds == 300 and s.max_attempts == 3
    assert s.upload_max_bytes == 64 * 1024 * 1024
    assert list(tmp_path.iterdir()) == []  # no data dir created by reading settings


def test_environment_dotenv_and_toml(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("SCM_CALIB_DATA_DIR", str(tmp_path / "data"))
    monkeypatch.setenv("SCM_CALIB_BROKER_URL", "")
    monkeypatch.setenv("SCM_CALIB_MAX_ATTEMPTS", "5")
    s = Settings()
    assert s.database_url == f"sqlite:///{tmp_path / 'data' / 'scm-calib.db'}"
    assert s.broker_url is None and s.embedded and s.max_attempts == 5

    (tmp_path / ".env").write_text("SCM_CALIB_LEASE_SECONDS=42\nSCM_CALIB_MAX_ATTEMPTS=7\n")
    toml = tmp_path / "calib.toml"
    toml.write_text(
        'database_url = "postgresql://u@db/calib"\nlease_seconds = 10\nworker_concurrency = 3\n'
    )
    monkeypatch.setenv(CONFIG_FILE_ENV, str(toml))
    s = Settings()
    assert s.database_url == "postgresql://u@db/calib"  # from TOML
    assert s.worker_concurrency == 3  # from TOML
    assert s.lease_seconds == 42  # .env beats TOML
    assert s.max_attempts == 5  # environment beats .env

    monkeypatch.setenv(CONFIG_FILE_ENV, str(tmp_path / "missing.toml"))
    with pytest.raises(FileNotFoundError, match=r"missing\.toml"):
        Settings()


def test_api_tokens_hashed_and_checked(monkeypatch) -> None:
    token, digest = new_token()
    assert digest == hash_token(token) and digest.startswith("sha256:") and len(digest) == 71
    monkeypatch.setenv("SCM_CALIB_API_TOKENS", f"{digest}, dev-plain-token")
    s = Settings()
    assert s.api_tokens == [digest, hash_token("dev-plain-token")]  # never kept in plain
    assert s.token_is_valid(token) and s.token_is_valid("dev-plain-token")
    assert not s.token_is_valid("nope") and not s.token_is_valid(None)
    assert not s.token_is_valid(digest)  # the hash itself is not a token
    monkeypatch.setenv("SCM_CALIB_API_TOKENS", f'["{digest}"]')
    assert Settings().api_tokens == [digest]


def test_get_settings_is_cached(monkeypatch) -> None:
    monkeypatch.setenv("SCM_CALIB_MAX_ATTEMPTS", "4")
    a = get_settings()
    monkeypatch.setenv("SCM_CALIB_MAX_ATTEMPTS", "9")
    assert get_settings() is a and a.max_attempts == 4
    get_settings.cache_clear()
    assert get_settings().max_attempts == 9


def test_store_from_settings(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("SCM_CALIB_DATA_DIR", str(tmp_path / "d"))
    monkeypatch.setenv("SCM_CALIB_LEASE_SECONDS", "12.5")
    settings = Settings()
    with pytest.raises(SchemaVersionError, match="scm-calib db upgrade"):
        Store.from_settings(settings)
    assert (tmp_path / "d").is_dir()  # the engine (not the settings) made the directory
    upgrade(settings.database_url)
    with Store.from_settings(settings) as store:
        assert store.db.lease_seconds == 12.5 and store.db.max_attempts == 3
        assert store.engine.url.database == str(tmp_path / "d" / "scm-calib.db")
