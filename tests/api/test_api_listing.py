"""Pagination of datasets and studies, status filters, cancel, and the pooled posterior.

Studies are submitted through the API without a local pool; where a test needs finished
studies, their work batches are run in this process through the real orchestrator
(:func:`run_inline`).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_api_support import (
    AUTH,
    detail,
    run_inline,
    summary_doc,
    svg_text,
    tiny_case,
)


def _pages(client, path: str, limit: int, **params) -> list[dict]:
    pages, offset = [], 0
    while offset is not None:
        page = client.get(path, params={"limit": limit, "offset": offset, **params}).json()
        pages.append(page)
        offset = page["next_offset"]
    return pages


def test_dataset_pagination(env) -> None:
    client, _ = env
    ids = []
    for k in range(5):
        r = client.post("/datasets", json=summary_doc(float(k)), headers=AUTH)
        assert r.status_code == 201, r.text
        ids.append(r.json()["id"])
    pages = _pages(client, "/datasets", 2)
    assert [len(p["items"]) for p in pages] == [2, 2, 1]
    assert all(p["total"] == 5 for p in pages)
    listed = [d["id"] for p in pages for d in p["items"]]
    assert listed == sorted(ids, reverse=True)  # newest first
    one = client.get(f"/datasets/{ids[0]}").json()
    assert one["source_kind"] == "summary" and one["means"]["z"] == pytest.approx(0.019)
    assert client.get("/datasets", params={"offset": 10}).json()["items"] == []
    r = client.get(f"/datasets/{ids[0]}/series")
    assert r.status_code == 404 and "summary" in detail(r)


def test_study_pagination_filter_and_cancel(env) -> None:
    client, _ = env
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    ids = []
    for seed in range(5):
        r = client.post(
            "/studies",
            json={"case": tiny_case(), "dataset_ids": [ds], "seed": seed, "name": f"s{seed}"},
            headers=AUTH,
        )
        assert r.status_code == 201, r.text
        assert r.json()["seed"] == seed and r.json()["status"] == "running"
        ids.append(r.json()["id"])
    for sid in ids[:2]:
        r = client.post(f"/studies/{sid}/cancel", json={"reason": "test"}, headers=AUTH)
        assert r.status_code == 200 and r.json()["status"] == "cancelled"
        assert r.json()["error"] == "test"
    r = client.post(f"/studies/{ids[0]}/cancel", headers=AUTH)
    assert r.status_code == 409 and "cancelled" in detail(r)

    pages = _pages(client, "/studies", 2)
    assert [s["id"] for p in pages for s in p["items"]] == sorted(ids, reverse=True)
    assert [len(p["items"]) for p in pages] == [2, 2, 1]
    running = client.get("/studies", params={"status": "running"}).json()
    assert running["total"] == 3 and {s["id"] for s in running["items"]} == set(ids[2:])
    both = client.get("/studies", params={"status": "running,cancelled", "limit": 1}).json()
    assert both["total"] == 5 and len(both["items"]) == 1 and both["next_offset"] == 1
    assert client.get("/studies", params={"status": "completed"}).json()["total"] == 0

    study = client.get(f"/studies/{ids[3]}").json()
    assert study["name"] == "s3" and study["dataset_ids"] == [ds]
    p = study["progress"]
    assert p["stage"] == 0 and p["evaluations_planned"] == 20 and p["evaluations_done"] == 0
    assert p["eta_seconds"] is None  # no rate yet
    cancelled = client.get(f"/studies/{ids[0]}").json()["progress"]
    assert cancelled["status"] == "cancelled" and cancelled["eta_seconds"] is None
    # nothing finished yet: no summary, no samples
    r = client.get(f"/studies/{ids[3]}/summary")
    assert r.status_code == 409 and "no finished stage" in detail(r)
    page = client.get(f"/studies/{ids[3]}/stages/0/samples").json()
    assert page["total"] == 0 and page["stage_status"] == "planned"


def test_pooled_posterior(env) -> None:
    client, url = env
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]

    def submit(**body) -> int:
        r = client.post("/studies", json={"dataset_ids": [ds], **body}, headers=AUTH)
        assert r.status_code == 201, r.text
        return r.json()["id"]

    a = submit(case=tiny_case(seed=1))
    b = submit(case=tiny_case(seed=2), n_samples=30)
    other = submit(case=tiny_case(seed=3, params=("phi", "J")))
    running = submit(case=tiny_case(seed=4))
    for sid in (a, b, other):
        assert run_inline(url, sid) == "completed"

    r = client.post("/pooled", json={"study_ids": [a, b], "include_samples": True})
    assert r.status_code == 200, r.text
    pooled = r.json()
    assert pooled["n_per_study"] == 20 and pooled["n_samples"] == 40
    assert pooled["names"] == ["phi", "n"] and len(pooled["samples"]) == 40
    assert [s["n_samples"] for s in pooled["studies"]] == [20, 30]
    phi = next(p for p in pooled["parameters"] if p["name"] == "phi")
    assert phi["unit"] == "deg" and 20.0 <= phi["mean"] <= 35.0 and phi["map"] is None
    # equal weights: the pooled mean lies between the two studies' contributions (study b's
    # 30 samples are subsampled to 20)
    X = np.array(pooled["samples"])
    halves = (X[:20, 0].mean(), X[20:, 0].mean())
    assert phi["mean"] == pytest.approx(X[:, 0].mean())
    assert min(halves) <= phi["mean"] <= max(halves)

    # the agreement: each study's 20 pooled samples one chain of ArviZ's R-hat and ESS
    import arviz as az

    agree = pooled["agreement"]
    assert agree["studies"] == 2 and agree["draws_per_study"] == 20
    assert set(agree["parameters"]) == {"phi", "n"}
    for j, name in enumerate(pooled["names"]):
        chains = X[:, j].reshape(2, 20)
        got = agree["parameters"][name]
        assert got["rhat"] == pytest.approx(float(az.rhat(chains)), rel=1e-9)
        assert got["ess_bulk"] == pytest.approx(float(az.ess(chains, method="bulk")), rel=1e-9)
        assert got["study_means"] == pytest.approx(list(chains.mean(axis=1)))
    assert agree["converged"] == all(p["rhat"] <= 1.01 for p in agree["parameters"].values())
    assert agree["verdict"].startswith("converged" if agree["converged"] else "NOT converged")
    alone = client.post("/pooled", json={"study_ids": [a]}).json()
    assert alone["agreement"] is None

    same = client.get("/pooled", params={"study_ids": f"{a},{b}"}).json()
    assert same["parameters"] == pooled["parameters"]
    again = client.get("/pooled", params=[("study_ids", a), ("study_ids", b)]).json()
    assert again["parameters"] == pooled["parameters"]

    for body, words in [
        ({"study_ids": [a, other]}, ("study_ids", "same parameters")),
        ({"study_ids": [a, running]}, ("study_ids", "running")),
        ({"study_ids": [a, a]}, ("study_ids", "twice")),
        ({"study_ids": []}, ("study_ids",)),
        ({"study_ids": [a, b], "n_per_study": 25}, ("n_per_study", "20")),
    ]:
        r = client.post("/pooled", json=body)
        assert r.status_code == 422, (body, r.text)
        assert all(w in detail(r) for w in words), detail(r)

    summary = client.get(f"/studies/{a}/summary").json()
    assert summary["is_posterior"] and summary["status"] == "completed"
    assert summary["log_evidence"] is not None and summary["log_evidence_sd"] is not None
    assert summary["map"] is not None and summary["map_log_posterior"] is not None


def test_runs_make_a_group_whose_agreement_pooled_gives(env) -> None:
    """runs 3: three studies with the seeds 5, 6, 7 (names say which run), one run group; the
    answer is the first with the group's ids; once completed, /pooled on the group gives the
    agreement. An update or runs outside 1..64 are refused naming 'runs', storing nothing."""
    client, url = env
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    body = {"case": tiny_case(seed=5), "dataset_ids": [ds], "runs": 3, "name": "rep"}
    r = client.post("/studies", json=body, headers=AUTH)
    assert r.status_code == 201, r.text
    first = r.json()
    ids = first["runs"]
    assert len(ids) == 3 and ids[0] == first["id"] and first["run_group"] == first["id"]
    assert r.headers["Location"] == f"/studies/{first['id']}"
    studies = [client.get(f"/studies/{i}").json() for i in ids]
    assert [s["seed"] for s in studies] == [5, 6, 7]
    assert [s["name"] for s in studies] == [f"rep (run {k}/3)" for k in (1, 2, 3)]
    assert all(s["runs"] == ids and s["run_group"] == ids[0] for s in studies)
    listed = client.get("/studies").json()["items"]
    assert {s["id"]: s["run_group"] for s in listed} == dict.fromkeys(ids, ids[0])
    for sid in ids:
        assert run_inline(url, sid) == "completed"
    agree = client.get("/pooled", params={"study_ids": ",".join(map(str, ids))}).json()
    assert agree["agreement"]["studies"] == 3 and set(agree["agreement"]["parameters"]) == {
        "phi",
        "n",
    }

    # the group as one InferenceData: a chain per run, the verdict in its attributes
    import tempfile
    import warnings
    from pathlib import Path

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz as az

        with tempfile.TemporaryDirectory() as tmp:
            for group, chains in ((True, 3), (False, 1)):
                r = client.get(f"/studies/{ids[1]}/inference-data", params={"group": group})
                assert r.status_code == 200, r.text
                path = Path(tmp) / f"g{group}.nc"
                path.write_bytes(r.content)
                idata = az.from_netcdf(str(path))
                assert idata.posterior.sizes["chain"] == chains
            # idata is the one-chain file of study ids[1]; the group file's attrs:
            grouped = az.from_netcdf(str(Path(tmp) / "gTrue.nc"))
            for k, study in enumerate(agree["studies"]):
                got = float(grouped.posterior["phi"].values[k].mean())
                assert got == pytest.approx(study["mean"]["phi"], rel=1e-12)
            assert grouped.posterior.attrs["verdict"] == agree["agreement"]["verdict"]
            assert float(idata.posterior["phi"].values[0].mean()) == pytest.approx(
                agree["studies"][1]["mean"]["phi"], rel=1e-12
            )

    # the dashboard: each run's page names its group, the comparison of the group the verdict
    live = client.get(f"/ui/f/studies/{ids[1]}/live").text
    assert "run 2 of 3" in live and f"/ui/compare?id={ids[0]}&amp;id={ids[1]}" in live
    page = client.get("/ui/f/compare", params={"ids": ",".join(map(str, ids))}).text
    assert "Do the runs agree?" in page
    verdict = agree["agreement"]["verdict"]
    assert verdict.split(";")[0].replace(">", "&gt;").replace("<", "&lt;") in page

    alone = client.post("/studies", json={**body, "runs": 1, "seed": 9}, headers=AUTH).json()
    assert alone["runs"] == [] and alone["run_group"] is None
    # issue 69: a study not yet run is shown as such, the others compared; a calibration with
    # another sampler is compared (evidence, posteriors) but given no verdict on agreement
    page = client.get("/ui/f/compare", params={"ids": f"{ids[0]},{ids[1]},{alone['id']}"})
    assert page.status_code == 200, page.text
    status = client.get(f"/studies/{alone['id']}").json()["status"]
    assert status in ("queued", "running")
    assert f"{alone['id']}: {alone['name']}</a> is {status}" in page.text
    assert "joins the comparison when it completes" in page.text
    assert "Do the runs agree?" in page.text
    other = {**body, "runs": 1, "case": tiny_case(seed=5, n_samples=24)}
    bigger = client.post("/studies", json=other, headers=AUTH).json()["id"]
    assert run_inline(url, bigger) == "completed"
    page = client.get("/ui/f/compare", params={"ids": f"{ids[0]},{bigger}"}).text
    assert "Do the runs agree?" not in page and "NOT converged" not in page
    assert f"No verdict on agreement: studies {ids[0]} and {bigger} differ in more than" in page
    assert "sampler.n_samples 20 vs 24" in page
    ranks = client.get("/ui/figures/ranks.svg", params={"ids": f"{ids[0]},{bigger}"})
    assert ranks.status_code == 404 and "runs of one calibration" in detail(ranks)
    total = client.get("/studies").json()["total"]
    for bad in (
        {**body, "runs": 0},
        {**body, "runs": 65},
        {"update_of": ids[0], "dataset_ids": [ds], "runs": 2},
        {**body, "seed": 2**63 - 2},
    ):
        r = client.post("/studies", json=bad, headers=AUTH)
        assert r.status_code == 422 and "runs" in detail(r), (bad, r.text)
    assert client.get("/studies").json()["total"] == total


def test_figures_of_a_stopped_study_say_it_is_not_a_posterior(env) -> None:
    """max_stages 1: the run ends below exponent 1; every stage figure's title says what its
    samples are instead (issue 44 item 5); a completed study's last stage does not."""
    client, url = env
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    r = client.post(
        "/studies", json={"case": tiny_case(seed=3), "dataset_ids": [ds], "max_stages": 1},
        headers=AUTH,
    )  # fmt: skip
    stopped = r.json()["id"]
    full = client.post(
        "/studies", json={"case": tiny_case(seed=4), "dataset_ids": [ds]}, headers=AUTH
    ).json()["id"]
    run_inline(url, stopped)
    assert run_inline(url, full) == "completed"
    exponent = client.get(f"/studies/{stopped}/stages").json()[-1]["exponent"]
    assert exponent < 1.0
    for name in ("prior_posterior", "pairs", "fit"):
        svg = client.get(f"/ui/figures/studies/{stopped}/{name}.svg").text
        assert f"stage 1 (exponent {exponent:.3g}: not a posterior)" in svg_text(svg), name
        chart = client.get(f"/ui/figures/studies/{stopped}/{name}.json").json()  # the page's
        assert f"stage 1 (exponent {exponent:.3g}: not a posterior)" in chart["title"], name
        prior = client.get(f"/ui/figures/studies/{stopped}/{name}.svg", params={"stage": 0}).text
        assert "stage 0 (the prior sample: not a posterior)" in svg_text(prior), name
        done = client.get(f"/ui/figures/studies/{full}/{name}.svg").text
        assert "not a posterior" not in done, name


