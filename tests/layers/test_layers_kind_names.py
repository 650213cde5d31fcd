"""No study kind's name is spelled outside its kind module and the registry
(``services/studies/kinds/``) and the tests (issue 43): the API, the dashboard (templates and
scripts included), the CLI, the worker and the store ask a kind for what they need (its
title, its collection, whether it has a posterior, its dashboard panel)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from layer_support import parse_file

from services.studies.kinds import KINDS

ROOT = Path(__file__).resolve().parents[2]
SCANNED = ("services", "worker")
SUFFIXES = (".py", ".html", ".js", ".css")
KIND_MODULES = ROOT / "services" / "studies" / "kinds"
#: (file, name): why the name stands there
ALLOWED = {
    ("services/store/models.py", "calibration"): "the server default of studies.kind (0011)",
    ("services/api/dashboard/templates/_new_study.html", "calibration"): "the form's kinds",
    ("services/api/dashboard/templates/_new_study.html", "sensitivity"): "the form's kinds",
    # the same words, not a kind: a prediction's role, a sentence, a submodule's name
    ("services/plots/predict.py", "calibration"): "a measurement's role in a prediction",
    ("services/api/routes/comparison.py", "calibration"): "an error message's noun",
    ("services/plots/__init__.py", "sensitivity"): "the submodule services.plots.sensitivity",
    ("services/cli/calibrate.py", "update"): "the section of a results folder's summary.json",
    ("services/cli/results.py", "update"): "the section of a results folder's summary.json",
    ("services/cli/parent.py", "update"): "the section of a results folder's summary.json",
}


def test_no_kind_name_outside_the_kind_modules() -> None:
    found = []
    for top in SCANNED:
        for path in sorted((ROOT / top).rglob("*")):
            if path.suffix not in SUFFIXES or KIND_MODULES in path.parents:
                continue
            text = path.read_text(encoding="utf-8")
            rel = path.relative_to(ROOT).as_posix()
            for name in KINDS:
                quoted = re.compile(rf"""["'=]{re.escape(name)}["'\]\s>]""")
                for k, line in enumerate(text.splitlines(), 1):
                    if quoted.search(line) and (rel, name) not in ALLOWED:
                        found.append(f"{rel}:{k}: {line.strip()}")
    assert found == [], "\n".join(found)


def test_the_check_finds_a_kind_name() -> None:
    name = next(iter(KINDS))
    for line in (f'if study.kind == "{name}":', f"kind='{name}'", f"value={name}]"):
        assert re.search(rf"""["'=]{re.escape(name)}["'\]\s>]""", line), line


#: the kind modules by their module name (``services.studies.kinds.<name>``)
KIND_MODULE_NAMES = sorted(
    f"services.studies.kinds.{p.stem}"
    for p in KIND_MODULES.glob("*.py")
    if p.stem not in ("__init__", "base", "registry")
)
ROUTES = ROOT / "services" / "api" / "routes"


def _kind_imports(path: Path) -> list[str]:
    found = []
    for node in ast.walk(parse_file(path)):
        if isinstance(node, ast.ImportFrom) and node.module in KIND_MODULE_NAMES:
            found.append(f"{path.name}:{node.lineno}: {node.module}")
        elif isinstance(node, ast.Import):
            found += [
                f"{path.name}:{node.lineno}: {a.name}"
                for a in node.names
                if a.name in KIND_MODULE_NAMES
            ]
    return found


def test_the_routes_import_no_kind_module() -> None:
    """The API's routes know the kinds through the registry and the protocol only: every
    kind's routes are mounted from its declaration (issue 72), none by hand."""
    assert "services.studies.kinds.calibration" in KIND_MODULE_NAMES
    found = [hit for path in sorted(ROUTES.glob("*.py")) for hit in _kind_imports(path)]
    assert found == [], "\n".join(found)


def test_the_route_check_finds_a_kind_import(tmp_path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text(f"from {KIND_MODULE_NAMES[0]} import KIND\nimport {KIND_MODULE_NAMES[-1]}\n")
    assert len(_kind_imports(bad)) == 2
