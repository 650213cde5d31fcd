"""A coarse-grid simulator against the response surrogate as the cheap stage of delayed acceptance.

Run: ``python benchmarks/bench_coarse_model.py RESULTS [--points 40] [--factors 1.5 2]`` with
RESULTS the folder of a finished ``scm-calib calibrate`` (e.g. of ``examples/cmu_smooth.toml``).

From the final population x (posterior samples) it draws one random-walk proposal y per point
(the sampler's own step: the final proposal scale beta times the population's covariance) and
evaluates the log-likelihood at x and y with the case's simulator, with the same simulator on a
grid coarsened by each ``--factors`` f (dx times f, dt from the rig's rules), and with the
study's response surrogate (fitted, as the sampler does, on the final population and the states
the simulator evaluated). For an approximation a with error e = log L_a - log L, delayed
acceptance's exact stage accepts what the cheap stage passed with min(1, exp(-(e(y) - e(x))))
at exponent 1 (Christen & Fox 2005), so the table gives, per approximation, the cost per
evaluation relative to the simulator, the spread of e(y) - e(x) and the mean of that factor: an
approximation pays as a stage before the simulator only if it is much cheaper and its factor is
near one.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from scm_core.calibration.model import StudyModel
from scm_core.inference.surrogate import fit_surrogate
from scm_core.simulator.rig import resolve_rig
from services.cli.common import read_datasets
from services.cli.parent import load_parent


def _log_likelihood(model: StudyModel, X: np.ndarray) -> tuple[np.ndarray, float]:
    """(log L (m,), wall time per row [s])."""
    t0 = time.perf_counter()
    ll = model.log_likelihood_batch(X)[0]
    return np.asarray(ll, float), (time.perf_counter() - t0) / len(X)


def _coarse_model(model: StudyModel, case, datasets, factor: float) -> StudyModel:
    """The case with dx (and the dt the rig derives from it) coarsened by ``factor``: dx taken
    from the first dataset's resolved rig at the prior medians."""
    prior = case.prior()
    median = prior.ppf(np.full((1, prior.dim), 0.5))[0]
    _, wheel, rig = model.configs(median, 0)
    dx = resolve_rig(wheel, rig).dx
    simulator = {**case.to_dict().get("simulator", {}), "dx": dx * factor}
    return StudyModel(case.with_changes(simulator=simulator), datasets)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", type=Path)
    ap.add_argument("--points", type=int, default=40)
    ap.add_argument("--factors", type=float, nargs="+", default=[1.5, 2.0])
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    study = load_parent(args.results)
    case, final = study.case, study.final
    datasets = read_datasets(case, study.dataset_paths)
    model = StudyModel(case, datasets)
    rng = np.random.default_rng(args.seed)
    pick = rng.choice(final.samples.shape[0], args.points, replace=False)
    X = final.samples[pick]
    chol = np.linalg.cholesky(np.cov(final.samples.T) + 1e-12 * np.eye(X.shape[1]))
    Y = X + final.beta * rng.standard_normal(X.shape) @ chol.T
    inside = np.asarray(case.prior().in_support(Y))
    X, Y = X[inside], Y[inside]

    _log_likelihood(model, X[:2])  # compile / load the simulator
    ll_x, t_fine = _log_likelihood(model, X)
    ll_y, _ = _log_likelihood(model, Y)
    rows = []
    settings = case.tmcmc_settings()
    train_x = np.concatenate([final.samples, final.train_samples])
    train_r = np.concatenate([final.responses, final.train_responses])
    sur = fit_surrogate(
        train_x,
        train_r,
        tuple(model.response_inputs),
        settings.surrogate_neighbors,
        settings.surrogate_smoothing,
    )
    t0 = time.perf_counter()
    sx = np.asarray(model.from_responses(X, sur.predict(X))[0], float)
    sy = np.asarray(model.from_responses(Y, sur.predict(Y))[0], float)
    t_sur = (time.perf_counter() - t0) / (2 * len(X))
    rows.append(("response surrogate", t_sur, sx, sy))
    for f in args.factors:
        coarse = _coarse_model(model, case, datasets, f)
        _log_likelihood(coarse, X[:2])
        cx, t_c = _log_likelihood(coarse, X)
        cy, _ = _log_likelihood(coarse, Y)
        rows.append((f"simulator, dx x {f:g}", t_c, cx, cy))

    table = Table(
        title=f"{args.results}: {len(X)} posterior points and one proposal each "
        f"(simulator {1000 * t_fine:.0f} ms per evaluation on all cores)"
    )
    columns = ("cheap stage", "cost / simulator", "|de| median", "|de| 90 %", "exact-stage factor")
    for col in columns:
        table.add_column(col, justify="right")
    for name, t, ax, ay in rows:
        de = (ay - ll_y) - (ax - ll_x)
        ok = np.isfinite(de)
        factor = np.where(ok, np.exp(-np.maximum(np.where(ok, de, 0.0), 0.0)), 0.0)
        table.add_row(
            name,
            f"{t / t_fine:.3f}",
            f"{np.median(np.abs(de[ok])):.2f}",
            f"{np.percentile(np.abs(de[ok]), 90):.2f}",
            f"{factor.mean():.2f}",
        )
    Console(width=120).print(table)


if __name__ == "__main__":
    main()
