"""Where the stages of a TMCMC run are kept: one small interface, two implementations.

:class:`StageStore` (:mod:`.base`) is what every reader of a run's stages uses: how many
stages are done (``count``), one done stage's :class:`~scm_core.inference.StageState` bit for
bit (``state``; ``-1`` the last) and every done stage's scalars (``rows``). Its two
implementations, in the manner of Optuna's storages:

* :class:`FolderStages` (:mod:`.folder`): a ``scm-calib calibrate`` results folder's
  ``checkpoints/stage_NNN.json`` from before folders held a database (read), and the JSON that
  ``scm-calib export DIR --to stages`` writes from a folder's database (``save``);
* :class:`DatabaseStages` (:mod:`.database`): a stored study's stage rows and sample rows,
  written by the service's exactly-once stage advance (``services.store``), with the stored
  forms of a plan and a population (:func:`planned_stage`, :func:`reduced_stage`,
  :func:`stage_state`).

The functions over the interface (:func:`stage_states`, :func:`run_population`) serve both:
resuming, an update's earlier posterior, the ArviZ export. One test suite
(``tests/stages/test_stage_stores.py``) runs on a folder, SQLite and PostgreSQL.
"""

from .base import StageStore, StageStoreError, run_population, stage_states
from .database import DatabaseStages, planned_stage, reduced_stage, stage_state
from .folder import FolderStages

__all__ = [
    "DatabaseStages",
    "FolderStages",
    "StageStore",
    "StageStoreError",
    "planned_stage",
    "reduced_stage",
    "run_population",
    "stage_state",
    "stage_states",
]
