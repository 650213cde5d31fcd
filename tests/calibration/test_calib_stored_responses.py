"""The rule for responses stored before the lateral force was declared (issue 70): an array
with k < N_RESPONSES values per dataset holds the first k responses (F, T, z), and reads with
the later ones NaN, "not simulated" (``scm_core.signals.responses.widened``). The store-level
checks (SQLite and PostgreSQL) are tests/store/test_store_legacy_responses.py."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from scm_core.calibration import CaseDefinition, DatasetTerms, StudyModel, UpdateLikelihood
from scm_core.calibration.stored import with_all_responses
from scm_core.inference.tmcmc.stage import PointEvaluation
from scm_core.signals.responses import N_FIRST, N_RESPONSES, RESPONSE_KEYS, widened


def test_three_per_dataset_read_as_four_with_fy_nan() -> None:
    old = np.arange(12.0).reshape(2, 6)  # 2 samples, 2 datasets of F, T, z
    wide = widened(old, 2)
    assert wide.shape == (2, 2 * N_RESPONSES)
    for k in range(2):
        group = wide[:, k * N_RESPONSES : (k + 1) * N_RESPONSES]
        np.testing.assert_array_equal(group[:, :N_FIRST], old[:, 3 * k : 3 * k + 3])
        assert np.isnan(group[:, N_FIRST:]).all()
    assert RESPONSE_KEYS[N_FIRST:] == ("Fy",)
    now = np.ones((3, 2 * N_RESPONSES))
    assert widened(now, 2) is now  # as wide as today: as it is
    assert widened(np.empty((0, 0)), 3).shape == (0, 3 * N_RESPONSES)
    assert widened(np.array([1.0, 2.0, 3.0]), 1).shape == (N_RESPONSES,)
    for bad, groups in ((np.ones((2, 7)), 2), (np.ones((2, 10)), 2), (np.ones((2, 3)), 0)):
        with pytest.raises(ValueError, match="group"):
            widened(bad, groups)


def test_stored_forms_and_terms_of_three_responses() -> None:
    ev = PointEvaluation(np.zeros(2), np.arange(12.0).reshape(2, 6), 0)
    wide = with_all_responses(ev, 2)
    assert wide.responses.shape == (2, 8) and np.isnan(wide.responses[:, [3, 7]]).all()
    assert with_all_responses(wide, 2) is wide
    none = dataclasses.replace(ev, responses=None)
    assert with_all_responses(none, 2) is none
    terms = DatasetTerms("old", {"W": 100.0, "slip": 0.2}, (1.0, 2.0, 3.0))
    assert terms.means[:N_FIRST] == (1.0, 2.0, 3.0) and np.isnan(terms.means[N_FIRST:]).all()
    assert terms.measured == ("F", "T", "z") and len(terms.trial_sd) == N_RESPONSES


def test_base_parts_of_a_parent_stored_with_three_responses() -> None:
    case = CaseDefinition.from_dict(
        {
            "name": "upd",
            "parameters": {"phi": {"dist": "uniform", "lower": 20.0, "upper": 40.0}},
            "nominal": {"sigma_F": 8.0, "sigma_T": 0.8, "sigma_z": 0.002},
        }
    )
    data = [DatasetTerms(f"d{k}", {"W": 100.0, "slip": 0.2}, (1.0, 2.0, 0.01)) for k in range(3)]
    update = UpdateLikelihood(StudyModel(case, data), 2)
    parts = update.base_parts(np.arange(12.0).reshape(2, 6))
    assert sorted(parts) == [0, 1]
    np.testing.assert_array_equal(parts[1][:, :N_FIRST], [[3.0, 4.0, 5.0], [9.0, 10.0, 11.0]])
    assert np.isnan(parts[1][:, N_FIRST:]).all()
    today = np.arange(16.0).reshape(2, 8)
    assert update.base_parts(today)[1].tobytes() == today[:, 4:8].copy().tobytes()
    with pytest.raises(ValueError, match="do not hold 2 datasets"):
        update.base_parts(np.ones((2, 5)))
