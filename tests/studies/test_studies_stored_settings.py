"""A stored study holds every sampler setting its samples depend on (issue 43): a later change
of a default in code (a release that retunes the sampler) changes neither a stored study's
settings nor its results, and needs no migration; a study created after the change gets the
new defaults. A case stored before the tuning was stored reads with the values it ran with."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from test_api_support import AUTH, api_client, fresh_database, run_inline, summary_doc, tiny_case

from scm_core.calibration import CaseDefinition, SamplerSettings
from scm_core.calibration import case as case_module
from scm_core.inference.tmcmc import moves as tmcmc_moves
from services.store import Store
from services.studies.kinds import base

#: what the "new release" changes: two of TMCMCSettings' tuning defaults and one default a
#: move scheme fills in (each changes the samples of this study)
NEW_TUNING = {"initial_steps": 5, "min_steps": 2}
NEW_FORM = {"resampling": "multinomial"}


def _retune(tuning: dict, form: dict) -> None:
    for name, value in tuning.items():
        SamplerSettings.model_fields[name].default = value
    tmcmc_moves._PLAIN.update(form)
    SamplerSettings.model_rebuild(force=True)
    CaseDefinition.model_rebuild(force=True)
    base._stored_case.cache_clear()  # what each process parsed before the change
    base._case_terms.cache_clear()


@pytest.fixture
def new_release(monkeypatch) -> Iterator[None]:
    """Changes the defaults in code, as an edit of case.py / tmcmc/moves.py would."""
    old_tuning = {n: SamplerSettings.model_fields[n].default for n in NEW_TUNING}
    old_form = {k: tmcmc_moves._PLAIN[k] for k in NEW_FORM}
    _retune(NEW_TUNING, NEW_FORM)
    yield
    _retune(old_tuning, old_form)


@pytest.fixture
def env(tmp_path):
    with fresh_database("sqlite", tmp_path) as url, api_client(url) as client:
        yield client, url


def _final(url: str, sid: int) -> np.ndarray:
    store = Store.open(url)
    try:
        study = store.studies.get(sid)
        return store.samples.arrays(sid, int(study.current_stage)).samples
    finally:
        store.close()


def test_a_changed_default_leaves_stored_studies_as_they_were(env, request) -> None:
    client, url = env
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    doc = tiny_case(seed=3, moves="resample-move")

    def submit() -> int:
        r = client.post("/studies", json={"case": doc, "dataset_ids": [ds]}, headers=AUTH)
        assert r.status_code == 201, r.text
        return r.json()["id"]

    before, stored = submit(), submit()
    sampler = client.get(f"/studies/{stored}").json()["case"]["sampler"]
    # every setting is in the stored case, resolved
    assert {"initial_steps", "min_steps", "beta0", "resampling"} <= set(sampler)
    assert run_inline(url, before) == "completed"

    request.getfixturevalue("new_release")
    # the change is real: a case made now takes the new defaults
    fresh = CaseDefinition.from_dict(doc).tmcmc_settings()
    assert (fresh.initial_steps, fresh.min_steps, fresh.resampling) == (5, 2, "multinomial")
    after = submit()
    assert client.get(f"/studies/{stored}").json()["case"]["sampler"] == sampler
    assert run_inline(url, stored) == "completed"
    assert run_inline(url, after) == "completed"
    # the study stored before the change runs as it would have: bit for bit the same samples
    assert np.array_equal(_final(url, stored), _final(url, before))
    # and the one created after it is another study
    new = _final(url, after)
    assert new.shape != _final(url, before).shape or not np.array_equal(new, _final(url, before))


def test_a_case_stored_before_the_tuning_was_reads_with_what_it_ran_with(new_release) -> None:
    """A stored case document without the tuning keys (stored before they were) reads with
    TUNING_BEFORE, the values its samples came from, not with today's (changed) defaults; its
    fingerprint is the one it was stored with."""
    doc = CaseDefinition.from_dict(tiny_case(seed=3, moves="resample-move")).to_dict()
    assert doc["sampler"]["initial_steps"] == 5  # made after the change
    old = {
        **doc,
        "sampler": {k: v for k, v in doc["sampler"].items() if k not in case_module.TUNING},
    }
    settings = CaseDefinition.from_stored(old).tmcmc_settings()
    for name, value in case_module.TUNING_BEFORE.items():
        assert getattr(settings, name) == value, name
    # the fingerprint of an old document is unchanged by the keys it now holds
    again = CaseDefinition.from_stored(old)
    assert again.fingerprint() == CaseDefinition.from_stored(again.to_dict()).fingerprint()


def test_a_waste_free_case_stores_its_moves_per_chain(monkeypatch) -> None:
    """Waste-free's moves per chain are filled in and stored like the rest (they were computed
    at run time from WASTE_FREE_STEPS): a release that changes the default changes no stored
    case, and a case stored before they were stored reads with the value it ran with."""
    doc = CaseDefinition.from_dict(tiny_case(seed=3, moves="waste-free")).to_dict()
    assert doc["sampler"]["n_steps"] == tmcmc_moves.WASTE_FREE_STEPS == 4
    old = {**doc, "sampler": {k: v for k, v in doc["sampler"].items() if k != "n_steps"}}
    assert (
        CaseDefinition.from_stored(old).fingerprint()
        == CaseDefinition.from_stored(doc).fingerprint()
    )
    monkeypatch.setitem(tmcmc_moves._ACCELERATED, "n_steps", 9)  # a new release's default
    assert CaseDefinition.from_dict(tiny_case(seed=3, moves="waste-free")).sampler.n_steps == 9
    assert CaseDefinition.from_stored(doc).tmcmc_settings().n_steps == 4
    assert CaseDefinition.from_stored(old).tmcmc_settings().n_steps == 4
    # a case that names its moves per chain keeps them; resample-move's still adapt
    named = CaseDefinition.from_dict(tiny_case(seed=3, moves="waste-free", n_steps=2))
    assert named.sampler.n_steps == 2
    adapted = CaseDefinition.from_dict(tiny_case(seed=3, moves="resample-move"))
    assert adapted.sampler.n_steps is None


def test_fingerprints_are_those_of_before_the_tuning_was_stored() -> None:
    """A results folder's checkpoints name their case by its fingerprint (resume checks it): the
    committed quick case's, as the code before this change computed it (literal), so that an
    interrupted run of it resumes across the change."""
    from pathlib import Path

    from scm_core.calibration import load_case

    quick = Path(__file__).resolve().parents[2] / "examples" / "quick.toml"
    assert load_case(quick).fingerprint() == (
        "ec247cd3d2e7f4f660afb0eb153fada3aa7a7c9a2a3d467a4a3fc48c724a43c4"
    )


def test_the_record_of_the_past_tuning_is_todays_defaults_until_one_changes() -> None:
    """TUNING_BEFORE names every tuning field with the value TMCMCSettings had when the tuning
    began to be stored; today that is still its default (a change of a default leaves this
    record as it is, and this test is then updated to name what changed)."""
    from scm_core.inference import TMCMCSettings

    assert set(case_module.TUNING_BEFORE) == set(case_module.TUNING)
    defaults = TMCMCSettings()
    assert {n: getattr(defaults, n) for n in case_module.TUNING} == case_module.TUNING_BEFORE


@pytest.mark.parametrize(
    ("change", "words"),
    [
        ({"min_steps": 100}, ("sampler:", "'min_steps' (100)", "max_steps")),
        ({"beta0": "x"}, ("sampler.beta0:", "valid number")),
        ({"surrogate_memory": 1.5}, ("sampler.surrogate_memory:",)),
        ({"beta00": 0.2}, ("sampler.beta00: unknown field",)),
    ],
)
def test_bad_tuning_is_one_line_naming_the_field(change: dict, words: tuple) -> None:
    """The tuning a case may now give is checked as TMCMCSettings checks it, in one line that
    names the field (not the whole table)."""
    from scm_core.calibration import CaseError

    doc = tiny_case(seed=3, moves="resample-move")
    doc["sampler"].update(change)
    with pytest.raises(CaseError) as err:
        CaseDefinition.from_dict(doc)
    message = str(err.value)
    assert "\n" not in message and "n_samples" not in message, message
    for w in words:
        assert w in message, message


def test_a_study_with_bad_tuning_is_refused_and_stores_nothing(env) -> None:
    client, _ = env
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    doc = tiny_case(seed=3, moves="resample-move")
    doc["sampler"]["initial_steps"] = 0
    r = client.post("/studies", json={"case": doc, "dataset_ids": [ds]}, headers=AUTH)
    assert r.status_code == 422 and "initial_steps" in r.json()["detail"], r.text
    assert client.get("/studies").json()["total"] == 0
