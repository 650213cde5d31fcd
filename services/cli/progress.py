"""Progress of a ``scm-calib calibrate`` run: its display and what follows the study's stages."""

from __future__ import annotations

import math
import time
from typing import Any

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from scm_core.calibration import StageStart
from scm_core.calibration.failures import reasons_text
from scm_core.inference import StageState
from services.stages import DatabaseStages
from services.studies.kinds import kind_of

# ---------------------------------------------------------------------- progress


class StageDisplay:
    """Progress of the stages: a rich bar per stage (stage, exponent, evaluations done/planned,
    ETA) on a terminal; otherwise (a log file, a pipe) plain lines, one every 10 % of a stage
    and one per finished stage, flushed at once."""

    def __init__(self, quiet: bool, console: Console | None = None):
        self.quiet = quiet
        self.console = console or Console(stderr=True)
        self.lines = not self.console.is_terminal
        self.progress = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("evaluations"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=self.console,
            disable=quiet or self.lines,
        )
        self.task = None
        self.total = 1
        self.done = 0
        self.next_tenth = 1
        self.stage = 0
        self.t0 = time.perf_counter()

    def __enter__(self):
        self.progress.__enter__()
        return self

    def __exit__(self, *exc):
        return self.progress.__exit__(*exc)

    def _line(self, text: str) -> None:
        if not self.quiet:
            print(text, file=self.console.file, flush=True)

    def stage_start(self, s: StageStart) -> None:
        self.total = max(s.planned, 1)
        self.done = 0
        self.next_tenth = 1
        self.stage = s.stage
        self.t0 = time.perf_counter()
        if self.lines:
            self._line(
                f"stage {s.stage:2d} started: p = {s.exponent:.4g}, {s.planned} evaluations planned"
            )
            return
        desc = f"stage {s.stage:2d}  p = {s.exponent:.4g}"
        if self.task is not None:
            self.progress.update(self.task, visible=False)
        self.task = self.progress.add_task(desc, total=self.total)

    def batch(self, k: int) -> None:
        self.done += k
        if not self.lines:
            if self.task is not None:
                self.progress.advance(self.task, k)
            return
        crossed = False
        while self.next_tenth <= 9 and self.done * 10 >= self.next_tenth * self.total:
            self.next_tenth += 1  # a batch that crosses several tenths gives one line
            crossed = True
        if crossed and self.done < self.total:  # the stage's end has its own line
            elapsed = time.perf_counter() - self.t0
            frac = self.done / self.total
            eta = elapsed * (1 - frac) / frac
            self._line(
                f"stage {self.stage:2d}: {int(100 * frac):3d} % ({self.done}/{self.total} "
                f"evaluations), {elapsed:.0f} s elapsed, ETA {eta:.0f} s"
            )

    def stage_done(self, state: StageState, wall: float) -> None:
        if self.task is not None:
            self.progress.update(self.task, completed=self.total)
        if not self.quiet:
            rate = state.acceptance_rate
            acc = f"{rate:.2f}" if math.isfinite(rate) else "-"
            why = reasons_text(state.failed_runs, state.failed_by.to_dict())
            reasons = f" ({why})" if why else ""
            text = (
                f"stage {state.stage:2d} done: p = {state.exponent:.4g}, acceptance {acc}, "
                f"ESS {state.ess:.0f}, unique {state.n_unique}, model runs {state.model_runs}, "
                f"failed {state.failed_runs}{reasons}, {wall:.1f} s"
            )
            if state.part_runs_saved:
                n = state.part_runs_saved
                text += f", {n} simulation{'s' if n != 1 else ''} saved by early rejection"
            if state.surrogate_steps:
                text += (
                    f", {state.surrogate_steps} surrogate steps (acceptance "
                    f"{state.surrogate_steps_accepted / state.surrogate_steps:.2f}), "
                    f"{state.first_stage_rejections} moves turned down without a run"
                )

            if self.lines:
                self._line(text)
            else:
                self.progress.console.print(text)


# ---------------------------------------------------------------------- a study's stages


class StageWatch:
    """Follows a study run here (:data:`worker.here.Watch`: called after each batch, or at
    each look while a pool runs them): the display's stage starts, batches and finished
    stages, from the stage ``done`` (those the store held when the session began are not
    shown again), and each finished stage's wall time [s] in :attr:`walls` (timed here if it
    ran in this session, else from the store's times: :func:`stored_walls`)."""

    def __init__(self, display: StageDisplay, done: int):
        self.display = display
        self.saved = done
        self.walls: dict[int, float] = {}
        self.stage: int | None = None
        self.planned: list[int] = []
        self.counted: set[int] = set()
        self.t_stage = time.perf_counter()
        self.session = True

    def __call__(self, store: Any, study: Any) -> None:
        stages = DatabaseStages(store, study.id)
        while self.saved < stages.count():
            state = stages.state(self.saved)
            wall = self._wall(store, study, self.saved)
            self.walls[self.saved] = wall
            self.display.stage_done(state, wall)
            self.saved += 1
        if study.status not in ("queued", "running") or study.current_stage is None:
            return
        batches = store.batches.list(study.id, study.current_stage)
        if study.current_stage != self.stage:
            self.stage = int(study.current_stage)
            plan = store.stages.plan(study.id, self.stage)
            ranges = [range(b.chain_start, b.chain_stop) for b in batches]
            self.planned = kind_of(study.kind).planned_runs(plan, ranges)
            self.counted = set()
            self.t_stage = time.perf_counter()
            exponent = store.stages.get(study.id, self.stage).exponent or 0.0
            self.display.stage_start(
                StageStart(self.stage, float(exponent), sum(self.planned), len(batches))
            )
        for b in batches:
            if b.status == "done" and b.key.batch_index not in self.counted:
                self.counted.add(b.key.batch_index)
                self.display.batch(self.planned[b.key.batch_index])

    def _wall(self, store: Any, study: Any, index: int) -> float:
        """Seconds stage ``index`` took: timed here if it ran in this session, else from
        the store's times."""
        if index == self.stage:
            return time.perf_counter() - self.t_stage
        return stored_walls(store, study)[index]


def stored_walls(store: Any, study: Any) -> list[float]:
    """Seconds each stage of ``study`` took by the store's times (one read): its end less the
    previous stage's (or the study's start); 0 where a time is missing."""
    begin = study.started_at
    walls = []
    for row in store.stages.list(study.id):
        end = row.finished_at
        walls.append(max(0.0, (end - begin).total_seconds()) if end and begin else 0.0)
        begin = end
    return walls
