"""Calibration case definitions (paper sections 4.5 and 5, Table 2): what to calibrate, how.

A case names the calibrated parameters with their priors, the nominal values of everything else,
the simulator settings, the sampler settings and the datasets. It is written as TOML::

    name = "case1"
    seed = 1
    likelihood = "normalized"          # eq. (12)-(15); or "gaussian", eq. (6)
    responses = ["F", "T", "z"]        # steady means entering the likelihood (the default;
                                       # a steered wheel's lateral force "Fy" only if named)
    trials = "mean"                    # a summary of repeated trials is one test at its mean;
                                       # "each": every trial is a test (its mean, sd, n_trials)

    [parameters]                       # calibrated, in this order (the sample columns)
    k_c = { dist = "uniform", lower = -1e9, upper = 1e9, unit = "N/m^(n+1)" }
    n = { dist = "normal", mean = 1.1, sd = 0.2, lower = 0.8, upper = 2.0 }
    sigma_F = { dist = "uniform", lower = 0.0, upper = 5.0 }

    [nominal]                          # fixed values (any SoilParams/WheelGeometry/RigConfig
    J = 0.001                          # field, or a sigma_* not calibrated)

    [simulator]                        # RigConfig numerics/rig overrides
    duration = 50.0
    dt = 0.02

    [sampler]
    n_samples = 2000
    moves = "leader"                   # or "waste-free" (default), "resample-move"

    [data]
    files = ["wf34_s020.csv"]          # relative to the case file; --data replaces them
    offset = 40.0                      # experimental averaging offset [s]

    [reference]                        # bevameter values drawn on the figures (optional)
    k_star = 1e7
    n = 1.1
    phi = 30.0

Calibratable names: the float fields of :class:`~scm_core.simulator.SoilParams` (``n``, ``k_c``,
``k_phi``, ``c``, ``phi`` [deg], ``D_soil``, ``J``, ``K``, ...) and of
:class:`~scm_core.simulator.WheelGeometry` (``R``, ``b``, ...), plus the prediction-error standard
deviations ``sigma_F`` [N], ``sigma_T`` [N m], ``sigma_z`` [m], ``sigma_Fy`` [N]. One sigma per
response, shared by all datasets of the study; a dataset that did not measure a response (NaN:
the CMU data's torque, a straight test's lateral force) has no term for it.

Every problem is reported as :class:`CaseError` with a one-line message that names the field
(``parameters.k_c``, ``nominal.J``, ``sampler.n_samples`` ...).
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    Field,
    PrivateAttr,
    ValidationError,
)

from scm_core.inference.priors import (
    JointPrior,
    distribution_from_dict,
)
from scm_core.inference.tmcmc.stage import TMCMCSettings
from scm_core.seeds import SEED_MAX
from scm_core.signals.responses import DEFAULT_KEYS, RESPONSE_KEYS, response
from scm_core.simulator import RigConfig, SoilParams, WheelGeometry
from scm_core.validation_text import first_error, one_line

from .sampler_settings import (
    TUNING,
    TUNING_BEFORE,
    WASTE_FREE_STEPS_BEFORE,
    SamplerSettings,
    StrictModel,
)

__all__ = [
    "CALIBRATABLE",
    "RESPONSE_KEYS",
    "SIGMA_NAMES",
    "CaseDefinition",
    "CaseError",
    "DataSettings",
    "PriorSpec",
    "SamplerSettings",
    "load_case",
]

#: each response's prediction-error sigma and its unit (scm_core.signals.responses)
SIGMA_NAMES = {k: response(k).sigma for k in RESPONSE_KEYS}
SIGMA_UNITS = {response(k).sigma: response(k).unit for k in RESPONSE_KEYS}
#: measurement offsets: measured = simulated + offset (a datum the rig does not know exactly,
#: e.g. the sinkage zero of a log); calibrated or fixed like the sigmas, shared by all datasets
OFFSET_NAMES = {"z": "z_offset"}
OFFSET_UNITS = {"z_offset": "m"}


def _float_fields(cls: type[BaseModel]) -> tuple[str, ...]:
    return tuple(
        name
        for name, f in cls.model_fields.items()
        if f.annotation is float or f.annotation == (float | None)
    )


SOIL_FIELDS = tuple(SoilParams.model_fields)
WHEEL_FIELDS = tuple(WheelGeometry.model_fields)
RIG_FIELDS = tuple(RigConfig.model_fields)

#: parameter name -> owner ("soil", "wheel" or "sigma") for every calibratable name
CALIBRATABLE: dict[str, str] = {
    **{n: "soil" for n in _float_fields(SoilParams)},
    **{n: "wheel" for n in _float_fields(WheelGeometry)},
    **{s: "sigma" for s in SIGMA_NAMES.values()},
    **{s: "offset" for s in OFFSET_NAMES.values()},
}
#: every name accepted in [nominal]
NOMINAL_NAMES = (
    *SOIL_FIELDS,
    *WHEEL_FIELDS,
    *RIG_FIELDS,
    *SIGMA_NAMES.values(),
    *OFFSET_NAMES.values(),
)


class CaseError(ValueError):
    """A refused case definition; the message is one line and names the field."""


class PriorSpec(StrictModel):
    """A prior as written in the case: ``dist`` plus its parameters (see
    :func:`scm_core.inference.distribution_from_dict`): uniform / log_uniform need lower and
    upper; normal (truncated_normal) needs mean, sd, lower and upper; log_normal needs median,
    factor (the geometric sd, > 1), lower and upper. ``unit`` is a label."""

    dist: Literal[
        "uniform",
        "normal",
        "truncated_normal",
        "log_uniform",
        "loguniform",
        "log_normal",
        "lognormal",
    ]
    lower: float | None = None
    upper: float | None = None
    mean: float | None = None
    sd: float | None = None
    median: float | None = None
    factor: float | None = None
    unit: str | None = None

    def to_distribution(self):
        data = self.model_dump(exclude_none=True, exclude={"unit"})
        return distribution_from_dict(data)

    def to_dict(self) -> dict[str, Any]:
        return self.model_dump(exclude_none=True)


class DataSettings(StrictModel):
    """Datasets: file paths relative to the case file (replaced by ``--data`` at run time),
    the averaging offset of the experimental signals [s] (paper: 40 s) and the low-pass cutoff
    [Hz] (None: :func:`scm_core.signals.load_log`'s default)."""

    files: tuple[str, ...] = ()
    offset: float = Field(40.0, ge=0.0)
    cutoff_hz: float | None = Field(None, gt=0.0)


class CaseDefinition(StrictModel):
    """A calibration study: priors of the calibrated parameters, nominal values of the others.

    Simulator configuration of a run, by increasing precedence: the simulator's defaults (the
    paper's set-up), ``nominal``, ``simulator``, the dataset's test conditions (W, slip, omega,
    R, b, n_grousers, grouser_height), the calibrated values. The dataset's wheel radius R is
    the lab's nominal radius: it sets ``RigConfig.slip_radius`` and also ``WheelGeometry.R``
    unless R is calibrated (cases 2: the equivalent rigid radius).
    """

    name: str = Field(min_length=1)
    seed: int = Field(0, ge=0, le=SEED_MAX)
    likelihood: Literal["normalized", "gaussian"] = "normalized"
    trials: Literal["mean", "each"] = "mean"
    responses: tuple[Literal[RESPONSE_KEYS], ...] = DEFAULT_KEYS
    parameters: dict[str, PriorSpec]
    nominal: dict[str, float | int | bool | str] = Field(default_factory=dict)
    simulator: dict[str, float | int | bool | str] = Field(default_factory=dict)
    sampler: SamplerSettings = Field(default_factory=SamplerSettings)
    data: DataSettings = Field(default_factory=DataSettings)
    reference: dict[str, float] = Field(default_factory=dict)
    description: str = ""

    _base_dir: Path | None = PrivateAttr(default=None)

    # ------------------------------------------------------------------ construction

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], base_dir: str | Path | None = None):
        """Validate a decoded case (TOML/JSON document); raises :class:`CaseError`."""
        if not isinstance(data, Mapping):
            raise CaseError("case: top level must be a table")
        try:
            case = cls.model_validate(dict(data))
        except ValidationError as exc:
            raise CaseError(_describe(exc)) from None
        case._check()
        case._base_dir = None if base_dir is None else Path(base_dir)
        return case

    @classmethod
    def from_stored(
        cls, data: Mapping[str, Any], base_dir: str | Path | None = None
    ) -> CaseDefinition:
        """A case as stored (:meth:`to_dict`, in the database or a results folder): the
        tuning a case stored before it was stored takes the values it ran with
        (:data:`TUNING_BEFORE`), not today's defaults."""
        if not isinstance(data, Mapping):
            raise CaseError("case: top level must be a table")
        sampler = data.get("sampler")
        if isinstance(sampler, Mapping) and not any(k in sampler for k in TUNING):
            sampler = {**TUNING_BEFORE, **sampler}
        if (
            isinstance(sampler, Mapping)
            and sampler.get("moves") == "waste-free"
            and sampler.get("n_steps") is None
        ):  # stored before its form's n_steps was filled in: it ran with the default then
            sampler = {**sampler, "n_steps": WASTE_FREE_STEPS_BEFORE}
        if sampler is not data.get("sampler"):
            data = {**data, "sampler": sampler}
        return cls.from_dict(data, base_dir)

    @classmethod
    def from_toml(cls, text: str, base_dir: str | Path | None = None) -> CaseDefinition:
        """Parse TOML text; data file paths are relative to ``base_dir``."""
        try:
            doc = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise CaseError(f"case file is not valid TOML: {exc}") from None
        return cls.from_dict(doc, base_dir)

    def with_changes(self, **changes: Any) -> CaseDefinition:
        """A validated copy; ``sampler`` / ``data`` may be given as partial dicts."""
        doc = self.to_dict()
        # the sampler keeps what the case gave; what its move scheme filled in follows the
        # (possibly changed) scheme
        doc["sampler"] = self.sampler.given()
        for key, value in changes.items():
            if key in ("sampler", "data") and isinstance(value, Mapping):
                doc[key] = {**doc.get(key, {}), **value}
            else:
                doc[key] = value
        return CaseDefinition.from_dict(doc, self._base_dir)

    # ------------------------------------------------------------------ validation

    def _check(self) -> None:
        if not self.parameters:
            raise CaseError("parameters: at least one calibrated parameter is required")
        if len(set(self.responses)) != len(self.responses) or not self.responses:
            raise CaseError(f"responses: must be distinct entries of {list(RESPONSE_KEYS)}")
        for name, spec in self.parameters.items():
            where = f"parameters.{name}"
            if name not in CALIBRATABLE:
                raise CaseError(
                    f"{where}: unknown parameter {name!r}; calibratable: {', '.join(CALIBRATABLE)}"
                )
            if name in self.nominal:
                raise CaseError(
                    f"{where}: {name!r} is both calibrated and nominal (nominal.{name}); remove one"
                )
            try:
                dist = spec.to_distribution()
            except (TypeError, KeyError) as exc:
                raise CaseError(f"{where}: {spec.dist} prior is missing {exc}") from None
            except ValueError as exc:
                raise CaseError(f"{where}: {_strip_cls(str(exc))}") from None
            if CALIBRATABLE[name] == "sigma" and dist.lower < 0:
                raise CaseError(f"{where}: a standard deviation needs lower >= 0")
            owner = {"soil": SoilParams, "wheel": WheelGeometry}.get(CALIBRATABLE[name])
            if owner is not None:
                _check_prior_range(where, name, dist.lower, dist.upper, owner)
        for name in self.nominal:
            if name not in NOMINAL_NAMES:
                raise CaseError(
                    f"nominal.{name}: unknown name {name!r}; accepted: simulator keys "
                    f"(see `scm-calib simulate` keys), {', '.join(SIGMA_NAMES.values())} or "
                    f"{', '.join(OFFSET_NAMES.values())}"
                )
        for name in self.simulator:
            if name not in RIG_FIELDS:
                raise CaseError(
                    f"simulator.{name}: unknown rig/numerics key {name!r}; accepted: "
                    f"{', '.join(RIG_FIELDS)}"
                )
            if name in self.nominal:
                raise CaseError(f"simulator.{name}: also given as nominal.{name}; remove one")
            if name in self.parameters:
                raise CaseError(f"simulator.{name}: {name!r} is calibrated")
        for resp in self.responses:
            sig = SIGMA_NAMES[resp]
            if sig in self.parameters:
                continue
            if sig not in self.nominal:
                raise CaseError(
                    f"{sig}: response {resp} is used but {sig} is neither calibrated "
                    f"([parameters]) nor fixed ([nominal])"
                )
            value = self.nominal[sig]
            if isinstance(value, bool | str) or not (math.isfinite(value) and value > 0):
                raise CaseError(f"nominal.{sig}: must be a number > 0, got {value!r}")
        for name in OFFSET_NAMES.values():
            value = self.nominal.get(name, 0.0)
            if isinstance(value, bool | str) or not math.isfinite(value):
                raise CaseError(f"nominal.{name}: must be a number, got {value!r}")
        # nominal values and simulator settings must build valid configurations
        for cls, fields, label in (
            (SoilParams, SOIL_FIELDS, "nominal"),
            (WheelGeometry, WHEEL_FIELDS, "nominal"),
        ):
            values = {k: v for k, v in self.nominal.items() if k in fields}
            _validate_config(cls, values, label)
        rig_values = {k: v for k, v in self.nominal.items() if k in RIG_FIELDS}
        _validate_config(RigConfig, rig_values, "nominal")
        _validate_config(RigConfig, {**rig_values, **self.simulator}, "simulator")
        for name in self.reference:
            if name != "k_star" and name not in CALIBRATABLE:
                raise CaseError(f"reference.{name}: unknown parameter {name!r}")

    # ------------------------------------------------------------------ derived

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(self.parameters)

    @property
    def base_dir(self) -> Path | None:
        return self._base_dir

    def prior(self) -> JointPrior:
        """The joint prior of the calibrated parameters, in case order."""
        dists = {n: s.to_distribution() for n, s in self.parameters.items()}
        units = {n: s.unit for n, s in self.parameters.items() if s.unit}
        return JointPrior(dists, units)

    def tmcmc_settings(self) -> TMCMCSettings:
        return self.sampler.tmcmc_settings()

    def data_paths(self) -> list[Path]:
        """Dataset paths of ``data.files``, resolved against the case file's directory."""
        base = self._base_dir or Path.cwd()
        return [Path(f) if Path(f).is_absolute() else base / f for f in self.data.files]

    def offset_spec(self) -> dict[str, tuple[str, float | int]]:
        """Per response with a measurement offset in the case: ("parameter", column index) or
        ("fixed", value); responses without one are left out."""
        names = self.parameter_names
        out: dict[str, tuple[str, float | int]] = {}
        for resp, name in OFFSET_NAMES.items():
            if name in self.parameters:
                out[resp] = ("parameter", names.index(name))
            elif name in self.nominal:
                out[resp] = ("fixed", float(self.nominal[name]))
        return out

    def sigma_spec(self) -> dict[str, tuple[str, float | int]]:
        """Per used response: ("parameter", column index) or ("fixed", value)."""
        names = self.parameter_names
        out: dict[str, tuple[str, float | int]] = {}
        for resp in self.responses:
            sig = SIGMA_NAMES[resp]
            if sig in self.parameters:
                out[resp] = ("parameter", names.index(sig))
            else:
                out[resp] = ("fixed", float(self.nominal[sig]))
        return out

    # ------------------------------------------------------------------ serialisation

    def to_dict(self) -> dict[str, Any]:
        """JSON/TOML-compatible dict; ``from_dict(to_dict())`` gives an equal case."""
        out = self.model_dump(mode="json", exclude_none=True)
        out["parameters"] = {n: s.to_dict() for n, s in self.parameters.items()}
        out["responses"] = list(self.responses)
        out["data"]["files"] = list(self.data.files)
        # defaults of keys added later are left out: stored cases and fingerprints keep the
        # form they had before the key existed
        if self.trials == "mean":
            del out["trials"]
        return out

    def fingerprint(self) -> str:
        """sha256 of everything that changes the samples of a stage: not the data file names
        (the datasets are hashed by content), the batch size, ``max_stages`` (it only decides
        when to stop, so a stopped study can be continued with a larger value), the
        description, the reference values or ``early_rejection`` (exact: the same samples)."""
        doc = self.to_dict()
        doc["data"].pop("files", None)
        doc.pop("description", None)
        doc.pop("reference", None)
        doc["sampler"].pop("batch_size", None)
        doc["sampler"].pop("max_stages", None)
        doc["sampler"].pop("early_rejection", None)
        for name, value in TUNING_BEFORE.items():
            # cases from before the tuning was stored keep their fingerprint
            if doc["sampler"].get(name) == value:
                del doc["sampler"][name]
        if (
            doc["sampler"].get("moves") == "waste-free"
            and doc["sampler"].get("n_steps") == WASTE_FREE_STEPS_BEFORE
        ):  # and those from before waste-free's n_steps was filled in (null: left out)
            del doc["sampler"]["n_steps"]
        if doc["sampler"].get("resampling") == "systematic":
            # cases from before resampling could be chosen keep their fingerprint
            del doc["sampler"]["resampling"]
        text = json.dumps(doc, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(b"scm-calib-case/1\n" + text.encode()).hexdigest()


def load_case(path: str | Path) -> CaseDefinition:
    """Read a TOML case file; data paths are relative to its directory."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise CaseError(f"cannot read case file {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise CaseError(f"case file {path} is not UTF-8 text") from None
    try:
        return CaseDefinition.from_toml(text, path.parent)
    except CaseError as exc:
        raise CaseError(f"{path.name}: {exc}") from None


# ---------------------------------------------------------------------- error formatting


def _strip_cls(msg: str) -> str:
    for prefix in ("Uniform: ", "TruncatedNormal: ", "LogUniform: ", "LogNormal: "):
        msg = msg.replace(prefix, "")
    return msg


def _describe(exc: ValidationError) -> str:
    loc, msg, err = first_error(exc)
    where = ".".join(loc) or "case"
    kind = err.get("type", "")
    if kind == "missing":
        return f"{where}: required field is missing"
    if kind == "extra_forbidden":
        return f"{where}: unknown field"
    if "input" in err and kind != "model_type" and not isinstance(err["input"], Mapping):
        return f"{where}: {msg} (got {err['input']!r})"
    return f"{where}: {msg}"


def field_range(cls: type[BaseModel], name: str) -> tuple[float, float]:
    """Closed range [lo, hi] of a float field's own bounds (ge/gt, le/lt; +-inf if none)."""
    lo, hi = -math.inf, math.inf
    for rule in cls.model_fields[name].metadata:
        for attr in ("ge", "gt"):
            if getattr(rule, attr, None) is not None:
                lo = max(lo, float(getattr(rule, attr)))
        for attr in ("le", "lt"):
            if getattr(rule, attr, None) is not None:
                hi = min(hi, float(getattr(rule, attr)))
    return lo, hi


def _check_prior_range(
    where: str, name: str, lower: float, upper: float, cls: type[BaseModel]
) -> None:
    """A prior must not put mass where the simulator refuses the value: such draws would fail
    and silently truncate the prior. An open bound (gt/lt) may be the prior's bound (a set of
    probability zero)."""
    lo, hi = field_range(cls, name)
    if lower < lo or upper > hi:
        raise CaseError(
            f"{where}: the prior's range [{lower:g}, {upper:g}] leaves the simulator's range "
            f"of {name}, [{lo:g}, {hi:g}]; narrow the prior's lower/upper"
        )


def _validate_config(cls: type[BaseModel], values: dict[str, Any], label: str) -> None:
    try:
        cls.model_validate(values)
    except ValidationError as exc:
        raise CaseError(one_line(exc, label)) from None
