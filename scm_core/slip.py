"""Slip and speeds of a single-wheel test: the two slip conventions and their conversions.

A single-wheel rig moves the carriage (the axle) at speed v and turns the wheel at omega, so its
rim speed is v_rim = omega * r with r the radius that defines slip (the lab's nominal radius).
Labs report slip in one of two conventions:

* ``drive``: s = 1 - v / v_rim (Wong; the paper's s = 0.2). Equal to the symmetric form when the
  wheel drives (v_rim >= v); in skid it goes to minus infinity as the wheel locks.
* ``symmetric``: s = (v_rim - v) / max(v, v_rim), the usual lab form (e.g. CMU's SWT data): equal
  to the drive form when driving, v_rim / v - 1 in skid, so -1 is a locked wheel.

Conversion for skid (s < 0): s_symmetric = s_drive / (1 - s_drive), s_drive = s_symmetric /
(1 + s_symmetric). All functions are pure; speeds in m/s.
"""

from __future__ import annotations

import math

__all__ = [
    "SLIP_CONVENTIONS",
    "SlipError",
    "canonical_convention",
    "drive_to_symmetric",
    "resolve_speeds",
    "slips_from_speeds",
    "symmetric_to_drive",
]

SLIP_CONVENTIONS = ("drive", "symmetric")
_ALIASES = {
    "drive": "drive",
    "1-v/(omegar)": "drive",
    "1-v/(omega*r)": "drive",
    "1-v/(ωr)": "drive",
    "1-v/v_rim": "drive",
    "symmetric": "symmetric",
    "lab": "symmetric",
    "(omegar-v)/max(v,omegar)": "symmetric",
    "(omega*r-v)/max(v,omega*r)": "symmetric",
    "(v_rim-v)/max(v,v_rim)": "symmetric",
}
CONVENTION_HELP = (
    "'drive' (s = 1 - v/(omega r)) or 'symmetric' (s = (omega r - v)/max(v, omega r), the usual "
    "lab form, -1 = locked)"
)


class SlipError(ValueError):
    """Inconsistent or incomplete kinematics; the message is one line."""


def canonical_convention(name: str) -> str:
    """'drive' or 'symmetric' for a convention name or its formula (spaces ignored)."""
    key = "".join(str(name).split()).lower()
    if key not in _ALIASES:
        raise SlipError(f"unknown slip convention {name!r}; use {CONVENTION_HELP}")
    return _ALIASES[key]


def drive_to_symmetric(s: float) -> float:
    """1 - v/v_rim -> (v_rim - v)/max(v, v_rim); -inf (locked) -> -1."""
    if s >= 0.0:
        return s
    if math.isinf(s):
        return -1.0
    return s / (1.0 - s)


def symmetric_to_drive(s: float) -> float:
    """(v_rim - v)/max(v, v_rim) -> 1 - v/v_rim; -1 (locked) -> -inf."""
    if s >= 0.0:
        return s
    if s <= -1.0:
        return -math.inf
    return s / (1.0 + s)


def slips_from_speeds(v: float, v_rim: float) -> tuple[float, float]:
    """(drive slip, symmetric slip) of carriage speed v and rim speed v_rim (not both zero)."""
    if v <= 0.0 and v_rim <= 0.0:
        raise SlipError("carriage and rim are both at rest: slip is undefined")
    sym = (v_rim - v) / max(v, v_rim)
    drive = 1.0 - v / v_rim if v_rim > 0.0 else -math.inf
    return drive, sym


def resolve_speeds(
    slip: float | None,
    convention: str | None,
    carriage_speed: float | None,
    rim_speed: float | None,
    default_speed: float,
) -> tuple[float, float, float]:
    """(carriage speed v, rim speed v_rim [m/s], drive slip) from what is given.

    Any two of slip, carriage speed and rim speed fix the third; all three must agree (relative
    tolerance 1e-6). A slip alone moves the faster of carriage and rim at ``default_speed`` (the
    rim when driving, the carriage in skid); nothing at all is slip 0.2 at that speed. A negative
    slip needs its convention; the carriage must move (v > 0). The slip returned is the one given
    (or defaulted), exactly, else the one the two speeds make.
    """
    s_drive = None
    if slip is not None:
        if convention is None:
            if slip < 0.0:
                raise SlipError(
                    f"slip {slip:g} is negative (a skidding wheel) but its convention is not "
                    f"named: set slip_convention to {CONVENTION_HELP}"
                )
            convention = "drive"
        convention = canonical_convention(convention)
        if convention == "symmetric":
            if not -1.0 <= slip < 1.0:
                raise SlipError(f"slip {slip:g}: a symmetric slip lies in [-1, 1)")
            s_drive = symmetric_to_drive(slip)
        else:
            if not slip < 1.0 or math.isnan(slip):
                raise SlipError(f"slip {slip:g}: a drive slip 1 - v/(omega r) is below 1")
            s_drive = slip
    v, vr = carriage_speed, rim_speed
    if v is not None and vr is not None:
        if s_drive is not None:
            expect = slips_from_speeds(v, vr)[0]
            if not (math.isclose(expect, s_drive, rel_tol=1e-6, abs_tol=1e-9)):
                raise SlipError(
                    f"slip {slip:g} disagrees with carriage speed {v:g} m/s and rim speed "
                    f"{vr:g} m/s (slip {expect:g} in the drive convention)"
                )
    elif s_drive is None:
        s_drive = 0.2
        if v is None and vr is None:
            vr = default_speed
    if v is None and vr is None:  # slip alone: the faster one at the default speed
        if s_drive >= 0.0:
            vr = default_speed
        else:
            v = default_speed
    if v is None:
        v = vr * (1.0 - s_drive)
    elif vr is None:
        vr = 0.0 if math.isinf(s_drive) else v / (1.0 - s_drive)
    if not v > 0.0:
        raise SlipError(
            f"carriage speed {v:g} m/s: the carriage must move (slip 1 is a wheel spinning in "
            "place, which this rig does not simulate)"
        )
    if vr < 0.0:
        raise SlipError(f"rim speed {vr:g} m/s is negative (the wheel turns backwards)")
    return (
        float(v),
        float(vr),
        float(s_drive) if s_drive is not None else slips_from_speeds(v, vr)[0],
    )
