"""One stage loop (issue 43): the library's in-memory driver (``run_tmcmc``) and the
service's (the calibration kind's batches and reducer) both go through :class:`Tempering`, and
nothing else outside the inference core steps a TMCMC stage itself (stage-0 points, the
stopping rule, the next plan, a stage's reduction), so the two cannot drift apart. The
command line runs its studies through the service's kinds and batch function
(``worker.here.run_here`` -> ``execute_batch``, which the Celery task and the embedded pool
call too), not a driver of its own."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
from layer_support import parse_file

from scm_core.inference import JointPrior, TruncatedNormal, run_tmcmc
from scm_core.inference.tmcmc.loop import Tempering
from scm_core.inference.tmcmc.stage import TMCMCSettings

ROOT = Path(__file__).resolve().parents[2]
#: the stage functions only the loop calls (the stage modules define them)
STEPS = {
    "initial_samples",
    "first_occurrences",
    "initial_state",
    "stage_status",
    "plan_stage",
    "reduce_stage",
}
LOOP = "scm_core/inference/tmcmc/loop.py"
DEFINED_IN = ("scm_core/inference/tmcmc/stage", "scm_core/inference/tmcmc/steps")


def _calls(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(parse_file(path)):
        if isinstance(node, ast.Call):
            f = node.func
            names.add(f.id if isinstance(f, ast.Name) else getattr(f, "attr", ""))
    return names


def test_only_the_loop_steps_a_stage() -> None:
    found = []
    for top in ("scm_core", "services", "worker"):
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel == LOOP or rel.startswith(DEFINED_IN):
                continue
            for name in sorted(_calls(path) & STEPS):
                found.append(f"{rel} calls {name}")
    assert found == [], "\n".join(found)


def test_both_drivers_go_through_the_loop() -> None:
    for rel in ("scm_core/inference/tmcmc/driver.py", "services/studies/kinds/calibration.py"):
        calls = _calls(ROOT / rel)
        assert {"Tempering", "begin", "advance"} <= calls, rel


def test_run_tmcmc_takes_every_stage_from_the_loop(monkeypatch) -> None:
    """At run time too: every stage run_tmcmc returns is one Tempering produced."""
    made = []
    begin, advance = Tempering.begin, Tempering.advance

    def spy(method):
        def wrapped(self, *args):
            step = method(self, *args)
            made.append(step.state)
            return step

        return wrapped

    monkeypatch.setattr(Tempering, "begin", spy(begin))
    monkeypatch.setattr(Tempering, "advance", spy(advance))
    prior = JointPrior({"x": TruncatedNormal(0.0, 1.0, -5.0, 5.0)})

    def loglik(X):
        return -0.5 * ((X[:, 0] - 1.0) / 0.5) ** 2

    res = run_tmcmc(loglik, prior, 200, seed=3, settings=TMCMCSettings(n_steps=2))
    assert res.status == "completed"
    assert [id(s) for s in res.stages] == [id(s) for s in made]
    assert np.isfinite(res.log_evidence)


#: the service's one batch function, and who calls it
BATCH = "execute_batch"
BATCH_CALLERS = ("worker/runtime.py", "worker/here.py")
#: the CLI's commands that run a study, through worker.here.run_here
STUDY_COMMANDS = (
    "services/cli/calibrate.py",
    "services/cli/sensitivity.py",
    "services/cli/predict.py",
)
#: drivers or numerics of a study the CLI must not call itself
OWN_DRIVERS = {
    "run_tmcmc",
    "run_sensitivity",
    "predict",
    "Tempering",
    "run_chains",
    "evaluate_points",
}


def test_the_cli_runs_studies_through_the_services_batches() -> None:
    for rel in BATCH_CALLERS:
        assert BATCH in _calls(ROOT / rel), rel
    for rel in STUDY_COMMANDS:
        assert "run_here" in _calls(ROOT / rel), rel
    found = []
    for path in sorted((ROOT / "services" / "cli").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        found += [f"{rel} calls {name}" for name in sorted(_calls(path) & OWN_DRIVERS)]
    assert found == [], "\n".join(found)
