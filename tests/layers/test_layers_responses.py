"""The measured responses are declared once (issue 72: a new response, the steered wheel's
lateral force, had to be added to every list by hand): ``scm_core/signals/responses.py``.
No other module of the library, the service or the worker spells the list of response keys
or of their lab columns; each takes it from there."""

from __future__ import annotations

import re
from pathlib import Path

from scm_core.signals.responses import COLUMN_OF, RESPONSE_KEYS, RESPONSES

ROOT = Path(__file__).resolve().parents[2]
DECLARED = ROOT / "scm_core" / "signals" / "responses.py"
#: a sequence of the response keys or of their columns written out, in any order
_KEY = r"""["'](F|T|z|Fy)["']"""
_COLUMN = r"""["'](drawbar_pull|torque|sinkage|lateral_force)["']"""
_LISTS = [
    re.compile(rf"{_KEY},\s*{_KEY},\s*{_KEY}"),
    re.compile(rf"{_COLUMN},\s*{_COLUMN}"),
]
#: (file, line text) where such a list is not a list of the responses
ALLOWED: set[tuple[str, str]] = {
    # the case file format's documentation: an example of what a user writes
    (
        "scm_core/calibration/case.py",
        'responses = ["F", "T", "z"]        # steady means entering the likelihood',
    ),
}


def test_the_responses_are_listed_in_one_module() -> None:
    found = []
    for top in ("scm_core", "services", "worker"):
        for path in sorted((ROOT / top).rglob("*.py")):
            if path == DECLARED:
                continue
            rel = path.relative_to(ROOT).as_posix()
            for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                allowed = any(rel == f and line.strip().startswith(t) for f, t in ALLOWED)
                if any(p.search(line) for p in _LISTS) and not allowed:
                    found.append(f"{rel}:{k}: {line.strip()}")
    assert found == [], "\n".join(found)


def test_what_is_derived_from_the_declaration() -> None:
    from scm_core import calibration
    from scm_core.signals.logformat import RESPONSE_COLUMNS
    from services.plots.fit import _ROWS

    assert calibration.RESPONSE_KEYS == RESPONSE_KEYS == tuple(r.key for r in RESPONSES)
    assert {k: f"sigma_{k}" for k in RESPONSE_KEYS} == calibration.SIGMA_NAMES
    assert tuple(COLUMN_OF[k] for k in RESPONSE_KEYS) == RESPONSE_COLUMNS
    assert [row[2] for row in _ROWS] == [
        "drawbar pull F [N]",
        "torque T [N m]",
        "sinkage z [mm]",
        "lateral force Fy [N]",
    ]
