"""The API tests' shared fixture: a fresh database per backend and a client on it."""

from __future__ import annotations

import pytest
from test_api_support import BACKENDS, api_client, fresh_database


@pytest.fixture(params=BACKENDS)
def env(request: pytest.FixtureRequest, tmp_path):
    """(client, database URL) on a fresh database of each backend; a module that needs another
    set-up defines its own ``env``."""
    with fresh_database(request.param, tmp_path) as url, api_client(url) as client:
        yield client, url
