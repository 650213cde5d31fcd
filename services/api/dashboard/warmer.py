"""Make a watched study's charts when one of its stages finishes, before its page asks.

A study page polls its results fragment, which links the charts of the last finished stage
(their data, drawn in the browser); made on request, they would appear a computation later
than the fragment (kernel densities, contour paths, the fit's simulations at the MAP).
:class:`FigureWarmer` looks at the studies whose pages were open in the last ``forget_after``
seconds every ``interval`` seconds (one indexed read each) and, when one's finished stages or
state changed, makes that stage's page charts
(:func:`~services.api.dashboard.study_figures.page_figures`) into the dashboard's
:class:`~services.api.dashboard.study_figures.FigureCache` on its own thread; a page's request for a
chart being made waits for it instead of making it again.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Hashable
from concurrent.futures import ThreadPoolExecutor

from services.api.views import parameter_names
from services.store import Store
from services.store.errors import NotFoundError
from services.store.models import STUDY_ACTIVE

from .drawing import DRAWING_PROCESSES, FigureProcess
from .study_figures import CHART_FORMAT, FigureCache, FigureError, page_figures, study_figure

__all__ = ["FigureWarmer"]

log = logging.getLogger(__name__)


class FigureWarmer:
    """Draws the figures of watched studies' newly finished stages (see the module)."""

    def __init__(
        self, cache: FigureCache, *, interval: float = 0.2, forget_after: float = 600.0
    ) -> None:
        self.cache = cache
        self.drawer: FigureProcess | None = None  # set by start: figures drawn out of process
        self.interval = interval
        self.forget_after = forget_after
        self._seen: dict[int, float] = {}  # study id -> when a page last asked (monotonic s)
        self._drawn: dict[int, Hashable] = {}  # study id -> the state last drawn
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def watch(self, study_id: int) -> None:
        """A page of ``study_id`` is open: keep its figures drawn (cheap; call on every poll)."""
        with self._lock:
            self._seen[study_id] = time.monotonic()
        if self.drawer is not None:
            self.drawer.warm()

    def watched(self) -> list[int]:
        with self._lock:
            return sorted(self._seen)

    def start(self, store: Store, drawer: FigureProcess | None = None) -> FigureWarmer:
        """Watch on a thread of this process; figures drawn by ``drawer`` (None: here)."""
        self.drawer = drawer
        self._thread = threading.Thread(
            target=self._run, args=(store,), name="dashboard-figure-warmer", daemon=True
        )
        self._thread.start()
        return self

    def stop(self, timeout: float = 10.0) -> None:
        self._stop.set()  # a pass in progress stops between figures
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        self._stop.clear()  # passes by hand (tests) still draw

    def close(self) -> None:
        """Stop watching and stop the drawing process."""
        self.stop()
        if self.drawer is not None:
            self.drawer.close()
            self.drawer = None

    def _run(self, store: Store) -> None:
        while not self._stop.wait(self.interval):
            try:
                self.step(store)
            except Exception:  # a database hiccup: try again on the next tick
                log.exception("drawing the watched studies' figures failed")

    def step(self, store: Store) -> list[int]:
        """One look at every watched study; draws what changed. Returns the studies drawn."""
        now = time.monotonic()
        with self._lock:
            for sid in [s for s, t in self._seen.items() if now - t > self.forget_after]:
                del self._seen[sid]
                self._drawn.pop(sid, None)
            ids = sorted(self._seen)
        drawn = []
        for sid in ids:
            if self._stop.is_set():
                break
            if self._draw(store, sid):
                drawn.append(sid)
        return drawn

    def _draw(self, store: Store, study_id: int) -> bool:
        try:
            study = store.studies.get(study_id)
        except NotFoundError:
            self._forget(study_id)
            return False
        state = (study.status, study.current_stage)  # as the results fragment's ETag
        if self._drawn.get(study_id) == state:
            return False
        done = [s.stage_index for s in store.stages.list(study_id) if s.status == "done"]
        if done:
            try:
                names = parameter_names(study)
            except (KeyError, TypeError, ValueError):
                names = []

            def draw(item: tuple[int, dict]) -> bool:
                k, spec = item
                if self._stop.is_set() or (k and self._moved_on(store, study_id, state)):
                    return False  # a newer stage's figures come next: these would be stale
                # FigureError: not drawn for this kind or stage, so the page does not show it
                with contextlib.suppress(FigureError):
                    study_figure(
                        store, study, fmt=CHART_FORMAT, cache=self.cache, drawer=self.drawer, **spec
                    )
                return True

            # as many at once as the drawing processes draw (the page asks for two at a time),
            # the longest first (page_figures' order, the page's too) so they finish together
            specs = page_figures(names, done[-1])
            with ThreadPoolExecutor(DRAWING_PROCESSES, thread_name_prefix="figure") as pool:
                if not all(list(pool.map(draw, enumerate(specs)))):
                    return False
        self._drawn[study_id] = state
        if study.status not in STUDY_ACTIVE:
            self._forget(study_id)  # ended: its figures are final
        return True

    @staticmethod
    def _moved_on(store: Store, study_id: int, state: tuple) -> bool:
        study = store.studies.get(study_id)
        return (study.status, study.current_stage) != state

    def _forget(self, study_id: int) -> None:
        with self._lock:
            self._seen.pop(study_id, None)
            self._drawn.pop(study_id, None)
