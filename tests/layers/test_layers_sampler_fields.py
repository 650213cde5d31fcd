"""One declaration of the sampler's settings (issue 72): a case's ``[sampler]`` keys
(``SamplerSettings``) are generated from ``TMCMCSettings``' fields, read here from the source;
``scm_core/calibration/sampler_settings.py`` declares only the keys that are not TMCMCSettings
fields and names the others, so none of its class fields, ``create_model`` keywords or
pydantic field definitions may be a TMCMCSettings field again."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

from layer_support import parse_file

from scm_core.calibration.sampler_settings import (
    CASE_KEYS,
    FORM_KEYS,
    TUNING,
    SamplerSettings,
)
from scm_core.inference import TMCMCSettings
from scm_core.inference.tmcmc.moves import STUDY_MOVES

ROOT = Path(__file__).resolve().parents[2]
DECLARED = ROOT / "scm_core" / "inference" / "tmcmc" / "types.py"
CASE = ROOT / "scm_core" / "calibration" / "sampler_settings.py"


def declared_settings(tree: ast.Module) -> set[str]:
    """The fields of the class ``TMCMCSettings`` in ``tree``."""
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef) and node.name == "TMCMCSettings":
            return {
                s.target.id
                for s in node.body
                if isinstance(s, ast.AnnAssign) and isinstance(s.target, ast.Name)
            }
    raise AssertionError("no class TMCMCSettings")


def _is_field_definition(node: ast.expr) -> bool:
    """``Field(...)`` or a pydantic ``(type, default)`` pair."""
    if isinstance(node, ast.Call):
        f = node.func
        return (f.id if isinstance(f, ast.Name) else getattr(f, "attr", "")) == "Field"
    return isinstance(node, ast.Tuple) and len(node.elts) == 2


def redeclared(tree: ast.Module, names: set[str]) -> list[str]:
    """``name (line)`` of every field of ``names`` that ``tree`` declares: a class field, a
    ``create_model`` keyword or a dict entry defining a pydantic field."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef):
            found += [
                (s.target.id, s.lineno)
                for s in node.body
                if isinstance(s, ast.AnnAssign)
                and isinstance(s.target, ast.Name)
                and s.target.id in names
            ]
        elif isinstance(node, ast.Call) and getattr(node.func, "id", "") == "create_model":
            found += [(k.arg, node.lineno) for k in node.keywords if k.arg in names]
        elif isinstance(node, ast.Dict):
            found += [
                (k.value, k.lineno)
                for k, v in zip(node.keys, node.values, strict=True)
                if isinstance(k, ast.Constant) and k.value in names and _is_field_definition(v)
            ]
    return [f"{name} (line {line})" for name, line in sorted(found)]


def test_no_sampler_field_is_declared_twice() -> None:
    names = declared_settings(parse_file(DECLARED))
    assert names == {f.name for f in dataclasses.fields(TMCMCSettings)}
    found = redeclared(parse_file(CASE), names)
    assert not found, "TMCMCSettings fields declared again:\n" + "\n".join(found)


def test_every_setting_is_a_case_key_with_the_samplers_default() -> None:
    """Each field is a key: the sampler's default, except the case's default move scheme and
    the keys its move scheme fills (null until then)."""
    fields = SamplerSettings.model_fields
    assert set(CASE_KEYS) | set(TUNING) == {f.name for f in dataclasses.fields(TMCMCSettings)}
    assert not set(CASE_KEYS) & set(TUNING)
    for f in dataclasses.fields(TMCMCSettings):
        expected = STUDY_MOVES if f.name == "moves" else None if f.name in FORM_KEYS else f.default
        assert fields[f.name].default == expected, f.name
        assert fields[f.name].description == f.metadata.get("doc"), f.name


def test_the_rule_catches_a_second_declaration() -> None:
    tree = ast.parse(
        "class A(BaseModel):\n    beta0: float = 0.2\n    other: int = 1\n"
        "B = create_model('B', min_steps=(int, 10))\n"
        "C = {'max_steps': (int, 50), 'moves': 'leader'}\n"
        "D = {'stall_tol': Field(1e-8)}\n"
    )
    names = {"beta0", "min_steps", "max_steps", "stall_tol", "moves"}
    assert redeclared(tree, names) == [
        "beta0 (line 2)",
        "max_steps (line 5)",
        "min_steps (line 4)",
        "stall_tol (line 6)",
    ]
