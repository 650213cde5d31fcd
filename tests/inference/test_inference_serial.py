"""Strict-JSON round trips of every stored TMCMC dataclass, also under numpy 2.5's ``NDArray``.

numpy 2.5 (Python >= 3.12) declares ``type NDArray[ScalarT: np.generic] = np.ndarray[...]``, a
PEP 695 alias whose ``typing.get_origin`` is the alias, not ``np.ndarray``; serialisation that
read array fields from the type hints then left raw arrays in ``to_dict()`` and every study died
at its first checkpoint. These tests build that alias on Python 3.11 with
``typing_extensions.TypeAliasType`` and swap it into the modules that declare the dataclasses.
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any, TypeVar

import numpy as np
import pytest
from typing_extensions import TypeAliasType

import scm_core.inference._serial as serial
import scm_core.inference.tmcmc.driver as tmcmc_module
import scm_core.inference.tmcmc.types as types_module
from scm_core.inference import (
    ChainBatchResult,
    JointPrior,
    StagePlan,
    StageState,
    TMCMCResult,
    TMCMCSettings,
    Uniform,
    evaluate_points,
    initial_samples,
    initial_state,
    plan_stage,
    reduce_stage,
    run_chains,
    run_tmcmc,
)
from scm_core.inference.tmcmc.moves import form_defaults
from scm_core.inference.tmcmc.types import PointEvaluation

_ScalarT = TypeVar("_ScalarT", bound=np.generic)
#: numpy 2.5's spelling of NDArray, built on Python 3.11
NDARRAY_25 = TypeAliasType(
    "NDArray", np.ndarray[tuple[Any, ...], np.dtype[_ScalarT]], type_params=(_ScalarT,)
)


@pytest.fixture
def numpy25_ndarray(monkeypatch: pytest.MonkeyPatch):
    """The dataclass modules see numpy 2.5's NDArray; field kinds are looked up afresh."""
    for module in (types_module, tmcmc_module, serial):
        monkeypatch.setattr(module, "NDArray", NDARRAY_25)
    serial._kinds.cache_clear()
    yield
    serial._kinds.cache_clear()


def _gaussian_batch(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """log L of a 2-D Gaussian around (0.3, -0.2), sd 0.2, with the point as its 'responses';
    points left of x0 = -0.9 fail (-inf), so failures travel through the documents too."""
    X = np.atleast_2d(X)
    logl = -0.5 * np.sum(((X - np.array([0.3, -0.2])) / 0.2) ** 2, axis=1)
    logl = np.where(X[:, 0] < -0.9, -np.inf, logl)
    return logl, X.copy()


def _objects() -> list[Any]:
    """One of each stored TMCMC dataclass, from a real stage of the accelerated form (delayed
    acceptance, population jumps: every optional array is filled) and of a plain one."""
    prior = JointPrior({"a": Uniform(-1.0, 1.0), "b": Uniform(-1.0, 1.0)})
    settings = TMCMCSettings(**{**form_defaults("waste-free"), "n_steps": 3}, moves="waste-free")
    X = initial_samples(prior, 60, seed=5)
    ev = evaluate_points(X, _gaussian_batch)
    state0 = initial_state(prior, X, [ev], seed=5, settings=settings)
    plan = plan_stage(state0, prior, settings)
    batch = run_chains(plan, range(plan.n_chains), _gaussian_batch)
    state1 = reduce_stage(plan, [batch])
    plain = run_tmcmc(_gaussian_batch, prior, n_samples=40, seed=1, settings=TMCMCSettings())
    return [settings, ev, state0, plan, batch, state1, plain]


def _strict_round_trip(obj: Any) -> Any:
    text = json.dumps(obj.to_dict(), allow_nan=False)  # no encoder: plain JSON values only
    return type(obj).from_dict(json.loads(text))


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, TMCMCResult):
        return a.to_dict() == b.to_dict() and all(
            x.equals(y) for x, y in zip(a.stages, b.stages, strict=True)
        )
    return a.equals(b)


def _check_round_trips() -> None:
    objs = _objects()
    kinds = {type(o) for o in objs}
    assert kinds == {
        TMCMCSettings,
        PointEvaluation,
        StageState,
        StagePlan,
        ChainBatchResult,
        TMCMCResult,
    }
    for obj in objs:
        back = _strict_round_trip(obj)
        assert _same(obj, back), type(obj).__name__
        assert json.dumps(back.to_dict(), allow_nan=False) == json.dumps(
            obj.to_dict(), allow_nan=False
        )
    # the accelerated stage really carries every optional array, and -inf / NaN travel
    state1, plan = objs[5], objs[3]
    assert state1.train_samples is not None and state1.eve is not None
    assert plan.jump_chol is not None and plan.train_responses is not None
    assert isinstance(_strict_round_trip(state1).train_samples, np.ndarray)
    assert _strict_round_trip(state1).eve.dtype == np.int64
    assert math.isnan(_strict_round_trip(objs[2]).acceptance_rate)
    assert np.isneginf(objs[1].log_likelihood).any()


def test_every_stored_dataclass_round_trips_through_strict_json() -> None:
    _check_round_trips()


def test_round_trips_with_numpy_25_type_alias(numpy25_ndarray: None) -> None:
    """The numpy-2.5 form of NDArray in the annotations changes nothing."""
    assert types_module.NDArray is NDARRAY_25
    _check_round_trips()


def test_an_unknown_field_value_is_refused_not_written() -> None:
    """A value that is not JSON (a set, say) raises naming the field instead of leaving a
    document json.dumps cannot write."""
    state = _objects()[2]
    bad = dataclasses.replace(state, responses={1, 2})  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"StageState\.responses"):
        bad.to_dict()


def test_floats_written_as_ints_come_back_as_floats() -> None:
    """A float field stored as an integer-valued JSON number (PostgreSQL's jsonb writes 1e20
    without a point) is read back as a float; int fields stay ints."""
    d = TMCMCSettings().to_dict()
    d["target_cov"] = 1
    d["max_stages"] = 7
    back = TMCMCSettings.from_dict(d)
    assert isinstance(back.target_cov, float) and back.target_cov == 1.0
    assert isinstance(back.max_stages, int) and back.max_stages == 7
