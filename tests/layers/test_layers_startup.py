"""Processes start without the libraries they do not use at start.

matplotlib, scipy.stats, scipy.signal and scipy.spatial each take about a second to import on
a slow core, and every process of the service would pay for them: the API, each embedded pool
process and Celery worker, each figure process, each CLI command. They load on first use
instead (a figure drawn, a log filtered, a truncated normal prior evaluated, a surrogate
fitted); ``benchmarks/bench_startup.py`` measures what that saves. Each entry module is imported
in a fresh interpreter here, since this test process has long loaded them all.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

LAZY = ("matplotlib", "scipy.stats", "scipy.signal", "scipy.spatial")

ENTRIES = (
    "services.api.main",  # the API (its figures are drawn in figure processes)
    "worker.runtime",  # an embedded pool process, a Celery worker
    "worker.tasks",
    "services.cli.calibrate",
    "services.cli.predict",
    "scm_core.calibration",
    "services.api.dashboard",  # the pages decide which figures to link without drawing them
)

_PROBE = "import importlib, json, sys; importlib.import_module(sys.argv[1]); " + (
    "print(json.dumps([m for m in sys.argv[2:] if m in sys.modules]))"
)


def _loaded(module: str, *names: str) -> list[str]:
    out = subprocess.run(
        [sys.executable, "-c", _PROBE, module, *names],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)


@pytest.mark.parametrize("module", ENTRIES)
def test_entry_modules_import_no_heavy_library(module: str) -> None:
    assert _loaded(module, *LAZY) == []


def test_the_lazy_libraries_load_when_used() -> None:
    """What the entry modules leave out is still there when it is needed: a Table 2 prior's
    density (truncated normals: scipy.stats), a figure drawn (matplotlib; a chart's data needs
    none), a filtered log (scipy.signal)."""
    probe = (
        "import sys, numpy as np\n"
        "from scm_core.inference.priors import table2_prior\n"
        "p = table2_prior('1')\n"
        "assert 'scipy.stats' not in sys.modules\n"
        "assert np.isfinite(p.log_pdf(p.sample(np.random.default_rng(0), 3))).all()\n"
        "from scm_core.signals.processing import lowpass\n"
        "lowpass(np.sin(np.linspace(0, 20, 400)), 50.0)\n"
        "import services.plots as plots\n"
        "assert 'matplotlib' not in sys.modules\n"
        "chart = plots.stages.schedule_chart([0, 1, 2], [0.0, 0.3, 1.0], [None, 0.5, 0.4])\n"
        "assert 'matplotlib' not in sys.modules\n"  # a chart is data: the page draws it
        "plots.figures.render(plots.mpl.draw(chart), 'svg')\n"
        "print(' '.join(m for m in ('scipy.stats', 'scipy.signal', 'matplotlib') "
        "if m in sys.modules))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, check=False
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["scipy.stats", "scipy.signal", "matplotlib"]
