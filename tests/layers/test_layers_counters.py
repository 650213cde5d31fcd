"""The sampler's counters are declared once (issue 72: they were listed in eight files):
:class:`scm_core.inference.StageCounts`. No other module writes out a list of them (three or
more of their names as strings in one file: a tuple of names, a dict of them, a schema's
fields); the stage record, the API's ``StageOut``, the summary's stage table and the CLI take
them from :func:`scm_core.inference.count_fields`."""

from __future__ import annotations

import re
from pathlib import Path

from scm_core.inference import StageCounts, count_fields

ROOT = Path(__file__).resolve().parents[2]
DECLARED = ROOT / "scm_core" / "inference" / "tmcmc" / "types.py"


def test_no_second_list_of_the_counters() -> None:
    names = [name for name, _ in count_fields()]
    alternatives = "|".join(map(re.escape, names))
    quoted = re.compile(rf"""["']({alternatives})["']""")
    found = []
    for top in ("scm_core", "services", "worker"):
        for path in sorted((ROOT / top).rglob("*")):
            if path.suffix not in (".py", ".html", ".js") or path == DECLARED:
                continue
            seen = set(quoted.findall(path.read_text(encoding="utf-8")))
            if len(seen) >= 3:
                found.append(f"{path.relative_to(ROOT).as_posix()}: {sorted(seen)}")
    assert found == [], "\n".join(found)


def test_the_api_schema_has_every_counter_with_its_description() -> None:
    from services.api.schemas import StageOut

    fields = StageOut.model_fields
    for name, doc in count_fields():
        assert fields[name].description == doc
    assert {f for f in StageCounts.__dataclass_fields__} - fields.keys() == set()
