"""Sampler overhead of one TMCMC stage per model run (microseconds).

Target: 8-D Gaussian likelihood (sd 0.5) under a uniform box prior [-5, 5]^8, 2000 samples. The run
is advanced to stage 3 (so the proposal scale and step count are adapted), then stage 4 is planned,
run and reduced repeatedly from the same state. The likelihood is a cheap vectorised function
whose own time is measured and subtracted, so "overhead" is the sampler's cost alone:

    overhead per run = (stage wall time - time inside the likelihood) / model runs

Usage (from the repository root, or with the package installed):
    PYTHONPATH=. python benchmarks/bench_tmcmc.py [--reps 5] [--n-samples 2000] [--dim 8]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from scm_core.inference import JointPrior, TMCMCSettings, Uniform, run_tmcmc
from scm_core.inference.tmcmc.stage import plan_stage, reduce_stage, run_chains


class TimedGaussian:
    """log N(x; 0, 0.5^2 I) up to a constant, accumulating the time spent inside."""

    def __init__(self) -> None:
        self.seconds = 0.0

    def __call__(self, X: np.ndarray) -> np.ndarray:
        t0 = time.perf_counter()
        out = -0.5 * np.einsum("ij,ij->i", X, X) / 0.25
        self.seconds += time.perf_counter() - t0
        return out


def time_stage(state, prior, settings, batch_size: int | None, reps: int) -> dict[str, float]:
    walls, overheads, plans = [], [], []
    runs = 0
    for _ in range(reps):
        lik = TimedGaussian()
        t0 = time.perf_counter()
        plan = plan_stage(state, prior, settings)
        t1 = time.perf_counter()
        size = plan.n_chains if batch_size is None else batch_size
        batches = [range(i, min(i + size, plan.n_chains)) for i in range(0, plan.n_chains, size)]
        results = [run_chains(plan, b, lik) for b in batches]
        new = reduce_stage(plan, results)
        wall = time.perf_counter() - t0
        runs = new.model_runs
        walls.append(wall)
        plans.append(t1 - t0)
        overheads.append((wall - lik.seconds) / runs * 1e6)
    return {
        "runs": runs,
        "steps": new.n_steps,
        "wall_ms": statistics.median(walls) * 1e3,
        "plan_ms": statistics.median(plans) * 1e3,
        "overhead_us": statistics.median(overheads),
    }


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--n-samples", type=int, default=2000)
    ap.add_argument("--dim", type=int, default=8)
    args = ap.parse_args(argv)

    prior = JointPrior({f"x{i}": Uniform(-5.0, 5.0) for i in range(args.dim)})
    configs = [
        ("resample-move", None),
        ("resample-move", 100),
        ("resample-move", 10),
        ("resample-move", 1),
        ("leader", None),
        ("leader", 100),
    ]
    print(
        f"TMCMC stage overhead: {args.dim}-D Gaussian, {args.n_samples} samples, "
        f"median of {args.reps} repetitions, stage 4"
    )
    header = f"{'moves':<14} {'batch':>6} {'steps':>6} {'model runs':>11} {'stage ms':>10}"
    header += f" {'plan ms':>8} {'overhead us/run':>16}"
    print(header)
    print("-" * len(header))
    for moves, batch in configs:
        settings = TMCMCSettings(moves=moves)
        warm = run_tmcmc(
            TimedGaussian(),
            prior,
            n_samples=args.n_samples,
            seed=0,
            settings=TMCMCSettings(moves=moves, max_stages=3),
        )
        reps = args.reps if batch != 1 else max(5, args.reps // 2)
        row = time_stage(warm.stages[-1], prior, settings, batch, reps)
        print(
            f"{moves:<14} {batch if batch else 'all':>6} {row['steps']:>6} {row['runs']:>11} "
            f"{row['wall_ms']:>10.1f} {row['plan_ms']:>8.2f} {row['overhead_us']:>16.2f}"
        )


if __name__ == "__main__":
    main()
