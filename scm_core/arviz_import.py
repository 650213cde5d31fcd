"""ArviZ, imported on use with its import-time notice silenced.

ArviZ 0.23 announces its 1.0 refactor with a FutureWarning when it is imported: five lines on
a user's terminal before any table (issue 69). The notice is for library authors, and this
project's calls are tested against the versions ``pyproject.toml`` allows.
"""

from __future__ import annotations

import warnings
from types import ModuleType

__all__ = ["arviz"]


def arviz() -> ModuleType:
    """The ``arviz`` module (slow to import the first time: import it where it is used)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz as az
    return az