def _completed_study(client, url: str, seed: int) -> int:
    """A tiny calibration of one summary dataset, run to its end: its id."""
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    sid = client.post(
        "/studies", json={"case": tiny_case(seed=seed), "dataset_ids": [ds]}, headers=AUTH
    ).json()["id"]
    assert run_inline(url, sid) == "completed"
    return sid


def test_figure_urls_name_their_content_and_are_kept(env) -> None:
    """The results fragment links the schedule of the study's current version and each stage
    figure by its stage: those URLs are cached for good; another version's for a minute."""
    client, url = env
    sid = _completed_study(client, url, seed=6)
    version = client.get(f"/studies/{sid}").json()["version"]
    page = client.get(f"/ui/f/studies/{sid}/results").text
    assert f"/ui/figures/studies/{sid}/schedule.svg?v={version}" in page
    kept = "private, max-age=31536000, immutable"
    r = client.get(f"/ui/figures/studies/{sid}/schedule.svg", params={"v": version})
    assert r.status_code == 200 and r.headers["cache-control"] == kept
    old = client.get(f"/ui/figures/studies/{sid}/schedule.svg", params={"v": version - 1})
    assert old.headers["cache-control"] == "private, max-age=60"
    staged = client.get(f"/ui/figures/studies/{sid}/prior_posterior.svg", params={"stage": 1})
    assert staged.headers["cache-control"] == kept
    # the page draws the stage figures from their charts' data, kept the same way
    assert f"/ui/figures/studies/{sid}/schedule.json?v={version}" in page
    chart = client.get(f"/ui/figures/studies/{sid}/schedule.json", params={"v": version})
    assert chart.headers["cache-control"] == kept
    assert chart.headers["content-type"] == "application/json"


