"""The figure warmer makes a watched study's page charts when a stage finishes: after one of
its passes, the page's chart links are all in the cache (nothing left to make on request)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "api"))
from test_api_support import (
    AUTH,
    LOG,
    LOG2,
    api_client,
    fresh_database,
    run_inline,
    tiny_case,
    upload_file,
)


@pytest.mark.parametrize("backend", ["sqlite"])
def test_warmer_draws_the_figures_a_study_page_links(backend, tmp_path) -> None:
    with fresh_database(backend, tmp_path) as url, api_client(url) as client:
        warmer = client.app.state.figure_warmer
        warmer.stop()  # passes by hand below, not on its thread
        store = client.app.state.store
        d1 = upload_file(client, LOG).json()["id"]
        d2 = upload_file(client, LOG2).json()["id"]
        body = {"case": tiny_case(seed=4, params=("phi", "n", "J")), "dataset_ids": [d1, d2]}
        sid = client.post("/studies", json=body, headers=AUTH).json()["id"]
        assert warmer.step(store) == []  # no page open: nothing watched, nothing drawn
        assert run_inline(url, sid) == "completed"
        page = client.get(f"/ui/f/studies/{sid}/results")  # a page polls: watched
        assert page.status_code == 200 and warmer.watched() == [sid]
        assert warmer.step(store) == [sid]
        drawn = len(warmer.cache)  # the figures and the fit's simulation at the MAP
        links = re.findall(r'data-chart="([^"]+)"', page.text)
        assert len(links) == 6, links  # schedule, prior/posterior, trace, pairs, matrix, fit
        for link in links:
            r = client.get(link.replace("&amp;", "&"))
            assert r.status_code == 200 and r.json()["panels"], link
        assert len(warmer.cache) == drawn  # every link was drawn ahead: no new draw
        assert warmer.watched() == []  # ended: its figures are final, no longer watched
        assert warmer.step(store) == []
