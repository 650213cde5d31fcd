"""Test-session setup shared by every test package."""

import pytest

from scm_core.simulator.jit_cache import ensure_fresh_cache


@pytest.fixture(scope="session", autouse=True)
def _fresh_simulator_cache():
    """Tests that call jitted simulator functions directly (not through the entry points,
    which check it themselves) load no cached code built from other sources."""
    ensure_fresh_cache()