def test_the_page_draws_each_stage_figure_from_the_chart_the_download_draws(env) -> None:
    """Each stage figure is one chart: its JSON (what the page draws) and its SVG download
    (matplotlib) show the same title and axis labels; a figure drawn only as an image refuses
    the JSON, naming why; the JSON travels compressed."""
    client, url = env
    sid = _completed_study(client, url, seed=7)
    for name in ("schedule", "prior_posterior", "trace", "pairs", "matrix", "fit"):
        r = client.get(
            f"/ui/figures/studies/{sid}/{name}.json", headers={"Accept-Encoding": "gzip"}
        )
        assert r.status_code == 200, (name, r.text)
        chart = r.json()
        assert chart["panels"] and chart["title"], name
        svg = client.get(f"/ui/figures/studies/{sid}/{name}.svg").text
        shown = svg_text(svg)
        assert " ".join(chart["title"].split()) in shown, name
        labels = {p["x"]["label"] for p in chart["panels"] if p} - {""}
        assert all(label in shown for label in labels), (name, labels)
        if len(r.content) > 2000:
            assert r.headers.get("content-encoding") == "gzip", name
    r = client.get(f"/ui/figures/studies/{sid}/schedule.gif")
    assert r.status_code == 404 and "json" in r.json()["detail"]
    r = client.get("/ui/figures/compare.json", params={"ids": f"{sid},{sid}"})
    assert r.status_code == 404 and "format" in r.json()["detail"]  # an image only


