"""The measured responses of a single-wheel test, declared once.

A response has a key (the paper's symbol: ``F``, ``T``, ``z``; ``Fy`` for a steered wheel's
lateral force), the lab-file column it is measured as, its words, its SI unit, the quantity its
column's unit converts as, and the unit a figure draws it in. The lab files' readers, the
checks, the case's prediction-error sigmas (``sigma_<key>``), the study's likelihood, the
figures and the exports take their lists from :data:`RESPONSES`; the lab columns' other
spellings are the log format's (:data:`scm_core.signals.logformat.COLUMNS`).

Responses are only ever appended to :data:`RESPONSES`: an array of simulated responses stored
with k values per dataset (a study stored before the later ones were declared: three, F, T and
z, before issue 70's Fy) holds the first k, and :func:`widened` reads it with the others NaN
("not simulated"), as a response a dataset did not measure is NaN.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "COLUMN_OF",
    "DEFAULT_KEYS",
    "KEY_OF_COLUMN",
    "N_FIRST",
    "N_RESPONSES",
    "RESPONSES",
    "RESPONSE_KEYS",
    "Response",
    "keys_for",
    "keys_of",
    "response",
    "widened",
]


@dataclass(frozen=True)
class Response:
    """key: the symbol (``F``); column: the lab file's column (``drawbar_pull``); words: what a
    message calls it; unit: its SI unit; quantity: the unit family of its column
    (:mod:`~scm_core.signals.units`); shown_in, scale: the unit a figure draws it in and the
    factor from SI to it (sinkage in mm: 1000); steered: zero for a wheel driven straight by
    symmetry (the lateral force), so a case fits it only when it names it; window: the
    response whose averaging window it is averaged over ("": its own); unit_required: a
    summary must state its unit (the others default to SI, as summaries always did; no file
    written before the lateral force was read relies on a default for it)."""

    key: str
    column: str
    words: str
    unit: str
    quantity: str
    shown_in: str
    scale: float = 1.0
    steered: bool = False
    window: str = ""
    unit_required: bool = False

    @property
    def sigma(self) -> str:
        """The case's name of its prediction-error standard deviation (``sigma_F``)."""
        return f"sigma_{self.key}"

    @property
    def offset(self) -> str:
        """The rig's name of the start of its averaging window (``offset_F`` [s]; the lateral
        force is averaged over the drawbar pull's)."""
        return f"offset_{self.window or self.key}"

    @property
    def label(self) -> str:
        """A figure's axis label: "sinkage z [mm]"."""
        return f"{self.words} {self.key} [{self.shown_in}]"


#: every response a study can measure and fit, in the order they are stored and drawn
RESPONSES: tuple[Response, ...] = (
    Response("F", "drawbar_pull", "drawbar pull", "N", "force", "N"),
    Response("T", "torque", "torque", "N m", "torque", "N m"),
    Response("z", "sinkage", "sinkage", "m", "length", "mm", 1000.0),
    # + against the side slip: a wheel sliding toward -y (slip_angle > 0) is pushed toward +y
    Response(
        "Fy",
        "lateral_force",
        "lateral force",
        "N",
        "force",
        "N",
        steered=True,
        window="F",
        unit_required=True,
    ),
)
RESPONSE_KEYS: tuple[str, ...] = tuple(r.key for r in RESPONSES)
N_RESPONSES = len(RESPONSES)
#: how many were declared at first (F, T, z): arrays stored and random numbers drawn per
#: response before the later ones were declared hold these
N_FIRST = 3


def keys_of(steered: bool) -> tuple[str, ...]:
    """The keys of the responses a run gives: every one for a steered wheel, else those that
    symmetry does not make zero (F, T, z)."""
    return tuple(r.key for r in RESPONSES if steered or not r.steered)


def keys_for(steered: bool, *named: Iterable[str]) -> tuple[str, ...]:
    """The keys of the responses to report, in :data:`RESPONSES` order: those a run gives
    (:func:`keys_of`) and any ``named`` (a case's fitted responses, a dataset's measured
    ones)."""
    wanted = set(keys_of(steered)).union(*named)
    return tuple(r.key for r in RESPONSES if r.key in wanted)


#: the responses a case fits when it names none: those a straight wheel gives
DEFAULT_KEYS: tuple[str, ...] = keys_of(steered=False)
#: lab column -> response key, and back
KEY_OF_COLUMN: dict[str, str] = {r.column: r.key for r in RESPONSES}
COLUMN_OF: dict[str, str] = {r.key: r.column for r in RESPONSES}


def response(key: str) -> Response:
    """The response of ``key`` (``F``, ``T``, ``z``, ``Fy``)."""
    for r in RESPONSES:
        if r.key == key:
            return r
    raise KeyError(f"no response {key!r}; responses: {', '.join(RESPONSE_KEYS)}")


def widened(values: ArrayLike, groups: int) -> NDArray[np.float64]:
    """Responses (..., k groups) stored with the first k of :data:`RESPONSES` per group (a
    dataset, a prediction's target) as (..., N_RESPONSES groups), the later ones NaN; an
    array already that wide is returned as it is. ValueError if the width is not k groups
    for a k in 1..N_RESPONSES."""
    a = np.asarray(values, dtype=float)
    if a.size == 0:  # no samples: nothing to read
        return np.empty((*a.shape[:-1], groups * N_RESPONSES))
    width = a.shape[-1] if a.ndim else 0
    k, rest = divmod(width, groups) if groups > 0 else (0, 1)
    if rest or not 0 < k <= N_RESPONSES:
        raise ValueError(
            f"responses {width} wide are not {groups} group(s) of at most {N_RESPONSES} values"
        )
    if k == N_RESPONSES:
        return a
    out = np.full((*a.shape[:-1], groups, N_RESPONSES), np.nan)
    out[..., :k] = a.reshape(*a.shape[:-1], groups, k)
    return out.reshape(*a.shape[:-1], groups * N_RESPONSES)
