"""Test conditions of a single-wheel test (the simulator's configuration keys)."""

import math
from typing import Any

from pydantic import AliasChoices, BaseModel, ConfigDict, Field, ValidationError, model_validator

from scm_core.slip import (
    CONVENTION_HELP,
    SlipError,
    canonical_convention,
    drive_to_symmetric,
    resolve_speeds,
    slips_from_speeds,
    symmetric_to_drive,
)
from scm_core.validation_text import quoted

from .errors import LogFormatError


class TestConditions(BaseModel):
    """Conditions under which an SWT was run, in SI units (DESIGN section 3).

    ``W`` is required, plus the kinematics as a lab states them: a ``slip`` (in
    ``slip_convention``: ``drive`` = 1 - v/(omega r), or ``symmetric`` = (omega r - v)/max(v,
    omega r), the usual lab form; a negative slip must name its convention), or the carriage
    speed and the rim speed (or omega with R), or a slip and one speed. Validation converts them
    once: the record holds ``slip`` in the drive convention (None for a locked wheel),
    ``slip_symmetric``, and, where they follow, ``carriage_speed``, ``rim_speed`` and ``omega``.
    """

    __test__ = False  # not a pytest test class despite the name
    model_config = ConfigDict(
        frozen=True, extra="forbid", allow_inf_nan=False, populate_by_name=True
    )

    W: float = Field(gt=0, validation_alias=AliasChoices("W", "normal_load"), description="N")
    slip: float | None = Field(
        default=None, lt=1, description="-, 1 - v/(omega r); None for a locked wheel"
    )
    slip_symmetric: float | None = Field(
        default=None, ge=-1, lt=1, description="-, (omega r - v)/max(v, omega r)"
    )
    slip_convention: str | None = Field(
        default=None, description="convention of 'slip' as given: drive or symmetric"
    )
    omega: float | None = Field(default=None, ge=0, description="rad/s, wheel angular velocity")
    carriage_speed: float | None = Field(default=None, gt=0, description="m/s")
    rim_speed: float | None = Field(default=None, ge=0, description="m/s, omega r")
    R: float | None = Field(default=None, gt=0, description="m, wheel radius")
    b: float | None = Field(default=None, gt=0, description="m, wheel width")
    n_grousers: int | None = Field(default=None, ge=0)
    grouser_height: float | None = Field(default=None, ge=0, description="m")
    slip_angle: float | None = Field(
        default=None,
        ge=-90,
        le=90,
        description="deg, between the wheel's heading and the carriage's travel (0: straight)",
    )

    @model_validator(mode="before")
    @classmethod
    def _normalise_kinematics(cls, data: Any) -> Any:
        """Convert the kinematics as given into both slips and (where known) both speeds."""
        if not isinstance(data, dict):
            return data
        keys = ("slip", "slip_symmetric", "carriage_speed", "rim_speed", "omega", "R")
        if any(not _is_number(data.get(k)) for k in keys):
            return data  # field validation names the bad value
        d = dict(data)
        slip, sym = d.get("slip"), d.get("slip_symmetric")
        v, rim, omega, R = (d.get(k) for k in ("carriage_speed", "rim_speed", "omega", "R"))
        convention = d.get("slip_convention")
        try:
            if convention is not None:
                convention = canonical_convention(str(convention))
            if convention == "symmetric" and slip is not None:  # 'slip' given in the lab form
                if sym is not None and not math.isclose(sym, slip, abs_tol=1e-12):
                    raise SlipError(f"slip {slip!r} (symmetric) disagrees with {sym!r}")
                slip, sym = None, slip
            elif convention is None and slip is not None and slip < 0 and sym is None:
                raise SlipError(
                    f"slip {slip!r} is negative (a skidding wheel) but its convention is not "
                    f"named: set slip_convention to {CONVENTION_HELP}"
                )
            if (
                slip is not None
                and sym is not None
                and not math.isclose(symmetric_to_drive(sym), slip, rel_tol=1e-9, abs_tol=1e-12)
            ):
                raise SlipError(f"slip {slip!r} (drive) and slip_symmetric {sym!r} disagree")
            if omega is not None and R is not None:
                if rim is not None and not math.isclose(rim, omega * R, rel_tol=1e-6):
                    raise SlipError(f"rim_speed {rim!r} disagrees with omega * R = {omega * R!r}")
                rim = omega * R
            given = (sym, "symmetric") if sym is not None else (slip, "drive")
            if given[0] is None and (v is None or rim is None):
                if omega != 0 and rim != 0:
                    raise SlipError(
                        "'slip' is required (with slip_convention if negative), or the "
                        "carriage speed and the rim speed (or omega and R)"
                    )
                given = (-1.0, "symmetric")  # a locked wheel
            if v is not None or rim is not None:
                v, rim, _ = resolve_speeds(*given, v, rim, default_speed=1.0)
                if omega is None and R is not None:
                    omega = rim / R
            if given[0] is None:
                slip, sym = slips_from_speeds(v, rim)
            elif given[1] == "symmetric":  # the slip as given stays exact
                sym, slip = given[0], symmetric_to_drive(given[0])
            else:
                slip, sym = given[0], drive_to_symmetric(given[0])
        except SlipError as exc:
            raise ValueError(str(exc)) from None
        d.update(
            slip=None if math.isinf(slip) else slip,
            slip_symmetric=sym,
            slip_convention="drive",
            carriage_speed=v,
            rim_speed=rim,
            omega=omega,
        )
        return d

    @model_validator(mode="after")
    def _grousers_fit_wheel(self) -> "TestConditions":
        if self.R is not None and self.grouser_height is not None and self.grouser_height >= self.R:
            raise ValueError("grouser_height must be smaller than the wheel radius R")
        return self

    @property
    def locked(self) -> bool:
        """True for a locked wheel (symmetric slip -1, omega 0)."""
        return self.slip_symmetric == -1.0

    def wheel_omega(self) -> float | None:
        """Wheel angular velocity (rad/s) if it follows from the conditions."""
        return self.omega

    def to_dict(self) -> dict[str, Any]:
        """The fields as a dict, those added after datasets were first stored (``slip_angle``)
        only when given, so that the content hash and the stored form of a dataset that does
        not name them stay what they were."""
        return self.model_dump(exclude={k for k in _LATER_FIELDS if getattr(self, k) is None})

    def to_sim_config(self) -> dict[str, float | int | str]:
        """Simulator config keys (see :class:`scm_core.simulator.RigConfig`): W, the slip in the
        symmetric convention, one speed (omega when the wheel turns and omega is known, else
        the carriage speed), R, b, n_grousers, grouser_height and slip_angle as given."""
        out: dict[str, float | int | str] = {"W": self.W}
        if self.slip_symmetric is not None:
            if self.slip is not None and self.slip >= 0:
                out["slip"] = self.slip  # the drive convention: the paper's form, unchanged
            else:
                out["slip"] = self.slip_symmetric
                out["slip_convention"] = "symmetric"
        if self.omega is not None and self.omega > 0:
            out["omega"] = self.omega
        elif self.carriage_speed is not None:
            out["carriage_speed"] = self.carriage_speed
        for key in ("R", "b", "n_grousers", "grouser_height", "slip_angle"):
            value = getattr(self, key)
            if value is not None:
                out[key] = value
        return out


