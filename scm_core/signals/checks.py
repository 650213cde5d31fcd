"""Plausibility checks of loaded SWT datasets, alone and as a set (``scm-calib check``).

A file that loads is well-formed; these checks catch what loads but is probably wrong, each
message naming the file and the fix:

* a per-trial summary of very many rows: a time series whose header lacks the time column is
  read as a summary of one trial per row (its mean includes the start-up);
* magnitudes no single-wheel test gives: |F|, |Fy| or |T| / r above 10 W (a wheel pulls or
  brakes at most a few W, Wong 2008 ch. 4; the CMU wheels dragged sideways, three), sinkage
  beyond the wheel radius (the axle below the surface), usually a unit error (kN under an
  ``[N]`` header, mm under ``[m]``);
* a lateral force without a slip angle: read as a straight wheel's (0 deg), which is probably
  not what the lab ran;
* a response measured in some datasets of a set but not in others: a study's likelihood uses a
  response only where it was measured.
"""

from __future__ import annotations

from collections.abc import Sequence

from .dataset import SWTDataset
from .responses import RESPONSE_KEYS, RESPONSES, response

__all__ = ["MAX_FORCE_OVER_W", "MAX_SUMMARY_TRIALS", "dataset_warnings", "set_warnings"]

#: largest plausible |F| and |T| / r in multiples of the normal load W
MAX_FORCE_OVER_W = 10.0
#: a per-trial summary with more rows than this is most likely a log without its time column
MAX_SUMMARY_TRIALS = 100
#: the responses that are forces (drawbar pull, lateral force)
_FORCES = tuple(r for r in RESPONSES if r.quantity == "force")


def dataset_warnings(ds: SWTDataset, label: str) -> list[str]:
    """What is probably wrong with one dataset (``label``: how to name it, e.g. its path)."""
    out = []
    if ds.source_kind == "summary" and (ds.n_trials or 0) > MAX_SUMMARY_TRIALS:
        out.append(
            f"{label}: read as a summary of {ds.n_trials} trials (one per row); if it is a time "
            "series, its header lacks the time column: add a column 'time [s]'"
        )
    W = ds.conditions.W
    means = ds.means
    for r in _FORCES:
        if r.key in means and abs(means[r.key]) > MAX_FORCE_OVER_W * W:
            out.append(
                f"{label}: {r.words} {means[r.key]:g} N is over {MAX_FORCE_OVER_W:g} W "
                f"({MAX_FORCE_OVER_W * W:g} N): check the unit in its header (N, not kN)"
            )
    R = ds.conditions.R
    if "T" in means and R is not None and abs(means["T"]) / R > MAX_FORCE_OVER_W * W:
        out.append(
            f"{label}: torque {means['T']:g} N m over the radius {R:g} m is over "
            f"{MAX_FORCE_OVER_W:g} W: check the unit in its header (N m, not N mm)"
        )
    if "z" in means and R is not None and means["z"] > R:
        out.append(
            f"{label}: sinkage {1000 * means['z']:g} mm is beyond the wheel radius "
            f"{1000 * R:g} mm: check the unit in its header (mm or m)"
        )
    if "Fy" in means and ds.conditions.slip_angle is None:
        out.append(
            f"{label}: lateral force (Fy) measured but no slip_angle given: the slip angle is "
            "read as 0 deg (a wheel driven straight); give slip_angle in its conditions if the "
            "wheel was steered"
        )
    return out


def set_warnings(datasets: Sequence[SWTDataset], labels: Sequence[str]) -> list[str]:
    """Responses measured in some datasets of the set but not in the others."""
    out = []
    for key in RESPONSE_KEYS:
        have = [lab for ds, lab in zip(datasets, labels, strict=True) if key in ds.responses]
        lack = [lab for ds, lab in zip(datasets, labels, strict=True) if key not in ds.responses]
        if have and lack:
            out.append(
                f"{response(key).words} ({key}) is measured in {', '.join(have)} but not in "
                f"{', '.join(lack)}: a study fits {key} only where it was measured; leave "
                f"{key} out of the case's responses, or add it to those files"
            )
    return out
