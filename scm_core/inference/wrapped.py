"""A wrapper around a batch likelihood that keeps what the sampler's accelerations look for.

Early rejection runs a likelihood's parts (``run_part``, :mod:`scm_core.inference.early_rejection`)
and delayed acceptance asks it for its responses (``from_responses``,
:mod:`scm_core.inference.surrogate`); a wrapper that only defined ``__call__`` would hide them
and silently turn both off. Subclasses put their own work around every model evaluation in
:meth:`WrappedLikelihood.around`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["WrappedLikelihood"]


class WrappedLikelihood:
    """``likelihood`` with :meth:`around` applied to each call and each part run; every other
    member is the wrapped likelihood's."""

    def __init__(self, likelihood: Callable[[Any], Any]) -> None:
        self.likelihood = likelihood

    def around(self, evaluate: Callable[[], Any]) -> Any:
        """Run one model evaluation (override to check, time or count it)."""
        return evaluate()

    def __call__(self, X):
        return self.around(lambda: self.likelihood(X))

    def run_part(self, X, k: int):
        return self.around(lambda: self.likelihood.run_part(X, k))

    def __getattr__(self, name: str) -> Any:
        if name == "likelihood":  # not set yet (e.g. while unpickling)
            raise AttributeError(name)
        return getattr(self.likelihood, name)
