"""The common SWT dataset type and its JSON-compatible dict form."""

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from scm_core.validation_text import quoted

from .conditions import TestConditions, make_conditions
from .errors import LogFormatError
from .processing import ResponseStat
from .responses import RESPONSE_KEYS

SourceKind = Literal["timeseries", "summary"]
DICT_FORMAT = "scm-swt-dataset"
DICT_VERSION = 2  # 2: conditions hold both slips and speeds (version 1: drive slip only)


def _frozen(x: Any) -> np.ndarray:
    a = np.array(x, dtype=np.float64)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class SWTSeries:
    """Time (s) with raw and low-pass-filtered channels in SI, keyed by column name
    (drawbar_pull N, torque Nm, sinkage m, lateral_force N, optional normal_force N, slip -).
    Read-only arrays."""

    t: np.ndarray
    raw: dict[str, np.ndarray]
    filtered: dict[str, np.ndarray]

    def __post_init__(self) -> None:
        object.__setattr__(self, "t", _frozen(self.t))
        object.__setattr__(self, "raw", {k: _frozen(v) for k, v in self.raw.items()})
        object.__setattr__(self, "filtered", {k: _frozen(v) for k, v in self.filtered.items()})

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, SWTSeries):
            return NotImplemented
        return (
            np.array_equal(self.t, other.t)
            and self.raw.keys() == other.raw.keys()
            and self.filtered.keys() == other.filtered.keys()
            and all(np.array_equal(v, other.raw[k]) for k, v in self.raw.items())
            and all(np.array_equal(v, other.filtered[k]) for k, v in self.filtered.items())
        )

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True)
class SWTDataset:
    """One SWT dataset: conditions, steady responses F (N), T (Nm), z (m), Fy (N) (those
    measured: at least one) and provenance.

    ``source_kind`` "timeseries": from a log, with ``window`` (s), ``n_samples``, ``rate_hz``,
    ``offset`` (s), ``cutoff_hz`` and usually ``series``. "summary": reported means and sds with
    ``n_trials``. ``content_hash`` (sha256 hex) identifies the uploaded content.
    """

    name: str
    conditions: TestConditions
    responses: dict[str, ResponseStat]
    source_kind: SourceKind
    content_hash: str
    provenance: dict[str, Any] = field(default_factory=dict)
    n_trials: int | None = None
    window: tuple[float, float] | None = None
    n_samples: int | None = None
    rate_hz: float | None = None
    offset: float | None = None
    cutoff_hz: float | None = None
    series: SWTSeries | None = None

    @property
    def means(self) -> dict[str, float]:
        """Steady means ``{"F": N, "T": Nm, "z": m, "Fy": N}`` (the experimental means of eq.
        (15)) of the responses the dataset measured."""
        return {k: self.responses[k].mean for k in RESPONSE_KEYS if k in self.responses}

    @property
    def standard_errors(self) -> dict[str, float]:
        """Standard errors of the means, same units."""
        return {k: self.responses[k].se for k in RESPONSE_KEYS if k in self.responses}

    def to_dict(self, include_series: bool = True) -> dict[str, Any]:
        """JSON-compatible dict (arrays as lists); inverse of :meth:`from_dict`."""
        out: dict[str, Any] = {
            "format": DICT_FORMAT,
            "version": DICT_VERSION,
            "name": self.name,
            "source_kind": self.source_kind,
            "content_hash": self.content_hash,
            "conditions": self.conditions.to_dict(),
            "provenance": dict(self.provenance),
            "responses": {
                k: {"mean": r.mean, "se": r.se, "sd": r.sd, "n_eff": r.n_eff}
                for k, r in self.responses.items()
            },
            "n_trials": self.n_trials,
            "window": None if self.window is None else list(self.window),
            "n_samples": self.n_samples,
            "rate_hz": self.rate_hz,
            "offset": self.offset,
            "cutoff_hz": self.cutoff_hz,
            "series": None,
        }
        if include_series and self.series is not None:
            s = self.series
            out["series"] = {
                "t": s.t.tolist(),
                "raw": {k: v.tolist() for k, v in s.raw.items()},
                "filtered": {k: v.tolist() for k, v in s.filtered.items()},
            }
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "SWTDataset":
        """Rebuild from :meth:`to_dict` output, validating conditions and responses."""
        if d.get("format") != DICT_FORMAT or d.get("version") not in (1, DICT_VERSION):
            raise LogFormatError(
                f"not an {DICT_FORMAT} v1 or v{DICT_VERSION} dict "
                f"(format={quoted(d.get('format'))}, version={quoted(d.get('version'))})"
            )
        try:
            conditions = dict(d["conditions"])
            if d["version"] == 1:  # its slip was 1 - v/(omega r), whatever its sign
                conditions.setdefault("slip_convention", "drive")
            responses = {
                k: ResponseStat(**d["responses"][k]) for k in RESPONSE_KEYS if k in d["responses"]
            }
            if not responses:
                raise LogFormatError(f"dataset dict: no response ({', '.join(RESPONSE_KEYS)})")
            kind = d["source_kind"]
            if kind not in ("timeseries", "summary"):
                raise LogFormatError(f"unknown source_kind {quoted(kind)}")
            series = d.get("series")
            window = d.get("window")
            return cls(
                name=str(d["name"]),
                conditions=make_conditions(conditions, "conditions"),
                responses=responses,
                source_kind=kind,
                content_hash=str(d["content_hash"]),
                provenance=dict(d.get("provenance") or {}),
                n_trials=d.get("n_trials"),
                window=None if window is None else (float(window[0]), float(window[1])),
                n_samples=d.get("n_samples"),
                rate_hz=d.get("rate_hz"),
                offset=d.get("offset"),
                cutoff_hz=d.get("cutoff_hz"),
                series=None
                if series is None
                else SWTSeries(series["t"], series["raw"], series["filtered"]),
            )
        except (KeyError, TypeError) as exc:
            raise LogFormatError(f"dataset dict: missing or malformed field {exc}") from None


def to_dict(dataset: SWTDataset, include_series: bool = True) -> dict[str, Any]:
    """``dataset.to_dict(include_series)``."""
    return dataset.to_dict(include_series)


def from_dict(d: Mapping[str, Any]) -> SWTDataset:
    """``SWTDataset.from_dict(d)``."""
    return SWTDataset.from_dict(d)
