"""numba's disk cache of the simulator follows the simulator's sources (jit_cache).

numba checks only the file of the function it compiled; ``ensure_fresh_cache`` flushes the
simulator's cached code when any simulator source changed. Each run below is a fresh process
with its own ``NUMBA_CACHE_DIR``, so the repository's cache is not touched.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from scm_core.simulator.jit_cache import STAMP_NAME, sources_digest

ROOT = Path(__file__).resolve().parents[2]

PROBE = """
import json
from scm_core.simulator import SoilParams, jit_cache, kernel, pack_many
flushed = jit_cache.ensure_fresh_cache()
kernel.grid_shape(pack_many([SoilParams()])[0])
stats = kernel.grid_shape.stats
print(json.dumps({"flushed": flushed, "hits": sum(stats.cache_hits.values()),
                  "misses": sum(stats.cache_misses.values())}))
"""


def _probe(cache_dir: Path) -> dict:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir), "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        [sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_cache_is_reused_while_sources_match_and_flushed_when_they_change(tmp_path):
    first = _probe(tmp_path)
    assert first == {"flushed": True, "hits": 0, "misses": 1}  # nothing stamped yet: compiled
    stamps = list(tmp_path.rglob(STAMP_NAME))
    assert len(stamps) == 1
    assert stamps[0].read_text().strip() == sources_digest()

    again = _probe(tmp_path)
    assert again == {"flushed": False, "hits": 1, "misses": 0}  # same sources: loaded

    # the cache was built from other sources (as after an update of a callee's module)
    stamps[0].write_text("0" * 64 + "\n")
    changed = _probe(tmp_path)
    assert changed == {"flushed": True, "hits": 0, "misses": 1}  # stale code not loaded
    assert stamps[0].read_text().strip() == sources_digest()


def test_digest_follows_every_python_source_and_nothing_else(tmp_path):
    (tmp_path / "a.py").write_text("X = 1\n")
    (tmp_path / "b.py").write_text("Y = 2\n")
    base = sources_digest(tmp_path)
    assert sources_digest(tmp_path) == base
    (tmp_path / "notes.txt").write_text("not code")
    assert sources_digest(tmp_path) == base
    (tmp_path / "b.py").write_text("Y = 3\n")
    assert sources_digest(tmp_path) != base
    (tmp_path / "b.py").write_text("Y = 2\n")
    assert sources_digest(tmp_path) == base
    (tmp_path / "c.py").write_text("")
    assert sources_digest(tmp_path) != base


def test_every_cached_function_of_the_package_is_flushed_with_the_rest():
    """A caller's cached machine code holds its callees' (numba does not follow them across
    files), so every function the package caches on disk is flushed when any source changes:
    found by reading the sources for ``@njit(cache=True ...)``, not by asking the module list
    (which once named four modules and left the flows, the side and erosion stale)."""
    import re

    from scm_core.simulator import jit_cache

    pattern = re.compile(r"@njit\(cache=True[^)]*\)\s*\ndef (\w+)")
    declared = {
        f"scm_core.simulator.{path.stem}.{name}"
        for path in sorted(jit_cache.PACKAGE_DIR.glob("*.py"))
        for name in pattern.findall(path.read_text())
    }
    flushed = {
        f"{d.__module__}.{d.__name__}"
        for d in jit_cache._cached_dispatchers(jit_cache._simulator_modules())
    }
    assert "scm_core.simulator.flow.flow_and_deposit" in declared
    assert len(declared) > 30
    assert declared <= flushed, sorted(declared - flushed)
