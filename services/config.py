"""Service settings: one pydantic-settings class, read from the environment.

Sources, highest priority first: keyword arguments, environment variables ``SCM_CALIB_*``, a
``.env`` file in the working directory, a TOML file named by ``SCM_CALIB_CONFIG_FILE`` (keys
without the prefix, e.g. ``database_url = "postgresql://..."``), then the defaults below.
Nothing is read or created at import time; :func:`get_settings` builds (and caches) the object.

Defaults give the embedded set-up's database: a SQLite file ``scm-calib.db`` in the data
directory (``./scm-calib-data/``, or ``$SCM_CALIB_DATA_DIR``). The directory is created when the
database engine is first made, not here.

API tokens
----------
``SCM_CALIB_API_TOKENS`` holds one or more tokens, comma-separated (or a JSON list). Store them
hashed: an entry ``sha256:<64 hex>`` is the SHA-256 of the token. Make a new one with::

    python -m services.config new-token

which prints the token (give it to the client, it is shown once) and the ``sha256:...`` line
(put it in the server's environment). A plain entry (without ``sha256:``) is accepted too and
hashed when the settings are loaded, which is handy for development only. Tokens are random
256-bit strings, so a fast hash is enough; comparison is constant-time.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import secrets
import sys
from functools import lru_cache
from pathlib import Path
from typing import Annotated, Any

from pydantic import Field, field_validator, model_validator
from pydantic_settings import (
    BaseSettings,
    NoDecode,
    PydanticBaseSettingsSource,
    SettingsConfigDict,
    TomlConfigSettingsSource,
)

__all__ = [
    "CONFIG_FILE_ENV",
    "TOKEN_HASH_PREFIX",
    "Settings",
    "get_settings",
    "hash_token",
    "new_token",
]

ENV_PREFIX = "SCM_CALIB_"
CONFIG_FILE_ENV = "SCM_CALIB_CONFIG_FILE"
TOKEN_HASH_PREFIX = "sha256:"
DEFAULT_DATA_DIR = Path("scm-calib-data")
DEFAULT_DB_FILE = "scm-calib.db"


def hash_token(token: str) -> str:
    """``sha256:<hex>`` of an API token, the form to put in ``SCM_CALIB_API_TOKENS``."""
    return TOKEN_HASH_PREFIX + hashlib.sha256(token.encode("utf-8")).hexdigest()


def new_token() -> tuple[str, str]:
    """A fresh random API token and its hash: ``(token, "sha256:...")``."""
    token = secrets.token_urlsafe(32)
    return token, hash_token(token)


def _is_hashed(entry: str) -> bool:
    hexpart = entry[len(TOKEN_HASH_PREFIX) :]
    return (
        entry.startswith(TOKEN_HASH_PREFIX)
        and len(hexpart) == 64
        and all(c in "0123456789abcdef" for c in hexpart.lower())
    )


class Settings(BaseSettings):
    """Configuration of the API, the workers, the store and the command line."""

    model_config = SettingsConfigDict(
        env_prefix=ENV_PREFIX,
        env_file=".env",
        env_file_encoding="utf-8",
        extra="ignore",
        validate_default=True,
    )

    data_dir: Path = Field(
        default=DEFAULT_DATA_DIR,
        description="Directory of the embedded SQLite database (and other local files).",
    )
    database_url: str = Field(
        default="",
        description=(
            "SQLAlchemy URL. Empty: sqlite:///<data_dir>/scm-calib.db. PostgreSQL: "
            "postgresql://user:pass@host/db (the psycopg 3 driver is selected automatically)."
        ),
    )
    broker_url: str | None = Field(
        default=None,
        description="Celery broker, e.g. redis://127.0.0.1:6379/0. None or empty (the default): "
        "embedded mode with a local process pool, no broker needed.",
    )
    api_tokens: Annotated[list[str], NoDecode] = Field(
        default_factory=list,
        description="Accepted API tokens, stored as sha256:<hex> (plain entries are hashed).",
    )
    read_requires_token: bool = Field(
        default=False, description="Require a token for read endpoints too (writes always do)."
    )
    dashboard: bool = Field(
        default=True,
        description="Serve the web dashboard at / (pages at /ui/...) with the API.",
    )
    worker_concurrency: int = Field(
        default_factory=lambda: os.cpu_count() or 1,
        ge=1,
        description="Processes of the local pool / Celery worker concurrency.",
    )
    lease_seconds: float = Field(
        default=300.0, gt=0, description="Lease of a work batch; workers heartbeat within it."
    )
    max_attempts: int = Field(
        default=3, ge=1, description="Leases of one batch before the study fails."
    )
    upload_max_bytes: int = Field(
        default=64 * 1024 * 1024, ge=1, description="Largest accepted SWT upload."
    )
    max_concurrent_uploads: int = Field(
        default=2,
        ge=1,
        description="Uploads parsed at once per API process; more answer 429 with Retry-After.",
    )
    # ---- limits (services/limits.py), checked before anything is stored or allocated
    max_samples_per_stage: int = Field(
        default=20_000, ge=10, description="Samples (chains) per TMCMC stage; Morris points."
    )
    max_stages: int = Field(default=100, ge=1, description="Tempering stages of a study.")
    max_batches_per_stage: int = Field(
        default=5_000, ge=1, description="Work batches one stage may be cut into."
    )
    max_datasets_per_study: int = Field(default=50, ge=1, description="Datasets of a study.")
    max_model_runs_per_study: int = Field(
        default=50_000_000,
        ge=1,
        description="Worst-case simulator runs of a study: samples x datasets x (1 + stages x "
        "Metropolis steps per chain).",
    )
    max_steps_per_run: int = Field(
        default=200_000, ge=10, description="Time steps of one simulator run (duration / dt)."
    )
    max_grid_cells: int = Field(
        default=5_000_000, ge=100, description="DEM cells of one simulator run."
    )
    max_output_rate: float = Field(
        default=1_000.0, gt=0, description="Output sample rate of a simulator run [Hz]."
    )
    max_json_depth: int = Field(
        default=32, ge=4, description="Nesting depth of a JSON body or metadata field."
    )

    @classmethod
    def settings_customise_sources(
        cls,
        settings_cls: type[BaseSettings],
        init_settings: PydanticBaseSettingsSource,
        env_settings: PydanticBaseSettingsSource,
        dotenv_settings: PydanticBaseSettingsSource,
        file_secret_settings: PydanticBaseSettingsSource,
    ) -> tuple[PydanticBaseSettingsSource, ...]:
        sources = [init_settings, env_settings, dotenv_settings]
        config_file = os.environ.get(CONFIG_FILE_ENV)
        if config_file:
            path = Path(config_file)
            if not path.is_file():
                raise FileNotFoundError(f"{CONFIG_FILE_ENV}={config_file}: no such file")
            sources.append(TomlConfigSettingsSource(settings_cls, toml_file=path))
        sources.append(file_secret_settings)
        return tuple(sources)

    @field_validator("broker_url", mode="before")
    @classmethod
    def _empty_broker(cls, value: Any) -> Any:
        if value is None or (isinstance(value, str) and value.strip().lower() in ("", "none")):
            return None
        return value

    @field_validator("api_tokens", mode="before")
    @classmethod
    def _split_tokens(cls, value: Any) -> Any:
        if isinstance(value, str):
            text = value.strip()
            if text.startswith("["):
                return json.loads(text)
            return [part.strip() for part in text.split(",") if part.strip()]
        return value

    @field_validator("api_tokens")
    @classmethod
    def _hash_tokens(cls, value: list[str]) -> list[str]:
        return [e.lower() if _is_hashed(e) else hash_token(e) for e in value]

    @model_validator(mode="after")
    def _default_database(self) -> Settings:
        if not self.database_url:
            path = (self.data_dir / DEFAULT_DB_FILE).expanduser()
            self.database_url = f"sqlite:///{path.as_posix()}"
        return self

    @property
    def embedded(self) -> bool:
        """True when no broker is configured: work runs in a local process pool."""
        return self.broker_url is None

    def token_is_valid(self, token: str | None) -> bool:
        """Whether ``token`` matches one of :attr:`api_tokens` (constant-time per entry)."""
        if not token:
            return False
        digest = hash_token(token)
        return any(hmac.compare_digest(digest, entry) for entry in self.api_tokens)


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process's settings, built on first call (``get_settings.cache_clear()`` to reload)."""
    return Settings()


def _main(argv: list[str]) -> int:
    if argv[:1] == ["new-token"]:
        token, digest = new_token()
        print(f"token (give to the client, shown once): {token}")
        print(f"server setting: SCM_CALIB_API_TOKENS={digest}")
        return 0
    print("usage: python -m services.config new-token", file=sys.stderr)
    return 2


if __name__ == "__main__":
    raise SystemExit(_main(sys.argv[1:]))
