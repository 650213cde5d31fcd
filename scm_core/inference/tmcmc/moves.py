"""TMCMC's move schemes as small strategy objects (as emcee's moves): how a stage's resampled
points become Metropolis chains (:func:`scm_core.inference.tmcmc.stage.plan_stage`) and which
states of a chain are the next stage's samples (:func:`~scm_core.inference.tmcmc.stage.run_chains`).
``TMCMCSettings.moves`` names one; :func:`move_of` gives it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:  # the settings name a move scheme: they import this module
    from scm_core.inference.tmcmc.types import TMCMCSettings

__all__ = [
    "MOVES",
    "LeaderMove",
    "Move",
    "ResampleMove",
    "WasteFreeMove",
    "form_defaults",
    "move_of",
    "stage_chains",
    "steps_for_acceptance",
]


class Move(Protocol):
    """A move scheme. ``keeps_every_step``: every visited state of a chain is a sample (else
    only its final state); ``keeps_start``: so is the chain's starting point."""

    name: str
    keeps_every_step: bool
    keeps_start: bool

    def resample_size(self, n: int, settings: TMCMCSettings) -> int:
        """How many points the stage resamples from its n weighted samples."""
        ...

    def chain_sizes(
        self, n: int, n_chains: int, settings: TMCMCSettings
    ) -> NDArray[np.int64] | None:
        """Sizes of the consecutive blocks of a stage's n samples that one chain made, where
        they are correlated enough to count as one unit (None: independent samples)."""
        ...

    def chains(
        self, parent: NDArray[np.int64], n: int, acceptance_rate: float, settings: TMCMCSettings
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """(start index into the previous population, Metropolis steps) of each chain, from
        the resampled indices ``parent`` (:meth:`resample_size`,), the population size n and
        the last stage's acceptance rate."""
        ...

    def max_runs_per_sample(self, settings: TMCMCSettings) -> int:
        """The most model runs a stage makes per sample (a worst case for budgets)."""
        ...


def steps_for_acceptance(
    acceptance_rate: float, move_probability: float, min_steps: int, max_steps: int
) -> int:
    """Metropolis steps so that a chain moves at least once with ``move_probability``.

    n = ceil(log(1 - move_probability) / log(1 - acceptance_rate)), clipped to
    [min_steps, max_steps]; acceptance 0 gives max_steps, 1 gives min_steps.
    """
    acc = float(acceptance_rate)
    if not math.isfinite(acc):
        raise ValueError("acceptance_rate must be finite")
    if acc <= 0.0:
        return int(max_steps)
    if acc >= 1.0:
        return int(min_steps)
    n = math.ceil(math.log(1.0 - move_probability) / math.log(1.0 - acc))
    return int(min(max(n, min_steps), max_steps))


class ResampleMove:
    """Resample-move (the unaccelerated accurate form): every resampled point starts a chain of
    ``n_steps`` steps (fixed, or adapted with :func:`steps_for_acceptance`) whose final state is
    the new sample."""

    name = "resample-move"
    keeps_every_step = False
    keeps_start = False

    def resample_size(self, n: int, settings: TMCMCSettings) -> int:
        return n

    def chain_sizes(self, n: int, n_chains: int, settings: TMCMCSettings) -> None:
        return None

    def max_runs_per_sample(self, settings: TMCMCSettings) -> int:
        return int(settings.n_steps or settings.max_steps)

    def chains(
        self, parent: NDArray[np.int64], n: int, acceptance_rate: float, settings: TMCMCSettings
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        # a surrogate transition makes ``surrogate_steps`` Metropolis steps per move
        k = int(settings.surrogate_steps) if settings.delayed_acceptance else 1
        if settings.n_steps is not None:
            n_steps = int(settings.n_steps)
        elif not math.isfinite(acceptance_rate):
            n_steps = math.ceil(settings.initial_steps / k)
        else:
            n_steps = steps_for_acceptance(
                acceptance_rate,
                settings.move_probability,
                math.ceil(settings.min_steps / k),
                settings.max_steps,
            )
        return parent, np.full(parent.shape[0], n_steps)


class LeaderMove:
    """The paper's form (Ching & Chen 2007): each distinct resampled point leads one chain as
    long as its multiplicity, every visited state a sample: at most one model run per sample
    and stage, but biased on targets with exact answers."""

    name = "leader"
    keeps_every_step = True
    keeps_start = False

    def resample_size(self, n: int, settings: TMCMCSettings) -> int:
        return n

    def chain_sizes(self, n: int, n_chains: int, settings: TMCMCSettings) -> None:
        return None

    def max_runs_per_sample(self, settings: TMCMCSettings) -> int:
        return 1

    def chains(
        self, parent: NDArray[np.int64], n: int, acceptance_rate: float, settings: TMCMCSettings
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        return np.unique(parent, return_counts=True)


#: moves per chain of the waste-free form when ``n_steps`` is not set (P = 5 states per chain:
#: on paper case 1 nearer the unaccelerated posterior than P = 10 at fewer model runs,
#: docs/sampler.md)
WASTE_FREE_STEPS = 4


class WasteFreeMove:
    """Waste-free SMC (Dau & Chopin 2022, JRSS B 84(1)): the stage resamples M = ceil(n / P)
    points, each starts a chain of P - 1 moves (P - 1 = ``n_steps``, default
    :data:`WASTE_FREE_STEPS`), and all P states of every chain, its start included, are the
    next stage's n samples. Consistent as M grows for any fixed P (the chains start from the
    tempered target and leave it invariant); costs n - M model runs per stage (under one per
    sample, the leader form's budget) where resample-move spends its n_steps runs on every
    sample and keeps only the last."""

    name = "waste-free"
    keeps_every_step = True
    keeps_start = True

    @staticmethod
    def states_per_chain(settings: TMCMCSettings) -> int:
        return (WASTE_FREE_STEPS if settings.n_steps is None else int(settings.n_steps)) + 1

    def resample_size(self, n: int, settings: TMCMCSettings) -> int:
        return -(-n // self.states_per_chain(settings))

    def max_runs_per_sample(self, settings: TMCMCSettings) -> int:
        return 1  # n - M runs per stage

    def chain_sizes(
        self, n: int, n_chains: int, settings: TMCMCSettings
    ) -> NDArray[np.int64] | None:
        per = self.states_per_chain(settings)
        m = -(-n // per)
        if n_chains != m:
            return None
        sizes = np.full(m, per, dtype=np.int64)
        sizes[-1] = n - per * (m - 1)
        return sizes

    def chains(
        self, parent: NDArray[np.int64], n: int, acceptance_rate: float, settings: TMCMCSettings
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        # the population size is M P unless P does not divide it: the last chain is shorter
        states = np.full(parent.shape[0], self.states_per_chain(settings))
        states[-1] = n - int(states[:-1].sum())
        return parent, states - 1


_MOVES: dict[str, Move] = {m.name: m for m in (ResampleMove(), LeaderMove(), WasteFreeMove())}
#: the move schemes' names, from the registry: the settings', a case's, the API's and the CLI's
#: choices
MOVES: tuple[str, ...] = tuple(_MOVES)


#: the accelerated accurate form (issue 12, docs/sampler.md): waste-free chains whose moves
#: are surrogate transitions of ACCELERATED_STEPS inner steps, a share ACCELERATED_JUMPS of them
#: population jumps, the log walk and multinomial resampling (a right evidence standard
#: error); each part exact
ACCELERATED_STEPS = 40
ACCELERATED_JUMPS = 0.2
_ACCELERATED = {
    "n_steps": WASTE_FREE_STEPS,
    "delayed_acceptance": True,
    "surrogate_steps": ACCELERATED_STEPS,
    "surrogate_jumps": ACCELERATED_JUMPS,
    "proposal_scale": "log",
    "resampling": "multinomial",
}
#: plain Metropolis steps in the parameters, systematic resampling: the paper's form (leader)
#: and the unaccelerated accurate form (resample-move)
_PLAIN = {
    "delayed_acceptance": False,
    "surrogate_steps": 1,
    "surrogate_jumps": 0.0,
    "proposal_scale": "linear",
    "resampling": "systematic",
}
#: the move scheme of a study that names none: the accelerated accurate form (on paper case 1
#: within issue 12's accuracy lines of the unaccelerated form at 1.2 times the leader form's
#: model runs, docs/sampler.md)
STUDY_MOVES = "waste-free"


def form_defaults(moves: str) -> dict[str, bool | int | float | str]:
    """The settings a study leaves to its move scheme: for "waste-free" the accelerated
    accurate form (waste-free chains are only accurate with surrogate transitions as their
    moves; :data:`WASTE_FREE_STEPS` moves per chain), for "resample-move" and "leader" plain
    steps (their ``n_steps`` adapts: not set here). Keys: ``n_steps`` (waste-free only),
    ``delayed_acceptance``, ``surrogate_steps``, ``surrogate_jumps``, ``proposal_scale``,
    ``resampling``."""
    move_of(moves)  # a known scheme
    return dict(_ACCELERATED if moves == "waste-free" else _PLAIN)


def stage_chains(n: int, settings: TMCMCSettings) -> int:
    """The most Metropolis chains a stage of n samples runs (what to cut into work batches):
    n for resample-move and leader, ceil(n / P) for waste-free."""
    return move_of(settings.moves).resample_size(n, settings)


def move_of(name: str) -> Move:
    """The move scheme called ``name`` (one of :data:`MOVES`)."""
    try:
        return _MOVES[name]
    except KeyError:
        raise ValueError(f"'moves' must be one of {MOVES}, got {name!r}") from None
