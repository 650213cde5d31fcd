"""A stage's own fields are declared once (issue 72: they were listed in the ORM model,
``records.StageRecord`` and the API's ``StageOut``, and copied one by one between them):
:class:`services.store.StageRecord`, its fields with a ``column`` in their metadata. The stages
table, ``StageOut``, the record's reader and the API's view take them from
:func:`services.store.stage_columns`; the plan and the reduction hand the store their
diagnostics by those names, checked against the declaration.

A second list is five or more of those twelve names declared in one class body (fields,
columns) or passed as keyword arguments of one call (a constructor copying them one by one),
anywhere in ``services/`` and ``worker/``: a study's totals and its progress share up to three
of the names (model and failed runs, log evidence, exponent) as quantities of their own, and
the lists this replaced held six to twelve. The sampler's own types in ``scm_core`` (``StagePlan``,
``StageState``) are the sampler's state, which the calibration kind translates into the
stage's columns, and are not scanned.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from services.store import PlannedStage, ReducedStage, SampleArrays, stage_columns

ROOT = Path(__file__).resolve().parents[2]
DECLARED = ROOT / "services" / "store" / "records.py"
FIVE = 5


def _second_lists(source: str, names: set[str]) -> list[str]:
    """Where ``source`` declares five or more of ``names`` in one class body or passes them
    as keyword arguments of one call: ``kind line: names``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ClassDef):
            declared = set()
            for stmt in node.body:
                targets = [stmt.target] if isinstance(stmt, ast.AnnAssign) else []
                targets += stmt.targets if isinstance(stmt, ast.Assign) else []
                declared |= {t.id for t in targets if isinstance(t, ast.Name)} & names
            if len(declared) >= FIVE:
                found.append(f"class {node.name} {node.lineno}: {sorted(declared)}")
        elif isinstance(node, ast.Call):
            passed = {k.arg for k in node.keywords if k.arg is not None} & names
            if len(passed) >= FIVE:
                found.append(f"call {node.lineno}: {sorted(passed)}")
    return found


def test_no_second_list_of_a_stages_fields() -> None:
    names = {f.name for f in stage_columns()}
    found = []
    for top in ("services", "worker"):
        for path in sorted((ROOT / top).rglob("*.py")):
            if path == DECLARED:
                continue
            for hit in _second_lists(path.read_text(encoding="utf-8"), names):
                found.append(f"{path.relative_to(ROOT).as_posix()}: {hit}")
    assert found == [], "\n".join(found)


def test_the_rule_catches_a_copied_list() -> None:
    names = {f.name for f in stage_columns()}
    five = ("exponent", "prev_exponent", "beta", "ess", "n_steps")
    schema = "class Out:\n" + "".join(f"    {n}: float\n" for n in five)
    copy = "Out(" + ", ".join(f"{n}=s.{n}" for n in five) + ")"
    four = "Out(" + ", ".join(f"{n}=s.{n}" for n in five[:4]) + ")"
    derived = "Out(**{n: getattr(s, n) for n in names}, stage=1)"
    assert _second_lists(schema, names) == [f"class Out 1: {sorted(five)}"]
    assert _second_lists(copy, names) == [f"call 1: {sorted(five)}"]
    assert _second_lists(four, names) == _second_lists(derived, names) == []


def test_the_stages_table_and_the_api_take_the_declaration() -> None:
    from services.api.schemas import StageOut
    from services.store.models import Stage

    columns = {c.name: c for c in Stage.__table__.columns}
    for f in stage_columns():
        assert columns[f.name].nullable == ("None" in str(f.type)), f.name
        assert StageOut.model_fields[f.name].description, f.name
    assert {f.name for f in stage_columns() if f.metadata["column"] == "bigint"} == {
        "model_runs",
        "failed_runs",
    }


def test_a_message_with_a_column_it_does_not_fill_is_refused() -> None:
    with pytest.raises(ValueError, match=r"not a stage diagnostic of a plan: \['acceptance'\]"):
        PlannedStage(stage=1, n_chains=2, blob=b"", diagnostics={"acceptance": 0.3})
    population = SampleArrays(*([None] * 4))
    with pytest.raises(ValueError, match=r"of a done: \['prev_exponent'\]"):
        ReducedStage(1, population, 2, 0, diagnostics={"prev_exponent": 0.5})
