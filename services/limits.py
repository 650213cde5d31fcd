"""Hard limits of the service, checked before anything is stored or allocated.

Each limit is a setting (:class:`services.config.Settings`, environment ``SCM_CALIB_MAX_*``)
with a documented default; a request over one is refused with a :class:`LimitError` whose
message names the request's field and the setting to raise.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

from scm_core.seeds import SEED_MAX
from services.config import Settings

#: largest id or count a database integer column (BIGINT) holds
INT64_MAX = 2**63 - 1
#: largest stage or batch index (INTEGER columns)
INT32_MAX = 2**31 - 1

_JSON_TOKENS = re.compile(rb'"(?:[^"\\]|\\.)*"|[\[\]{}]')


def seed_error(seed: int) -> str | None:
    """Why ``seed`` cannot seed a study (:data:`scm_core.seeds.SEED_MAX`), or None."""
    if not 0 <= int(seed) <= SEED_MAX:
        return f"must be 0 <= seed <= 2**63 - 1 (got {seed})"
    return None


def run_seeds(seed: int, runs: int) -> list[int]:
    """The seeds of ``runs`` repeated runs of a study seeded ``seed``: seed, seed + 1, ...;
    ValueError if the last would not fit a BIGINT column (the CLI checks the same, so a run
    group made there can be stored)."""
    if seed + runs - 1 > SEED_MAX:
        raise ValueError(f"the seeds from {seed} on pass 2**63 - 1")
    return [seed + k for k in range(runs)]


class LimitError(ValueError):
    """A request over a service limit; the message names the field and the setting."""


def _over(field: str, what: str, value: Any, limit: Any, setting: str) -> LimitError:
    return LimitError(
        f"{field}: {what} {value} is over the limit of {limit} "
        f"(server setting SCM_CALIB_{setting.upper()})"
    )


def max_batches(n: int, batch_size: int | None) -> int:
    """Most work batches one stage of ``n`` chains or points can be cut into with
    ``batch_size`` (guided self-scheduling never goes below an eighth of it, see
    :func:`worker.orchestrator.work_batches`), computed without making them."""
    if batch_size is None:
        return 1
    smallest = max(1, -(-int(batch_size) // 8))
    return -(-int(n) // smallest)


def check_study_size(
    settings: Settings,
    *,
    n_samples: int,
    max_stages: int,
    steps_per_chain: int,
    dataset_ids: Sequence[int],
    batch_size: int | None,
    samples_field: str = "n_samples",
) -> None:
    """Samples per stage, stages, datasets, work batches per stage and the worst-case model
    runs of a study (``n_samples`` x datasets x (1 + stages x steps per chain))."""
    if n_samples > settings.max_samples_per_stage:
        raise _over(
            samples_field,
            "samples per stage",
            n_samples,
            settings.max_samples_per_stage,
            "max_samples_per_stage",
        )
    if max_stages > settings.max_stages:
        raise _over("max_stages", "stages", max_stages, settings.max_stages, "max_stages")
    if len(dataset_ids) > settings.max_datasets_per_study:
        raise _over(
            "dataset_ids",
            "datasets",
            len(dataset_ids),
            settings.max_datasets_per_study,
            "max_datasets_per_study",
        )
    for k, did in enumerate(dataset_ids):
        if not 0 <= int(did) <= INT64_MAX:
            raise LimitError(f"dataset_ids.{k}: no dataset with id {did}")
    batches = max_batches(n_samples, batch_size)
    if batches > settings.max_batches_per_stage:
        need = math.ceil(n_samples / settings.max_batches_per_stage) * 8
        raise LimitError(
            f"batch_size: {batch_size} cuts {n_samples} samples into up to {batches} work "
            f"batches per stage, over the limit of {settings.max_batches_per_stage} (server "
            f"setting SCM_CALIB_MAX_BATCHES_PER_STAGE); use batch_size >= {need}"
        )
    runs = n_samples * max(1, len(dataset_ids)) * (1 + max_stages * steps_per_chain)
    if runs > settings.max_model_runs_per_study:
        raise LimitError(
            f"{samples_field}: up to {runs:.3g} model runs ({n_samples} samples x "
            f"{max(1, len(dataset_ids))} datasets x (1 + {max_stages} stages x "
            f"{steps_per_chain} steps)) is over the limit of "
            f"{settings.max_model_runs_per_study:.3g} (server setting "
            "SCM_CALIB_MAX_MODEL_RUNS_PER_STUDY); lower n_samples, max_stages or n_steps"
        )


def check_run_size(settings: Settings, prm: Any, where: str) -> None:
    """One simulator run (a packed parameter row): time steps, DEM cells and output rate.
    ``where``: what the run is for, e.g. ``dataset 3 (s020)``."""
    from scm_core.simulator.cost import run_size
    from scm_core.simulator.layout import P_DT, P_OUTEVERY

    size = run_size(prm)
    if size.steps > settings.max_steps_per_run:
        raise LimitError(
            f"simulator.duration: {where}: {size.steps} time steps per run (duration / dt) "
            f"is over the limit of {settings.max_steps_per_run} (server setting "
            "SCM_CALIB_MAX_STEPS_PER_RUN); shorten the duration or raise dt"
        )
    if size.grid_cells > settings.max_grid_cells:
        raise LimitError(
            f"simulator.dx: {where}: {size.grid_cells} grid cells per run is over the limit "
            f"of {settings.max_grid_cells} (server setting SCM_CALIB_MAX_GRID_CELLS); raise "
            "dx or shorten the duration"
        )
    rate = 1.0 / (prm[P_DT] * max(1, int(prm[P_OUTEVERY])))
    if rate > settings.max_output_rate * (1 + 1e-9):
        raise LimitError(
            f"simulator.output_rate: {where}: {rate:g} Hz is over the limit of "
            f"{settings.max_output_rate:g} Hz (server setting SCM_CALIB_MAX_OUTPUT_RATE)"
        )


def check_simulator_settings(settings: Settings, simulator: dict[str, Any]) -> None:
    """What can be refused from the case's simulator table alone, before any dataset is
    read: an output rate over the limit, or a duration / dt ratio over the step limit."""
    rate = simulator.get("output_rate")
    if isinstance(rate, int | float) and rate > settings.max_output_rate:
        raise _over(
            "simulator.output_rate",
            "output rate [Hz]",
            f"{rate:g}",
            f"{settings.max_output_rate:g}",
            "max_output_rate",
        )
    duration, dt = simulator.get("duration"), simulator.get("dt")
    if isinstance(duration, int | float) and isinstance(dt, int | float) and dt > 0:
        steps = duration / dt
        if steps > settings.max_steps_per_run:
            # blame dt when the duration would be fine at a 1 ms step
            fine_duration = duration <= settings.max_steps_per_run * 1e-3
            raise _over(
                "simulator.dt" if fine_duration else "simulator.duration",
                "time steps per run (duration / dt)",
                f"{steps:.3g}",
                settings.max_steps_per_run,
                "max_steps_per_run",
            )


def json_depth(raw: bytes) -> int:
    """Deepest nesting of arrays and objects in a JSON text (strings skipped), without
    parsing it: a check that runs before ``json.loads`` can recurse."""
    depth = deepest = 0
    for m in _JSON_TOKENS.finditer(raw):
        c = m.group()[:1]
        if c in b"[{":
            depth += 1
            deepest = max(deepest, depth)
        elif c in b"]}":
            depth -= 1
    return deepest


def check_json_depth(raw: bytes | str, max_depth: int, field: str = "body") -> None:
    """LimitError naming ``field`` when ``raw`` nests deeper than ``max_depth``."""
    data = raw.encode("utf-8", "surrogatepass") if isinstance(raw, str) else raw
    depth = json_depth(data)
    if depth > max_depth:
        raise _over(field, "JSON nesting depth", depth, max_depth, "max_json_depth")
