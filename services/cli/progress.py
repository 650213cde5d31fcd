"""Progress and Ctrl-C of a ``scm-calib calibrate`` run."""

from __future__ import annotations

import math
import signal
import threading
import time
from collections.abc import Callable
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
from scm_core.inference import StageState
from scm_core.inference.wrapped import WrappedLikelihood

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
            text = (
                f"stage {state.stage:2d} done: p = {state.exponent:.4g}, acceptance {acc}, "
                f"ESS {state.ess:.0f}, unique {state.n_unique}, model runs {state.model_runs}, "
                f"failed {state.failed_runs}, {wall:.1f} s"
            )
            if state.part_runs_saved:
                text += f", {state.part_runs_saved} simulations saved by early rejection"
            if state.inner_proposed:
                text += (
                    f", {state.inner_proposed} surrogate steps "
                    f"(acceptance {state.inner_accepted / state.inner_proposed:.2f}), "
                    f"{state.first_stage_rejections} moves turned down without a run"
                )

            if self.lines:
                self._line(text)
            else:
                self.progress.console.print(text)


# ---------------------------------------------------------------------- Ctrl-C


class StopRequest:
    """SIGINT handler for the run: the first Ctrl-C asks to stop at the next safe point (the
    next simulator call or returned batch, see :meth:`check`); a second one raises at once."""

    def __init__(self, console: Console | None):
        self.console = console
        self.requested = False
        self._previous: Any = None

    def _handler(self, signum, frame) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        if self.console is not None:
            self.console.print("stopping at the next safe point (Ctrl-C again to abort now)")

    def check(self) -> None:
        if self.requested:
            raise KeyboardInterrupt

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def __exit__(self, *exc) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None


class CheckedLikelihood(WrappedLikelihood):
    """A batch likelihood that refuses to start an evaluation (a batch, or one dataset's runs)
    while a stop is requested; its other members are the likelihood's."""

    def __init__(self, stop: StopRequest, likelihood: Callable[[Any], Any]):
        super().__init__(likelihood)
        self.stop = stop

    def around(self, evaluate: Callable[[], Any]) -> Any:
        self.stop.check()
        return evaluate()


def is_interrupt(exc: BaseException | None) -> bool:
    """KeyboardInterrupt, possibly wrapped (numba turns one raised while it unpickles a result
    into a SystemError whose cause is the KeyboardInterrupt)."""
    seen = 0
    while exc is not None and seen < 10:
        if isinstance(exc, KeyboardInterrupt):
            return True
        exc = exc.__cause__ or exc.__context__
        seen += 1
    return False
