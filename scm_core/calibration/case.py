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

import dataclasses
import hashlib
import json
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    create_model,
    model_validator,
)

from scm_core.inference.priors import (
    JointPrior,
    distribution_from_dict,
)
from scm_core.inference.tmcmc_moves import STUDY_MOVES, form_defaults
from scm_core.inference.tmcmc_stage import TMCMCSettings
from scm_core.inference.tmcmc_types import MOVES
from scm_core.seeds import SEED_MAX
from scm_core.signals.responses import DEFAULT_KEYS, RESPONSE_KEYS, response
from scm_core.simulator import RigConfig, SoilParams, WheelGeometry
from scm_core.validation_text import first_error, one_line

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


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class PriorSpec(_Strict):
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


#: the sampler's defaults (a case's ``[sampler]`` table leaves out what it keeps)
_DEFAULT = TMCMCSettings()


class _SamplerFields(_Strict):
    """TMCMC settings (see :class:`scm_core.inference.TMCMCSettings`).

    ``moves``: "waste-free" (the default: the accelerated accurate form), "resample-move" (the
    unaccelerated accurate form) or "leader" (the paper's form). ``n_steps`` (waste-free),
    ``delayed_acceptance``, ``surrogate_steps``, ``surrogate_jumps``, ``proposal_scale`` and
    ``resampling`` left out (or null) take the move scheme's defaults, filled in and stored with
    the case (:func:`scm_core.inference.tmcmc_moves.form_defaults`): for "waste-free" 4 moves per
    chain, surrogate transitions of 40 inner steps with population jumps, the log walk and
    multinomial resampling; for "resample-move" and "leader" plain steps in the parameters and
    systematic resampling (their ``n_steps`` left null adapts per stage).

    ``batch_size``: chains per batch handed to the ``map`` (None: chosen by the runner; does
    not change the results). ``max_stages``: stop (status "max_stages") after that many
    tempering stages. ``early_rejection``: stop simulating a proposal's datasets once they
    cannot lift it over the acceptance threshold (exact, same samples; see
    :mod:`scm_core.inference.early_rejection`). ``delayed_acceptance``: move with a surrogate
    of the responses fitted on the stage's starting states before simulating (exact, other
    samples; :mod:`scm_core.inference.surrogate`): ``surrogate_steps`` Metropolis steps on the
    surrogate per model run (1: Christen & Fox's delayed acceptance), of which a fraction
    ``surrogate_jumps`` are independence proposals from the population's t
    (:mod:`scm_core.inference.population_jump`). ``proposal_scale``:
    "log" walks the log of every strictly positive parameter (exact; SCM's multiplicative
    trade-offs become straight ridges, :mod:`scm_core.inference.walk_space`). ``resampling``:
    "systematic" (less resampling noise; the evidence's standard error is a lower bound,
    1.3-1.4 times too small) or "multinomial" (a right standard error).

    The sampler's finer tuning (``min_steps``, ``beta0``, ``surrogate_neighbors`` ...: the
    other fields of TMCMCSettings, :data:`TUNING`) is a field here too, generated from
    TMCMCSettings with its defaults, so that a case's stored form (:meth:`CaseDefinition.to_dict`)
    holds every setting its samples depend on: a later change of a default in code changes no
    stored study. A stored case from before these were stored is read with the values they had
    then (:data:`TUNING_BEFORE`, :meth:`CaseDefinition.from_stored`).
    """

    n_samples: int = Field(2000, ge=10, description="Samples per stage.")
    moves: Literal[MOVES] = Field(
        STUDY_MOVES,
        description="Move scheme: waste-free (the default, the accelerated accurate form), "
        "resample-move (unaccelerated) or leader (the paper's form).",
    )
    n_steps: int | None = Field(
        _DEFAULT.n_steps,
        ge=1,
        description="Moves per chain: waste-free (default 4), resample-move (default adapted).",
    )
    batch_size: int | None = Field(None, ge=1)
    max_stages: int = Field(
        _DEFAULT.max_stages, ge=1, description="Stop after this many tempering stages."
    )
    target_cov: float = Field(_DEFAULT.target_cov, gt=0.0)
    early_rejection: bool = Field(
        _DEFAULT.early_rejection,
        description="Stop simulating a proposal's datasets once they cannot lift it over the "
        "acceptance threshold (exact: the same samples, fewer runs).",
    )
    delayed_acceptance: bool | None = Field(
        None,
        description="Screen proposals with a surrogate of the responses before simulating "
        "them (default: true for waste-free moves, false for resample-move and leader; exact: "
        "the chain still targets the posterior).",
    )
    surrogate_steps: int | None = Field(None, ge=1, le=100)
    surrogate_jumps: float | None = Field(None, ge=0.0, lt=1.0)
    proposal_scale: Literal["linear", "log"] | None = None
    resampling: Literal["systematic", "multinomial"] | None = None

    _filled: frozenset[str] = PrivateAttr(default=frozenset())

    @model_validator(mode="after")
    def _form_defaults(self) -> SamplerSettings:
        """Fill what the case left to its move scheme; ``model_fields_set`` keeps what the
        case gave (:meth:`CaseDefinition.with_changes` merges onto that alone)."""
        filled = []
        for key, value in form_defaults(self.moves).items():
            if getattr(self, key) is None:
                self.__dict__[key] = value
                filled.append(key)
        self._filled = frozenset(filled)
        return self

    @model_validator(mode="after")
    def _valid_tuning(self) -> _SamplerFields:
        self.tmcmc_settings()  # TMCMCSettings' own checks (ValueError names the field)
        return self

    def __eq__(self, other: object) -> bool:
        # equal settings are equal whether the case named them or its move scheme filled them
        if not isinstance(other, _SamplerFields):
            return NotImplemented
        return self.model_dump() == other.model_dump()

    def __hash__(self) -> int:
        return hash(tuple(sorted(self.model_dump().items())))

    def given(self) -> dict[str, Any]:
        """The settings the case gave (not the ones its move scheme filled in)."""
        keys = set(self.model_fields_set) - self._filled
        return self.model_dump(include=keys, exclude_none=True)

    def tmcmc_settings(self) -> TMCMCSettings:
        return TMCMCSettings(
            **{name: getattr(self, name) for name in TUNING},
            moves=self.moves,
            n_steps=self.n_steps,
            max_stages=self.max_stages,
            target_cov=self.target_cov,
            early_rejection=self.early_rejection,
            delayed_acceptance=bool(self.delayed_acceptance),
            surrogate_steps=int(self.surrogate_steps or 1),
            surrogate_jumps=float(self.surrogate_jumps or 0.0),
            proposal_scale=str(self.proposal_scale),
            resampling=str(self.resampling),
        )


