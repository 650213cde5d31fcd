"""Least-squares fit of a case's physical parameters to its datasets' trial means.

A deterministic companion to a calibration: it finds the parameters (the simulator's and the
measurement offsets; sigmas held) that bring the simulated steady means closest to the measured
ones, within the prior's bounds, from a chosen start, and reports the case's own log-likelihood
there with each prediction-error sigma profiled (sigma^2 = mean squared residual over the tests
that count, clipped to its prior). A posterior whose best log-likelihood lies well below the
value printed here has not reached that region: the fit locates likelihood modes a sampler
should see.

Residuals are (simulated - measured) / weight per response (default 1 N, 1 N m, 2 mm);
log-uniform priors are fitted in log space; the Jacobian is one batched simulator call of
d + 1 points (forward differences). ``--check`` datasets are simulated at the fit and compared
with the issue's tolerances (max(1.5 N, 20 % |F|), 3 mm) but not fitted.

Usage (from the repository root):
    PYTHONPATH=. python examples/fit_least_squares.py examples/cmu_smooth.toml \\
        --check examples/cmu_smooth/*.csv --start k_phi=5.2e6 --start n=1.19 --start phi=30.4
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.optimize import least_squares

from scm_core.calibration import RESPONSES, SIGMA_NAMES, CaseError, StudyModel, load_case
from scm_core.inference.priors import LOG_SCALE_KINDS
from scm_core.signals import load_dataset


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("case", type=Path)
    ap.add_argument("--check", type=Path, nargs="*", default=[], help="datasets to predict")
    ap.add_argument("--start", action="append", default=[], help="NAME=VALUE (default: median)")
    ap.add_argument("--weights", default="F=1,T=1,z=0.002", help="residual scale per response")
    ap.add_argument("--max-evals", type=int, default=40)
    args = ap.parse_args()

    try:
        case = load_case(args.case)
    except CaseError as exc:
        ap.error(str(exc))
    fit_files = [args.case.parent / f for f in case.data.files]
    check_files = [f for f in args.check if f.resolve() not in {p.resolve() for p in fit_files}]
    model = StudyModel(case, [load_dataset(f) for f in fit_files + check_files])
    n_fit = len(fit_files)
    prior = case.prior()
    names = prior.names
    free = list(model.response_inputs)  # simulator parameters and measurement offsets
    logs = [prior.dists[names[j]].kind in LOG_SCALE_KINDS for j in free]
    x0 = np.array([float(prior.dists[n].ppf(0.5)) for n in names])
    for item in args.start:
        key, _, value = item.partition("=")
        if key not in names:
            ap.error(f"--start {item}: {key!r} is not a calibrated parameter of {names}")
        try:
            x0[names.index(key)] = float(value)
        except ValueError:
            ap.error(f"--start {item}: {value!r} is not a number")
    try:
        weights = dict(zip(RESPONSES, (1.0, 1.0, 0.002), strict=True))
        for kv in args.weights.split(","):
            key, _, value = kv.partition("=")
            if key not in RESPONSES or not float(value) > 0:
                raise ValueError(kv)
            weights[key] = float(value)
    except ValueError as exc:
        ap.error(f"--weights: expected F=..,T=..,z=.. with positive numbers, got {exc}")
    w = np.array([weights[r] for r in RESPONSES])
    used = list(model.used)

    def to_x(u: np.ndarray) -> np.ndarray:
        x = x0.copy()
        x[free] = np.where(logs, np.exp(u), u)
        return x

    lo, hi = prior.bounds[free].T

    def to_u(x: np.ndarray) -> np.ndarray:
        return np.where(logs, np.log(np.where(logs, x, 1.0)), x)

    ulo, uhi = to_u(lo), to_u(hi)

    def residuals(U: list[np.ndarray]) -> np.ndarray:
        means, _ = model.simulate_means(np.array([to_x(u) for u in U]), datasets=range(n_fit))
        r = (means[:, :n_fit, used] - model.x_exp[None, :n_fit, used]) / w[used]
        return np.where(np.isfinite(r), r, 50.0)[:, np.isfinite(model.x_exp[:n_fit, used])]

    def jac(u: np.ndarray) -> np.ndarray:
        h = 1e-2 * np.maximum(np.abs(u), 0.05)
        R = residuals([u] + [u + h[k] * np.eye(len(u))[k] for k in range(len(u))])
        return ((R[1:] - R[0]) / h[:, None]).T

    u0 = np.clip(to_u(x0[free]), ulo, uhi)
    fit = least_squares(
        lambda u: residuals([u])[0], u0, jac=jac, bounds=(ulo, uhi), max_nfev=args.max_evals
    )
    x = to_x(fit.x)
    means, _ = model.simulate_means(x[None])

    # the case's log-likelihood at the fit, each sigma profiled over the fitted datasets
    sig_cols = {r: names.index(SIGMA_NAMES[r]) for r in RESPONSES if SIGMA_NAMES[r] in names}
    fitted = model.x_exp[:n_fit]
    for r, col in sig_cols.items():
        i = RESPONSES.index(r)
        ok = np.isfinite(fitted[:, i])
        n_tests = np.array(model.n_tests[:n_fit])[ok]
        sd = np.array([d.trial_sd[i] for d in model.datasets[:n_fit]])
        ss = n_tests * (means[0, :n_fit, i][ok] - fitted[ok, i]) ** 2
        if case.trials == "each":
            ss = ss + (n_tests - 1) * np.nan_to_num(sd[ok]) ** 2
        dist = prior.dists[names[col]]
        x[col] = min(max(math.sqrt(ss.sum() / n_tests.sum()), dist.lower + 1e-12), dist.upper)
    sigmas = model.sigmas(x[None])
    log_l = float(model.log_likelihood_from_means(means, sigmas, range(n_fit))[0])

    console = Console()
    table = Table(title=f"{case.name}: least squares ({fit.nfev} evaluations), log L {log_l:.2f}")
    for col in ("dataset", "role", *(f"{r} sim / meas" for r in RESPONSES if r in case.responses)):
        table.add_column(col)
    for k, d in enumerate(model.datasets):
        cells = []
        for r in case.responses:
            i = RESPONSES.index(r)
            sim, meas = means[0, k, i], model.x_exp[k, i]
            scale = 1e3 if r == "z" else 1.0
            tol = 0.003 if r == "z" else max(1.5, 0.2 * abs(meas))
            mark = "" if not np.isfinite(meas) else (" ok" if abs(sim - meas) <= tol else " --")
            cells.append(f"{sim * scale:.2f} / {meas * scale:.2f}{mark}")
        table.add_row(d.name, "fit" if k < n_fit else "check", *cells)
    console.print(table)
    console.print({n: float(f"{x[j]:.4g}") for j, n in enumerate(names)})


if __name__ == "__main__":
    main()
