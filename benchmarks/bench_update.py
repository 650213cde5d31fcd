"""A posterior update against the joint study it replaces (issue 10; paper section 5.3).

The quick example case (``examples/quick.toml``: k_phi, n, phi, J; 500 samples per stage, leader
moves) is calibrated three ways for each seed:

* joint: both example logs (slips 0.2 and 0.5) from the prior;
* base: the slip 0.2 log alone from the prior;
* update: the base posterior updated with the slip 0.5 log (stage 0 = the base's final
  population, the slip 0.2 likelihood in the base density, stage 1 tuned with the base's final
  proposal scale and acceptance rate; seed = base seed + 1, as the CLI and the service).

The moves default to the accurate resample-move form (``--moves leader`` for the paper's form,
whose run-to-run scatter at 500 samples is itself 0.3-0.5 posterior sd in the means).

It prints one row per seed and study (model runs = likelihood evaluations, a point repeated in
an update's stage 0 evaluated once; simulations = the
simulator runs they made, datasets one by one with early rejection (the default, exact: the
runs it saved are the next column, so without it a study makes simulations + saved); stages;
wall time on the chosen workers; log evidence) and, per parameter, the distance of the update's
posterior mean to the joint one in joint posterior sd, with the two-sample KS statistic. The
update's total log evidence (base + increment) estimates the joint one.

Usage (from the repository root):
    PYTHONPATH=. python benchmarks/bench_update.py [--seeds 7 8 9] [--workers 2] [--samples 500]
        [--moves resample-move|leader|waste-free] [--surrogate-steps K]
        [--proposal-scale linear|log]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.stats import ks_2samp

from scm_core.calibration import (
    PopulationStart,
    StudyModel,
    UpdateLikelihood,
    load_case,
    run_tmcmc,
)
from scm_core.inference.tmcmc.moves import stage_chains
from scm_core.signals import load_dataset
from services.studies.batching import local_batch_size
from worker.batch_map import batch_map

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "quick.toml"
LOGS = [ROOT / "examples" / "wf34_s020.csv", ROOT / "examples" / "wf34_s050.csv"]


def _run(func, case, seed, mapper, batch_size, start=None):
    t0 = time.perf_counter()
    result = run_tmcmc(
        func,
        case.prior(),
        case.sampler.n_samples,
        seed,
        case.tmcmc_settings(),
        map=mapper,
        batch_size=batch_size,
        start=None
        if start is None
        else PopulationStart(
            start.samples, (start.beta, start.acceptance_rate), func.base_parts(start.responses)
        ),
    )
    return result, time.perf_counter() - t0


def _simulations(result) -> int:
    """Simulator runs of a study (every dataset of every evaluation that early rejection did
    not cut short)."""
    return sum(s.part_runs for s in result.stages)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[7, 8, 9])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--samples", type=int, default=500)
    ap.add_argument(
        "--moves",
        choices=["leader", "resample-move", "waste-free"],
        default="resample-move",
        help="TMCMC moves (the quick case's own are the leader form's)",
    )
    ap.add_argument(
        "--surrogate-steps",
        type=int,
        default=0,
        help="surrogate transitions with this many surrogate steps per model run (0: off)",
    )
    ap.add_argument(
        "--proposal-scale",
        choices=["linear", "log"],
        default="linear",
        help="random-walk coordinates (log: of every positive parameter)",
    )
    args = ap.parse_args()

    sampler = {"n_samples": args.samples, "moves": args.moves}
    sampler["proposal_scale"] = args.proposal_scale
    if args.surrogate_steps:
        sampler |= {"delayed_acceptance": True, "surrogate_steps": args.surrogate_steps}
    case = load_case(CASE).with_changes(sampler=sampler)
    data = [load_dataset(p, offset=case.data.offset, cutoff_hz=case.data.cutoff_hz) for p in LOGS]
    names = list(case.parameter_names)
    batch = local_batch_size(stage_chains(args.samples, case.tmcmc_settings()), args.workers)
    accel = f", surrogate steps {args.surrogate_steps}" if args.surrogate_steps else ""
    accel += f", {args.proposal_scale} walk"
    runs = Table(title=f"quick case, {args.samples} samples, {case.sampler.moves} moves{accel}")
    cols = ("seed", "study", "stages", "model runs", "simulations", "saved by ER", "wall s")
    cols = (*cols, "log Z")
    for col in cols:
        runs.add_column(col, justify="right" if col not in ("study",) else "left")
    dist = Table(title="update vs joint: |mean difference| / joint sd  (KS statistic)")
    dist.add_column("seed", justify="right")
    for n in names:
        dist.add_column(n, justify="right")
    dist.add_column("model-run ratio", justify="right")
    dist.add_column("simulation ratio", justify="right")
    dist.add_column("log Z total - joint", justify="right")
    worst, ratios, run_ratios = [], [], []
    with batch_map(args.workers) as mapper:
        for seed in args.seeds:
            joint_model = StudyModel(case, data)
            joint, t_joint = _run(joint_model, case, seed, mapper, batch)
            base_model = StudyModel(case, data[:1])
            base, t_base = _run(base_model, case, seed, mapper, batch)
            upd, t_upd = _run(
                UpdateLikelihood(joint_model, 1),
                case,
                seed + 1,
                mapper,
                batch,
                start=base.final,
            )
            total = base.log_evidence + upd.log_evidence
            for label, r, t, z in (
                ("joint", joint, t_joint, joint.log_evidence),
                ("base (slip 0.2)", base, t_base, base.log_evidence),
                ("update (+ slip 0.5)", upd, t_upd, upd.log_evidence),
            ):
                runs.add_row(
                    str(seed),
                    label,
                    str(len(r.stages) - 1),
                    str(r.n_model_runs),
                    str(_simulations(r)),
                    str(sum(s.part_runs_saved for s in r.stages)),
                    f"{t:.0f}",
                    f"{z:.3f} +- {r.log_evidence_se:.3f}",
                )
            a, b = upd.samples, joint.samples
            sd = b.std(axis=0, ddof=1)
            d = np.abs(a.mean(axis=0) - b.mean(axis=0)) / sd
            ks = [ks_2samp(a[:, j], b[:, j]).statistic for j in range(len(names))]
            worst.append(float(d.max()))
            ratio = _simulations(upd) / _simulations(joint)
            ratios.append(ratio)
            run_ratios.append(upd.n_model_runs / joint.n_model_runs)
            dist.add_row(
                str(seed),
                *[f"{d[j]:.3f} ({ks[j]:.3f})" for j in range(len(names))],
                f"{run_ratios[-1]:.2f}",
                f"{ratio:.2f}",
                f"{total - joint.log_evidence:+.3f}",
            )
    console = Console(width=140)
    console.print(runs)
    console.print(dist)
    console.print(
        f"worst mean distance per seed: {', '.join(f'{w:.3f}' for w in worst)} sd; "
        f"median update/joint ratio: model runs {statistics.median(run_ratios):.2f}, "
        f"simulations {statistics.median(ratios):.2f}"
    )


if __name__ == "__main__":
    main()
