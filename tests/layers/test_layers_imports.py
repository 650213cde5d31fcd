"""The layer rules, read from the source (every ``import``, also inside functions):

    entry points (services.api.main, the API's app factory; services.cli, the commands)
              ->  services.api (routes, dashboard), worker (the runtime)
              ->  services.studies  ->  services.stages  ->  services.store  ->  scm_core

plus ``services.config``/``services.limits`` (settings, usable from the store up),
``services.lifetime`` (a child process's lifetime: a leaf every tier may use) and
``services.plots``/``services.client`` (figures and the HTTP client: numerics only). A module
may import its own layer and the ones below it, never one above; only the entry points compose
the worker runtime (the routes and the dashboard do not reach it); the numerics know no
database, queue or web, the store no HTTP or queue, the study service no HTTP, queue or worker.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from layer_support import parse_file

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("scm_core", "services", "worker")

#: layer of a module (longest matching prefix) -> the layers it may import
ALLOWED: dict[str, set[str]] = {
    "scm_core": {"scm_core"},
    "services.config": {"services.config"},
    "services.limits": {"services.config", "scm_core"},
    "services.plots": {"services.plots", "scm_core"},
    "services.exports": {"services.exports", "scm_core"},
    "services.client": {"services.client", "services.config"},
    "services.store": {"services.store", "services.config", "services.limits", "scm_core"},
    "services.stages": {
        "services.stages",
        "services.store",
        "services.exports",
        "services.config",
        "services.limits",
        "scm_core",
    },
    "services.studies": {
        "services.studies",
        "services.stages",
        "services.store",
        "services.config",
        "services.limits",
        "scm_core",
    },
    "services.lifetime": {"services.lifetime"},
    "worker": {
        "worker",
        "services.studies",
        "services.stages",
        "services.store",
        "services.config",
        "services.lifetime",
        "scm_core",
    },
}
ALLOWED["services.api"] = (ALLOWED["worker"] - {"worker"}) | {
    "services.api",
    "services.limits",
    "services.plots",  # the dashboard's figures
    "services.exports",  # files for other tools (ArviZ)
}
#: the entry points: the one tier that composes the worker runtime
ALLOWED["services.api.main"] = ALLOWED["services.api"] | {"worker"}
ALLOWED["services.cli"] = ALLOWED["services.api"] | {
    "worker",
    "services.cli",
    "services.plots",
    "services.client",
}
ENTRY_POINTS = ("services.api.main", "services.cli")
ALLOWED["services"] = {"services"}  # the package's own __init__

#: third-party packages a layer must not import
FORBIDDEN: dict[str, set[str]] = {
    "scm_core": {"sqlalchemy", "alembic", "celery", "redis", "fastapi", "starlette", "httpx"},
    "services.store": {"celery", "redis", "fastapi", "starlette", "httpx"},
    "services.stages": {"celery", "redis", "fastapi", "starlette", "httpx", "sqlalchemy"},
    "services.studies": {"celery", "redis", "fastapi", "starlette", "httpx", "sqlalchemy"},
    "worker": {"fastapi", "starlette", "httpx"},
}


def _layer(module: str, layers) -> str | None:
    best = None
    for name in layers:
        if (module == name or module.startswith(name + ".")) and (
            best is None or len(name) > len(best)
        ):
            best = name
    return best


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path, module: str) -> list[tuple[int, str]]:
    """(line, absolute module) of every import in the file of ``module``."""
    tree = parse_file(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.append((node.lineno, mod))
    return out


def _sources() -> list[tuple[str, Path]]:
    paths = sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))
    return [(_module_name(p), p) for p in paths]


def violations(sources: list[tuple[str, Path]]) -> list[str]:
    """Imports of the (module, path) ``sources`` that break the rules, one line each."""
    found: list[str] = []
    for module, path in sources:
        layer = _layer(module, ALLOWED)
        assert layer is not None, f"{module} is in no layer"
        for line, target in _imports(path, module):
            top = target.split(".")[0]
            where = f"{path.name}:{line} ({module})"
            if (
                path.name == "__init__.py"
                and target.startswith(module + ".")
                and _layer(target, ENTRY_POINTS)
            ):
                continue  # a package re-exports its entry point (services.api: create_app)
            if top in PACKAGES:
                target_layer = _layer(target, ALLOWED) or target
                if target_layer not in ALLOWED[layer]:
                    found.append(f"{where}: {layer} imports {target} ({target_layer})")
            elif top in FORBIDDEN.get(_layer(module, FORBIDDEN) or "", set()):
                found.append(f"{where}: {layer} imports {top}")
    return found


def test_every_import_follows_the_layer_rules() -> None:
    bad = violations(_sources())
    assert not bad, "upward or forbidden imports:\n" + "\n".join(bad)


@pytest.mark.parametrize(
    ("layer", "source", "expected"),
    [
        ("services.store", "from services.studies import kinds\n", "imports services.studies"),
        ("services.studies", "import worker.orchestrator\n", "imports worker.orchestrator"),
        ("scm_core", "def f():\n    import sqlalchemy\n", "imports sqlalchemy"),
        ("services.studies", "from ...api import deps\n", "imports services.api"),
        ("services.api.routes", "from worker.local import LocalRuntime\n", "imports worker"),
        ("services.api.dashboard", "import worker.lifetime\n", "imports worker"),
    ],
)
def test_the_rule_catches_an_upward_import(tmp_path, layer, source, expected) -> None:
    """The checker itself: an upward import planted in a module of ``layer`` is reported."""
    planted = tmp_path / "planted.py"
    planted.write_text(source, encoding="utf-8")
    assert any(expected in v for v in violations([(f"{layer}.sub.planted", planted)]))


def test_only_the_entry_points_reach_the_worker_runtime() -> None:
    """Of ``services``, only the entry points import ``worker`` (the folders show the rule:
    ``worker/`` is reached from the app factory and the commands, nothing else)."""
    reaching = sorted(
        {
            module
            for module, path in _sources()
            if module.startswith("services")
            and any(t == "worker" or t.startswith("worker.") for _, t in _imports(path, module))
        }
    )
    assert reaching, "the entry points start the worker runtime"
    assert all(_layer(m, ENTRY_POINTS) for m in reaching), reaching
