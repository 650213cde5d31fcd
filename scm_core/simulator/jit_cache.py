"""Keep numba's on-disk cache of the simulator consistent with the simulator's sources.

numba's cache (``cache=True``) checks only the source file of the function it compiled. A change
in a jitted callee defined in another module (the kernel calls contact, deformation and geometry
functions) or in a module constant read at compile time (the layout indices) is not seen, and the
caller's cached machine code would silently run the old physics (numba's "Notes on caching":
cache invalidation does not follow symbols defined in other files). That happens whenever the
package is updated in place (``git pull`` on an editable install).

:func:`ensure_fresh_cache` keys the cache on a SHA-256 digest of every source file of the
package, kept in a stamp file beside numba's index files: when the digest differs, every cached
simulator function is flushed (numba's own ``flush``) before anything is loaded or compiled, and
the stamp is rewritten. The simulator's entry points call it once per process.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib
import os
import pkgutil
from collections.abc import Iterable
from pathlib import Path
from types import ModuleType

from numba.core.dispatcher import Dispatcher

__all__ = ["STAMP_NAME", "ensure_fresh_cache", "kernel_is_cached", "sources_digest"]

#: the stamp file written in each cache directory of the simulator's functions
STAMP_NAME = "scm_simulator_sources.sha256"

PACKAGE_DIR = Path(__file__).resolve().parent


def sources_digest(package_dir: Path = PACKAGE_DIR) -> str:
    """SHA-256 over the names and bytes of the package's ``*.py`` files, in name order."""
    h = hashlib.sha256()
    for path in sorted(package_dir.glob("*.py")):
        h.update(path.name.encode())
        h.update(b"\0")
        h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


def _cached_dispatchers(modules: Iterable[ModuleType]) -> list[Dispatcher]:
    """The jitted functions with an on-disk cache defined in ``modules``."""
    found = []
    for mod in modules:
        for obj in vars(mod).values():
            if (
                isinstance(obj, Dispatcher)
                and obj.__module__ == mod.__name__
                and hasattr(getattr(obj, "_cache", None), "flush")
            ):
                found.append(obj)
    return found


def _simulator_modules() -> list[ModuleType]:
    """Every module of the package: a jitted caller's cached code holds its callees' code, so
    all of them are flushed together (a module split off later is not forgotten)."""
    return [
        importlib.import_module(f"{__package__}.{m.name}")
        for m in pkgutil.iter_modules([str(PACKAGE_DIR)])
    ]


def refresh(dispatchers: Iterable[Dispatcher], digest: str) -> list[Path]:
    """Flush the cache of ``dispatchers`` in every cache directory whose stamp is not
    ``digest`` and stamp it; returns the directories flushed. A directory that cannot be
    written is flushed (if possible) and left unstamped, so it is checked again next time."""
    by_dir: dict[Path, list[Dispatcher]] = {}
    for d in dispatchers:
        by_dir.setdefault(Path(d._cache._cache_path), []).append(d)
    flushed = []
    for cache_dir, members in sorted(by_dir.items()):
        stamp = cache_dir / STAMP_NAME
        try:
            current = stamp.read_text(encoding="ascii").strip()
        except (OSError, UnicodeDecodeError):
            current = None
        if current == digest:
            continue
        for d in members:
            # OSError: nothing cached there yet, or not writable (then nothing is saved either)
            with contextlib.suppress(OSError):
                d._cache.flush()
        flushed.append(cache_dir)
        try:
            cache_dir.mkdir(parents=True, exist_ok=True)
            tmp = cache_dir / f"{STAMP_NAME}.{os.getpid()}.tmp"
            tmp.write_text(digest + "\n", encoding="ascii")
            os.replace(tmp, stamp)  # atomic: a concurrent process sees the old or the new stamp
        except OSError:
            pass
    return flushed


@functools.cache
def ensure_fresh_cache() -> bool:
    """Flush numba's cached simulator code if the simulator's sources changed since it was
    cached (see the module doc). Once per process; True if something was flushed."""
    return bool(refresh(_cached_dispatchers(_simulator_modules()), sources_digest()))


def kernel_is_cached() -> bool | None:
    """Whether numba's disk cache holds the kernel compiled from these sources (True), or
    the first simulation of this process will compile it, about 20 s (False); None where
    numba's cache is not laid out as known here. Ask before the first simulation: a flush
    (:func:`ensure_fresh_cache`) leaves an empty index behind."""
    from . import kernel

    try:
        cache = kernel.run_swt._cache
        index = Path(cache._cache_file._index_path)
        stamp = Path(cache._cache_path) / STAMP_NAME
    except AttributeError:
        return None
    try:
        return index.is_file() and stamp.read_text(encoding="ascii").strip() == sources_digest()
    except (OSError, UnicodeDecodeError):
        return False
