"""``scm-calib serve`` as a real subprocess on a free port, driven by the Python client and by
``scm-calib upload``; and serve's refusal of a database at the wrong revision."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner
from test_api_support import (
    LOG,
    LOG2,
    ROOT,
    TOKEN,
    free_port,
    fresh_database,
    serve_env,
    serving,
    tiny_case,
)

from services.cli.main import cli
from services.client import SCMCalibClient, SCMCalibError

#: one worker runs the module: its module fixtures (a served API, a results folder) are
#: built once, not once per pytest-xdist worker
pytestmark = pytest.mark.xdist_group("test_api_serve")


def _cli(*args: str, env: dict[str, str], cwd: Path, timeout: float = 120.0):
    return subprocess.run(
        [sys.executable, "-m", "services.cli", *args],
        env=env,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory):
    """A fresh embedded ``scm-calib serve`` (new data directory, 2 local workers), shared by
    the tests of this module and stopped with SIGINT at the end (exit code 0)."""
    with serving(tmp_path_factory.mktemp("serve")) as server:
        yield server


def test_client_and_upload_cli_against_serve(server) -> None:
    base, env, tmp, _ = server
    assert (tmp / "data" / "scm-calib.db").is_file()  # migrated on start
    with SCMCalibClient(base, token=TOKEN, timeout=30) as api:
        assert api.health()["mode"] == "embedded"
        assert api.ready()["status"] == "ready"
        first = api.upload_log(LOG)  # sends the sidecar wf34_s020.json as metadata
        assert first["name"] == "wf34_s020"
        assert first["meta"]["true_parameters"]["phi"] == 27.0
        again = api.upload_log(LOG)
        assert again["id"] == first["id"] and again["created"] is False

        # the upload command: prints the id; the same file again gives the same id
        r = _cli("upload", str(LOG2), "--server", base, "--token", TOKEN, env=env, cwd=tmp)
        assert r.returncode == 0, r.stderr
        second = int(r.stdout.strip())
        assert second != first["id"] and f"dataset {second} (wf34_s050)" in r.stderr
        r = _cli("upload", str(LOG2), "--server", base, "--token", TOKEN, env=env, cwd=tmp)
        assert r.returncode == 0 and int(r.stdout.strip()) == second
        assert "already stored" in r.stderr
        listed = {d["id"] for d in api.datasets()["items"]}
        assert {first["id"], second} <= listed

        # a tiny study through the client, run by the server's local pool
        study = api.create_study(case=tiny_case(), dataset_ids=[first["id"]], seed=11)
        assert study["seed"] == 11
        done = api.wait(study["id"], timeout=240, poll=0.5)
        assert done["status"] == "completed", done
        post = api.samples(study["id"])
        assert post.samples.shape == (20, 2) and post.names == ["phi", "n"]
        summary = api.summary(study["id"])
        assert summary["is_posterior"] and summary["n_samples"] == 20
        csv_text = api.samples_csv(study["id"])
        assert csv_text.splitlines()[0].startswith("sample,phi,n,log_likelihood")

        with pytest.raises(SCMCalibError) as err:
            api.create_study(preset="9", dataset_ids=[first["id"]])
        assert err.value.status_code == 422 and str(err.value).startswith("preset:")
    with SCMCalibClient(base, token="wrong") as api, pytest.raises(SCMCalibError) as err:
        api.upload_log(LOG)
    assert err.value.status_code == 401 and "invalid API token" in str(err.value)


def test_upload_cli_errors(server) -> None:
    base, _, tmp, _ = server
    bad = tmp / "bad.csv"
    bad.write_bytes(LOG.read_bytes().replace(b"sinkage [m]", b"sinkage [parsec]"))
    meta = tmp / "meta.json"
    meta.write_text("[1, 2]")
    up = ["upload", str(LOG), "--server", base]
    cases = [
        # (arguments, exit code, words in the one-line message)
        (["upload", str(tmp / "nope.csv"), "--server", base], 2, ["no such file"]),
        (["upload", str(LOG)], 2, ["--server"]),
        ([*up, "--token", TOKEN, "--meta", str(meta)], 2, ["--meta", "JSON object"]),
        ([*up, "--token", "wrong"], 1, ["401", "invalid API token"]),
        (up, 1, ["401", "missing API token"]),
        (["upload", str(bad), "--server", base, "--token", TOKEN], 1,
         ["422", "file bad.csv", "sinkage [parsec]", "unit"]),
        (["upload", str(LOG), "--server", f"http://127.0.0.1:{free_port()}"], 1,
         ["ConnectError"]),
    ]  # fmt: skip
    runner = CliRunner()  # in-process command line, real server
    for args, code, words in cases:
        r = runner.invoke(cli, args, env={"SCM_CALIB_SERVER": None, "SCM_CALIB_TOKEN": None})
        stdout, stderr = r.stdout, r.stderr
        assert r.exit_code == code, (args, stdout, stderr)
        assert stdout == ""
        lines = stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error:"), stderr
        assert all(w in lines[0] for w in words), lines[0]


def test_serve_refuses_a_database_at_the_wrong_revision(tmp_path: Path) -> None:
    with fresh_database("postgresql", tmp_path, migrate=False) as url:
        env = serve_env(tmp_path, SCM_CALIB_DATABASE_URL=url)
        r = _cli("serve", "--port", str(free_port()), env=env, cwd=tmp_path, timeout=60)
        assert r.returncode == 1, r.stderr
        assert "scm-calib db upgrade" in r.stderr and "base" in r.stderr
        assert len(r.stderr.strip().splitlines()) == 1


def test_upload_cli_prints_json(server) -> None:
    base, env, tmp, _ = server
    r = _cli("upload", str(LOG), "--server", base, "--token", TOKEN, "--json", env=env, cwd=tmp)
    assert r.returncode == 0, r.stderr
    record = json.loads(r.stdout)
    assert record["name"] == "wf34_s020" and record["source_kind"] == "timeseries"
    assert record["filename"] == LOG.name and record["size_bytes"] == LOG.stat().st_size
    assert str(ROOT) not in r.stdout  # the server sees the file name, not the client's path


def test_worker_and_reaper_need_the_database_and_say_why_in_one_line(tmp_path: Path) -> None:
    """Neither a Celery worker nor the reaper starts (or says ready) on a database that does
    not answer: exit 1 with one line naming it, no traceback."""
    dead = f"postgresql://nobody@127.0.0.1:{free_port()}/nothing"
    env = serve_env(tmp_path, SCM_CALIB_BROKER_URL="redis://127.0.0.1:6379/15")
    env["SCM_CALIB_DATABASE_URL"] = dead
    for command in ("worker", "reaper"):
        proc = _cli(command, "--wait-db", "1", env=env, cwd=tmp_path, timeout=60)
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 1, (command, proc.stderr)
        assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
        assert lines[0].startswith("error: cannot use the database postgresql+psycopg://nobody@")
        assert "Connection refused" in lines[0] and "ready" not in proc.stdout


def _peak_rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
    raise AssertionError("no VmHWM")


def test_a_huge_study_is_refused_before_anything_is_allocated(server) -> None:
    """n_samples 1e9 used to build every work batch inside the request (22.8 GB, killed by
    the kernel): now 422 naming the field, the server's peak RSS unchanged within 50 MB."""
    base, _, _, pid = server
    with SCMCalibClient(base, token=TOKEN, timeout=30) as api:
        dataset = api.upload_log(LOG)["id"]
        total = api.studies()["total"]
        peak = _peak_rss_kib(pid)
        t0 = time.perf_counter()
        with pytest.raises(SCMCalibError) as err:
            api.create_study(case=tiny_case(), dataset_ids=[dataset], n_samples=10**9)
        elapsed = time.perf_counter() - t0
        assert err.value.status_code == 422 and str(err.value).startswith("n_samples: ")
        assert _peak_rss_kib(pid) - peak < 50 * 1024
        assert api.studies()["total"] == total
        print(f"n_samples 1e9 refused in {elapsed * 1e3:.1f} ms")
