"""Test conditions of a single-wheel test (the simulator's configuration keys)."""

from typing import Any

from pydantic import AliasChoices, BaseModel, ConfigDict, Field, ValidationError, model_validator

from .errors import LogFormatError


class TestConditions(BaseModel):
    """Conditions under which an SWT was run, in SI units (DESIGN section 3).

    Field names are the simulator's configuration keys. ``W`` and ``slip`` are required.
    Imposed slip s = 1 - v / (omega r), so ``omega`` may be left out when ``carriage_speed`` and
    ``R`` are known (see :meth:`wheel_omega`).
    """

    __test__ = False  # not a pytest test class despite the name
    model_config = ConfigDict(
        frozen=True, extra="forbid", allow_inf_nan=False, populate_by_name=True
    )

    W: float = Field(gt=0, validation_alias=AliasChoices("W", "normal_load"), description="N")
    slip: float = Field(ge=-1, lt=1, description="-, imposed slip ratio")
    omega: float | None = Field(default=None, gt=0, description="rad/s, wheel angular velocity")
    carriage_speed: float | None = Field(default=None, gt=0, description="m/s")
    R: float | None = Field(default=None, gt=0, description="m, wheel radius")
    b: float | None = Field(default=None, gt=0, description="m, wheel width")
    n_grousers: int | None = Field(default=None, ge=0)
    grouser_height: float | None = Field(default=None, ge=0, description="m")

    @model_validator(mode="after")
    def _grousers_fit_wheel(self) -> "TestConditions":
        if self.R is not None and self.grouser_height is not None and self.grouser_height >= self.R:
            raise ValueError("grouser_height must be smaller than the wheel radius R")
        return self

    def wheel_omega(self) -> float | None:
        """Wheel angular velocity (rad/s): ``omega`` or v / ((1 - s) R) from the carriage speed."""
        if self.omega is not None:
            return self.omega
        if self.carriage_speed is not None and self.R is not None:
            return self.carriage_speed / ((1.0 - self.slip) * self.R)
        return None

    def to_sim_config(self) -> dict[str, float | int]:
        """Set fields as simulator config keys: W, slip, omega, R, b, n_grousers, grouser_height."""
        out: dict[str, float | int] = {"W": self.W, "slip": self.slip}
        omega = self.wheel_omega()
        if omega is not None:
            out["omega"] = omega
        for key in ("R", "b", "n_grousers", "grouser_height"):
            value = getattr(self, key)
            if value is not None:
                out[key] = value
        return out


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
            parts.append(f"{key} = {err.get('input')!r}: {err['msg']}")
        else:
            parts.append(err["msg"].removeprefix("Value error, "))
    return "; ".join(parts)