#: TMCMCSettings' fields a case's [sampler] table does not declare above: its finer tuning,
#: generated into SamplerSettings with TMCMCSettings' defaults
TUNING = tuple(
    f.name for f in dataclasses.fields(TMCMCSettings) if f.name not in _SamplerFields.model_fields
)

#: the tuning's values before stored cases held it (its code defaults until then): what a case
#: stored without it ran with. A record of the past, like a migration: never edit it when a
#: default changes (issue 43)
TUNING_BEFORE: dict[str, int | float] = {
    "min_steps": 10,
    "max_steps": 50,
    "initial_steps": 20,
    "move_probability": 0.99,
    "beta0": 0.2,
    "target_acceptance": 0.234,
    "beta_gain": 1.0,
    "beta_min": 0.02,
    "beta_max": 3.0,
    "stall_tol": 1e-8,
    "stall_stages": 3,
    "surrogate_neighbors": 50,
    "surrogate_smoothing": 1e-3,
    "surrogate_memory": 20_000,
}

#: moves per chain of a waste-free case stored before the form's default was stored with it
#: (WASTE_FREE_STEPS until then); a record of the past, like TUNING_BEFORE
WASTE_FREE_STEPS_BEFORE = 4

SamplerSettings = create_model(
    "SamplerSettings",
    __base__=_SamplerFields,
    __module__=__name__,
    __doc__=_SamplerFields.__doc__,
    **{name: (type(getattr(_DEFAULT, name)), getattr(_DEFAULT, name)) for name in TUNING},
)


class DataSettings(_Strict):
    """Datasets: file paths relative to the case file (replaced by ``--data`` at run time),
    the averaging offset of the experimental signals [s] (paper: 40 s) and the low-pass cutoff
    [Hz] (None: :func:`scm_core.signals.load_log`'s default)."""

    files: tuple[str, ...] = ()
    offset: float = Field(40.0, ge=0.0)
    cutoff_hz: float | None = Field(None, gt=0.0)


class CaseDefinition(_Strict):
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