def test_an_empty_datasets_page_says_how_to_fill_it(env) -> None:
    client, _ = env
    page = client.get("/ui/f/datasets").text
    assert "0 datasets" in page and "No dataset yet" in page
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()
    assert "No dataset yet" not in client.get("/ui/f/datasets").text
    # its page gives each condition with its unit
    page = client.get(f"/ui/f/datasets/{ds['id']}").text
    assert '<th scope="row">W [N]</th>' in page and "slip [-]" in page


def test_an_updates_posterior_has_a_summary_and_its_figures_say_what_stage_0_is(env) -> None:
    """An update's stages temper to a posterior, as a calibration's do (its kind says so): its
    summary answers (it was refused as "a update sensitivity study"), and its stage-0 figures
    call stage 0 the earlier posterior, in the update's own words."""
    client, url = env
    d1 = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    d2 = client.post("/datasets", json=summary_doc(3.0, "second"), headers=AUTH).json()["id"]
    first = client.post(
        "/studies", json={"case": tiny_case(seed=3), "dataset_ids": [d1]}, headers=AUTH
    ).json()["id"]
    assert run_inline(url, first) == "completed"
    r = client.post("/studies", json={"update_of": first, "dataset_ids": [d2]}, headers=AUTH)
    assert r.status_code == 201, r.text
    update = r.json()["id"]
    assert run_inline(url, update) == "completed"
    summary = client.get(f"/studies/{update}/summary")
    assert summary.status_code == 200, summary.text
    assert summary.json()["is_posterior"] is True
    svg = client.get(f"/ui/figures/studies/{update}/prior_posterior.svg", params={"stage": 0})
    assert "stage 0 (the earlier posterior: not yet updated)" in svg_text(svg.text)
    pooled = client.post("/pooled", json={"study_ids": [first, update]})
    assert pooled.status_code == 200, pooled.text
