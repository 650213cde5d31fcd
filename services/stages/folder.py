"""Stages kept as files, each ``{"state": StageState.to_dict(), "wall_time_s": seconds}``,
written atomically (a killed run leaves whole files only): ``DIR/checkpoints/stage_NNN.json``
of a ``scm-calib calibrate`` results folder written before folders held a database (read), and
``scm-calib export DIR --to stages`` (written on demand from the folder's database)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from scm_core import jsondoc
from scm_core.inference import StageState
from services.exports.inference_data import StageRow

from .base import StageStoreError, resolve_index

__all__ = ["FolderStages", "write_json"]


def write_json(path: Path, doc: Any, *, indent: int | None = None) -> None:
    """Write ``doc`` as strict JSON (:func:`scm_core.jsondoc.dumps`), atomically; an indented
    file ends with a newline."""
    text = jsondoc.dumps(doc, indent=indent) + ("\n" if indent is not None else "")
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


class FolderStages:
    """The :class:`~services.stages.StageStore` of the results folder ``results``."""

    def __init__(self, results: Path, directory: Path | None = None) -> None:
        """``directory``: where the stage files are (default ``results/checkpoints``)."""
        self.dir = Path(directory) if directory is not None else Path(results) / "checkpoints"

    def path(self, index: int) -> Path:
        return self.dir / f"stage_{index:03d}.json"

    def count(self) -> int:
        n = 0
        while self.path(n).is_file():
            n += 1
        return n

    def saved(self, index: int) -> tuple[StageState, float]:
        """Done stage ``index`` (negative: from the last) and the seconds it took to run (0
        if not recorded)."""
        path = self.path(resolve_index(index, self.count(), str(self.dir)))
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
            return StageState.from_dict(doc["state"]), float(doc.get("wall_time_s", 0.0))
        except (
            OSError,
            json.JSONDecodeError,
            AttributeError,
            KeyError,
            ValueError,
            TypeError,
        ) as exc:
            raise StageStoreError(f"{path}: unreadable checkpoint ({exc})") from None

    def state(self, index: int) -> StageState:
        return self.saved(index)[0]

    def rows(self) -> list[StageRow]:
        states = (self.state(i) for i in range(self.count()))
        return [StageRow.of(s.exponent, s.acceptance_rate, s.log_evidence) for s in states]

    def save(self, state: StageState, wall_time_s: float) -> None:
        """Write the next done stage (stages are saved in order: stage ``count()``)."""
        if state.stage != (n := self.count()):
            raise StageStoreError(f"{self.dir}: stage {state.stage} saved after {n} stages")
        self.dir.mkdir(parents=True, exist_ok=True)
        write_json(self.path(state.stage), {"state": state.to_dict(), "wall_time_s": wall_time_s})
