"""Schemathesis against a real ``scm-calib serve``: the OpenAPI document describes what the
server answers (status codes, bodies, headers, security), and no request makes it fail.

The server is a fresh embedded ``scm-calib serve`` (SQLite in a temporary directory, bound to
127.0.0.1, a throw-away database), seeded with a dataset, a completed calibration and a
completed sensitivity study so that the read endpoints have something to return. Schemathesis
(CLI, ``--checks all``) then runs twice against ``/openapi.json``: with the API token and
without one. Each run is bounded by a number of examples per operation and a wall-time budget;
both pass only with zero failures: no 5xx, no response outside its documented status codes,
schema, content type or headers, no request refused that the schema allows or accepted that it
forbids (except as configured below), 401 wherever a token is required and missing.

What fuzzing can change cannot break the test: every study it might create is held to a tiny
size by the server's limits (a few seconds of computation at most), the seeded studies have
ended (cancelling them answers 409), datasets are immutable (an upload only adds one), and the
checks of the seeded data run before the fuzzing.

``SCM_CALIB_TEST_SCHEMATHESIS_SEED`` (default 1) and ``SCM_CALIB_TEST_SCHEMATHESIS_EXAMPLES``
(default :data:`MAX_EXAMPLES`) change the seed and the examples per operation.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
from test_api_support import AUTH, LOG, TOKEN, serve_env, serving, tiny_case

#: examples per operation and phase (``--max-examples``): about 2000 requests and 30 s per
#: run on two shared cores; the module (server start, seeding, both runs) takes about 70 s
MAX_EXAMPLES = int(os.environ.get("SCM_CALIB_TEST_SCHEMATHESIS_EXAMPLES", "40"))
SEED = int(os.environ.get("SCM_CALIB_TEST_SCHEMATHESIS_SEED", "1"))
#: wall-time budget of one run, so that the module stays under 3 minutes (schemathesis' own
#: ``--max-time`` keeps fuzzing until the time is spent: the budget is the subprocess' timeout)
RUN_BUDGET_S = 75.0
REQUEST_TIMEOUT_S = 30.0

#: The server's limits: any study a fuzzed request manages to create is tiny (the seeded
#: case: 20 samples, at most 8 stages, 200 time steps per run, one dataset), so that
#: fuzzing cannot start hours of computation.
LIMITS = {
    "SCM_CALIB_MAX_SAMPLES_PER_STAGE": "20",
    "SCM_CALIB_MAX_STAGES": "8",
    "SCM_CALIB_MAX_DATASETS_PER_STUDY": "2",
    "SCM_CALIB_MAX_STEPS_PER_RUN": "200",
    "SCM_CALIB_MAX_MODEL_RUNS_PER_STUDY": "20000",
}

#: ``positive_data_acceptance`` expects a request the schema allows to be answered 2xx (or
#: 401/403/404/409/429: schemathesis' defaults). On these operations a schema-valid request is
#: refused with 422 by design, naming the field, because what makes it valid is not a matter
#: of form and no JSON Schema can say it: the check keeps running there with 422 added to the
#: expected statuses (a 400, 405, 415 or 5xx still fails it); everywhere else it runs as is.
SCHEMA_VALID_YET_422 = {
    ("POST", "/studies"): "the case document (the TOML case file as JSON) is checked by the "
    "case loader, the datasets must exist, and the simulator configuration must build at the "
    "prior medians on each dataset's test conditions, within the server's limits",
    ("POST", "/sensitivity"): "as for POST /studies: the case document, the dataset and the "
    "Morris design (even levels, bounds inside the simulator's ranges)",
    ("POST", "/datasets"): "the uploaded file (an SWT log or a summary) is parsed and checked "
    "line by line: columns, units, monotone time, plausible values",
    ("GET", "/pooled"): "the studies must exist and be completed calibrations with the same "
    "parameters",
    ("POST", "/pooled"): "as for GET /pooled",
    ("POST", "/predictions"): "the study must exist and be a completed calibration, the "
    "datasets must exist, and the conditions must make a simulator configuration within the "
    "server's limits",
}
DEFAULT_ACCEPTED = ["2xx", "3xx", "401", "403", "404", "409", "429", "5xx"]


def schemathesis_config() -> str:
    """``schemathesis.toml``: the operations of :data:`SCHEMA_VALID_YET_422`."""
    statuses = ", ".join(f'"{s}"' for s in [*DEFAULT_ACCEPTED, "422"])
    blocks = []
    for (method, path), why in SCHEMA_VALID_YET_422.items():
        blocks.append(
            f"# {method} {path}: {why}\n"
            "[[operations]]\n"
            f'include-path = "{path}"\n'
            f'include-method = "{method}"\n'
            f"checks.positive_data_acceptance.expected-statuses = [{statuses}]\n"
        )
    return "\n".join(blocks)


@pytest.fixture(scope="module")
def seeded(tmp_path_factory: pytest.TempPathFactory):
    """A ready embedded server with a dataset, a completed calibration and a completed
    sensitivity study; yields (base URL, tmp directory)."""
    tmp = tmp_path_factory.mktemp("schemathesis")
    with serving(tmp, serve_env(tmp, **LIMITS)) as (base, _, _, _):
        with httpx.Client(base_url=base, headers=AUTH, timeout=30) as client:
            meta = LOG.with_suffix(".json").read_text()
            files = {"file": (LOG.name, LOG.read_bytes(), "text/csv")}
            r = client.post("/datasets", files=files, data={"metadata": meta})
            assert r.status_code == 201, r.text
            dataset = r.json()["id"]
            r = client.post("/studies", json={"case": tiny_case(), "dataset_ids": [dataset]})
            assert r.status_code == 201, r.text
            study = r.json()["id"]
            morris = {"case": tiny_case(), "dataset_id": dataset, "r": 2, "levels": 4}
            r = client.post("/sensitivity", json=morris)
            assert r.status_code == 201, r.text
            screening = r.json()["id"]
            deadline = time.monotonic() + 240
            for sid in (study, screening):
                while (status := client.get(f"/studies/{sid}").json()["status"]) in (
                    "queued",
                    "running",
                ):
                    assert time.monotonic() < deadline, f"study {sid} still {status}"
                    time.sleep(0.3)
                assert status == "completed", (sid, status)
            assert client.get(f"/studies/{study}/summary").status_code == 200
            # an offset past any sample is an empty page (it overflowed the database's integer)
            r = client.get(f"/studies/{study}/stages/0/samples", params={"offset": 2**63 - 1})
            assert r.status_code == 200 and r.json()["samples"] == [], r.text
            assert client.get(f"/sensitivity/{screening}").json()["result"] is not None
        yield base, tmp


def _schemathesis(base: str, tmp: Path, token: str | None) -> tuple[int, str, float]:
    config = tmp / "schemathesis.toml"
    config.write_text(schemathesis_config())
    args = [
        "--config-file", str(config),
        "run", f"{base}/openapi.json",
        "--url", base,  # the schema's own servers are never used: only 127.0.0.1
        "--checks", "all",
        "--max-examples", str(MAX_EXAMPLES),
        "--seed", str(SEED),
        "--request-timeout", str(REQUEST_TIMEOUT_S),
        "--generation-database", "none",
        "--no-color",
    ]  # fmt: skip
    if token is not None:
        args += ["--header", f"Authorization: Bearer {token}"]
    env = {k: v for k, v in os.environ.items() if not k.startswith("SCHEMATHESIS_")}
    env["NO_COLOR"] = "1"
    command = [sys.executable, "-c", "from schemathesis.cli import schemathesis; schemathesis()"]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            [*command, *args],
            cwd=tmp,
            env=env,
            capture_output=True,
            text=True,
            timeout=RUN_BUDGET_S,
        )
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout or ""
        out = out.decode(errors="replace") if isinstance(out, bytes) else out
        pytest.fail(f"schemathesis over its budget of {RUN_BUDGET_S:.0f} s:\n{out[-4000:]}")
    return proc.returncode, proc.stdout + proc.stderr, time.perf_counter() - t0


@pytest.mark.slow
@pytest.mark.parametrize("token", [TOKEN, None], ids=["with-token", "without-token"])
def test_schemathesis_finds_nothing(seeded, token: str | None, record_property) -> None:
    base, tmp = seeded
    code, output, elapsed = _schemathesis(base, tmp, token)
    cases = re.search(r"(\d+) generated", output)
    n_cases = int(cases.group(1)) if cases else 0
    record_property("schemathesis_cases", n_cases)
    record_property("schemathesis_seconds", round(elapsed, 1))
    print(f"schemathesis: {n_cases} cases in {elapsed:.1f} s (seed {SEED})")
    passed = re.search(rf"\b{n_cases} generated, {n_cases} passed\b", output)
    assert code == 0 and passed, output[-8000:]
    # every operation of the document was tested
    selected = re.search(r"Selected: (\d+)/(\d+)\s+Tested: (\d+)", output)
    assert selected and len(set(selected.groups())) == 1, output[-4000:]
    # the server never failed (not only as seen from outside) and is still ready
    log = (tmp / "serve.log").read_text()
    assert "unhandled error" not in log and "database error" not in log, log[-4000:]
    assert httpx.get(base + "/health/ready", timeout=10).status_code == 200
