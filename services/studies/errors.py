"""The one error of the study service: a request that cannot be accepted."""

from __future__ import annotations

__all__ = ["StudyRequestError"]


class StudyRequestError(ValueError):
    """A study request that cannot be accepted; the message (one line) starts with the
    request's field (``dataset_ids``, ``bounds.phi``, ``n_samples`` ...)."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))