#: condition fields added after content hashes were pinned (left out of to_dict when unset)
_LATER_FIELDS = ("slip_angle",)


def _is_number(x: Any) -> bool:
    return x is None or (
        not isinstance(x, bool) and isinstance(x, int | float) and math.isfinite(x)
    )


def condition_unit(name: str) -> str | None:
    """The SI unit of test condition ``name`` (``"-"`` for a ratio, None for a count, a label
    or an unknown name), from the field's description."""
    field = TestConditions.model_fields.get(name)
    if field is None or not field.description:
        return None
    unit = field.description.split(",")[0].strip()
    return unit if unit in ("N", "m", "m/s", "rad/s", "-", "deg") else None


def make_conditions(values: dict[str, Any], where: str = "metadata") -> TestConditions:
    """Validate ``values`` into :class:`TestConditions`, raising a one-line LogFormatError."""
    try:
        return TestConditions.model_validate(values)
    except ValidationError as exc:
        raise LogFormatError(f"invalid {where}: {_describe(exc)}") from None


def _describe(exc: ValidationError) -> str:
    parts = []
    for err in exc.errors():
        key = ".".join(str(p) for p in err["loc"])
        if err["type"] == "missing":
            hint = " (or 'normal_load')" if key == "W" else ""
            parts.append(f"'{key}'{hint} is required")
        elif key:
            parts.append(f"{key} = {quoted(err.get('input'))}: {err['msg']}")
        else:
            parts.append(err["msg"].removeprefix("Value error, "))
    return "; ".join(parts)
