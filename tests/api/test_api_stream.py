"""``GET /studies/{id}/stream``: a study's progress as server-sent events, through a served
instance (the embedded pool running the study) and the Python client's ``watch``."""

from __future__ import annotations

import httpx
import pytest
from test_api_support import LOG, LOG2, TOKEN, serving, tiny_case

from services.client import SCMCalibClient, SCMCalibError


def test_the_stream_follows_a_study_until_it_ends(tmp_path) -> None:
    with serving(tmp_path) as (base, _env, _tmp, _pid), SCMCalibClient(base, token=TOKEN) as api:
        ids = [api.upload_log(p)["id"] for p in (LOG, LOG2)]
        case = tiny_case(seed=13, params=("phi", "n", "J"), n_samples=40)
        case["nominal"].update(sigma_F=3.0, sigma_T=0.3, sigma_z=0.0005)  # a few stages
        sid = api.create_study(case=case, dataset_ids=ids, name="streamed")["id"]
        seen = list(api.watch(sid))
        final = api.get_study(sid)
        # the first event comes at once, not buffered (gzip) until the study ends
        assert seen[0]["status"] in ("queued", "running"), seen[0]["status"]
        versions = [s["version"] for s in seen]
        assert versions == sorted(set(versions)), versions  # each change once, in order
        stages = [s["current_stage"] or 0 for s in seen]
        assert stages == sorted(stages) and len(set(stages)) >= 2, stages  # it followed stages
        last = seen[-1]
        assert last["status"] == final["status"] == "completed"
        for key in ("version", "current_stage", "log_evidence", "model_runs"):
            assert last[key] == final[key], key
        # a finished study's stream is its one event
        assert [s["version"] for s in api.watch(sid)] == [final["version"]]
        with pytest.raises(SCMCalibError) as err:
            list(api.watch(sid + 100))
        assert err.value.status_code == 404
        r = httpx.get(f"{base}/studies/{sid}/stream", timeout=30)
        assert r.headers["content-type"].startswith("text/event-stream")
        assert r.text.startswith(f"id: {final['version']}\nevent: study\ndata: {{")
