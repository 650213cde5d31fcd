"""An update's default seed, one rule for the service's update kind and the CLI's
``--update-of``: the parent's next seed, wrapping to 0 after 2**63 - 1 (the largest a stored
seed can be), so that an update of a study seeded at the limit is still a valid study."""

from __future__ import annotations

from scm_core.seeds import SEED_MAX
from services.limits import seed_error
from services.studies.kinds.update import update_seed


def test_an_update_takes_the_next_seed_and_wraps_at_the_largest() -> None:
    assert update_seed(7) == 8
    assert update_seed(SEED_MAX - 1) == SEED_MAX
    assert update_seed(SEED_MAX) == 0
    assert all(seed_error(update_seed(s)) is None for s in (0, 7, SEED_MAX - 1, SEED_MAX))


def test_the_cli_update_of_a_study_seeded_at_the_limit_wraps_too(tmp_path) -> None:
    from scm_core.calibration import CaseDefinition
    from services.cli.calibrate import _update_inputs
    from services.cli.parent import ParentStudy

    case = CaseDefinition.from_dict(
        {
            "name": "edge",
            "parameters": {"phi": {"dist": "uniform", "lower": 20, "upper": 35}},
            "nominal": {"sigma_F": 5.0, "sigma_T": 0.5, "sigma_z": 0.001},
        }
    ).with_changes(seed=SEED_MAX)
    parent = ParentStudy(tmp_path, case, None, [], [], 0.0)  # no datasets to re-read
    updated, paths, datasets = _update_inputs(parent, [], None)
    assert updated.seed == 0 and paths == [] and datasets == []
