"""The measured responses of a single-wheel test, declared once.

A response has a key (the paper's symbol: ``F``, ``T``, ``z``), the lab-file column it is
measured as, its words, its SI unit, the quantity its column's unit converts as, and the unit
a figure draws it in. The lab files' readers, the checks, the case's prediction-error sigmas
(``sigma_<key>``), the study's likelihood, the figures and the exports take their lists from
:data:`RESPONSES`; the lab columns' other spellings are the log format's
(:data:`scm_core.signals.logformat.COLUMNS`).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "COLUMN_OF",
    "KEY_OF_COLUMN",
    "N_RESPONSES",
    "RESPONSES",
    "RESPONSE_KEYS",
    "Response",
    "response",
]


@dataclass(frozen=True)
class Response:
    """key: the symbol (``F``); column: the lab file's column (``drawbar_pull``); words: what a
    message calls it; unit: its SI unit; quantity: the unit family of its column
    (:mod:`~scm_core.signals.units`); shown_in, scale: the unit a figure draws it in and the
    factor from SI to it (sinkage in mm: 1000)."""

    key: str
    column: str
    words: str
    unit: str
    quantity: str
    shown_in: str
    scale: float = 1.0

    @property
    def sigma(self) -> str:
        """The case's name of its prediction-error standard deviation (``sigma_F``)."""
        return f"sigma_{self.key}"

    @property
    def offset(self) -> str:
        """The rig's name of the start of its averaging window (``offset_F`` [s])."""
        return f"offset_{self.key}"

    @property
    def label(self) -> str:
        """A figure's axis label: "sinkage z [mm]"."""
        return f"{self.words} {self.key} [{self.shown_in}]"


#: every response a study can measure and fit, in the order they are stored and drawn
RESPONSES: tuple[Response, ...] = (
    Response("F", "drawbar_pull", "drawbar pull", "N", "force", "N"),
    Response("T", "torque", "torque", "N m", "torque", "N m"),
    Response("z", "sinkage", "sinkage", "m", "length", "mm", 1000.0),
)
RESPONSE_KEYS: tuple[str, ...] = tuple(r.key for r in RESPONSES)
N_RESPONSES = len(RESPONSES)
#: lab column -> response key, and back
KEY_OF_COLUMN: dict[str, str] = {r.column: r.key for r in RESPONSES}
COLUMN_OF: dict[str, str] = {r.key: r.column for r in RESPONSES}


def response(key: str) -> Response:
    """The response of ``key`` (``F``, ``T``, ``z``)."""
    for r in RESPONSES:
        if r.key == key:
            return r
    raise KeyError(f"no response {key!r}; responses: {', '.join(RESPONSE_KEYS)}")
