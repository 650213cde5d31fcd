"""GET /comparison: completed calibrations of the same data grouped into model classes (runs of
one calibration each), ranked by their runs' mean log evidence, the best one's Bayes factors
with their uncertainty and verdict (issue 71, part 3); bad requests refused naming study_ids."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats
from test_api_support import (
    AUTH,
    detail,
    run_inline,
    summary_doc,
    tiny_case,
)


def _group(client, url, ds: int, name: str, case: dict, runs: int) -> list[int]:
    body = {"case": case, "dataset_ids": [ds], "runs": runs, "name": name}
    r = client.post("/studies", json=body, headers=AUTH)
    assert r.status_code == 201, r.text
    ids = r.json()["runs"] if runs > 1 else [r.json()["id"]]
    for sid in ids:
        assert run_inline(url, sid) == "completed"
    return ids


def test_model_classes_ranked_with_bayes_factors(env) -> None:
    """Two runs of the case, two of the case with phi's prior moved away from the data, one
    of a third: three classes. Each class's log evidence is the mean of its studies', its
    standard error their sd over sqrt(2) (the single run's: its own); the verdict of two
    classes of two runs is Welch's test (scipy) at 5 %."""
    client, url = env
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    wide = _group(client, url, ds, "wide", tiny_case(seed=5), 2)
    away = tiny_case(seed=8)
    away["parameters"]["phi"] = {"dist": "uniform", "lower": 20.0, "upper": 22.0, "unit": "deg"}
    narrow = _group(client, url, ds, "narrow", away, 2)
    one = _group(client, url, ds, "single", tiny_case(seed=11, params=("phi",)), 1)
    ids = [*wide, *narrow, *one]
    r = client.get("/comparison", params={"study_ids": ",".join(map(str, ids))})
    assert r.status_code == 200, r.text
    doc = r.json()
    z = {s: client.get(f"/studies/{s}").json()["log_evidence"] for s in ids}
    classes = {tuple(c["study_ids"]): c for c in doc["classes"]}
    assert set(classes) == {tuple(wide), tuple(narrow), tuple(one)}
    for members, c in classes.items():
        runs = [z[s] for s in members]
        assert c["runs"] == len(members) and c["run_log_evidence"] == runs
        assert c["log_evidence"] == pytest.approx(np.mean(runs), rel=1e-12)
        if len(members) > 1:
            assert c["se"] == pytest.approx(np.std(runs, ddof=1) / math.sqrt(2), rel=1e-9)
    assert [c["log_evidence"] for c in doc["classes"]] == sorted(
        (c["log_evidence"] for c in doc["classes"]), reverse=True
    )
    best = doc["classes"][0]["name"]
    assert all(bf["better"] == best for bf in doc["bayes_factors"])
    assert len(doc["bayes_factors"]) == 2
    page = client.get("/ui/f/compare", params={"ids": ",".join(map(str, ids))})
    assert page.status_code == 200, page.text
    assert "Model classes" in page.text
    for bf in doc["bayes_factors"]:  # the page says what the API says
        assert bf["verdict"].split(":")[0] in page.text.replace("&#39;", "'")
    top = doc["classes"][0]["study_ids"]
    for bf, c in zip(doc["bayes_factors"], doc["classes"][1:], strict=True):
        assert bf["worse"] == c["name"]
        if len(top) == 2 and c["runs"] == 2:
            welch = stats.ttest_ind([z[s] for s in top], c["run_log_evidence"], equal_var=False)
            assert bf["decided"] == (welch.pvalue < 0.05)
    assert all(bf["verdict"].startswith(f"{best} over ") for bf in doc["bayes_factors"])


def test_bad_comparisons_are_refused_naming_study_ids(env) -> None:
    """Runs of one calibration only, calibrations of different data, a study twice, an unknown
    or unfinished study: 422 naming study_ids, in words."""
    client, url = env
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    ds2 = client.post("/datasets", json=summary_doc(shift=3.0), headers=AUTH).json()["id"]
    runs = _group(client, url, ds, "wide", tiny_case(seed=5), 2)
    other = _group(client, url, ds2, "other data", tiny_case(seed=5), 1)
    queued = client.post(
        "/studies", json={"case": tiny_case(seed=9), "dataset_ids": [ds]}, headers=AUTH
    ).json()["id"]
    for ids, needle in (
        (runs, "runs of one calibration"),
        ([runs[0], other[0]], "different data"),
        ([runs[0], runs[0]], "listed twice"),
        ([runs[0], 99999], "no study with id 99999"),
        ([runs[0], queued], "not a completed calibration"),
    ):
        r = client.get("/comparison", params={"study_ids": ",".join(map(str, ids))})
        assert r.status_code == 422, (ids, r.text)
        assert "study_ids" in detail(r) and needle in detail(r), detail(r)
