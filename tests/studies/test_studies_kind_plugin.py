"""A study kind is a plug-in: a dummy kind added to the registry in this test (its module is
this file) gets its API collection, runs through the same leases and stage machinery as every
kind, shows its own panel on the dashboard and its command on the command line, with nothing
else changed (issue 43); a second one with only a create route of its own (its own request
handling, repeated runs, answered with the common study, as the calibration kind's
``POST /studies`` is) gets it the same way, and every kind's create route, the built-in ones'
too, is the generic mount's (issue 72)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import click
import numpy as np
from click.testing import CliRunner
from pydantic import BaseModel, ConfigDict, Field
from test_api_support import AUTH, api_client, fresh_database, settings_for

from scm_core.inference.tmcmc.stage import PointEvaluation
from services.api.main import create_app
from services.api.views import kind_posts
from services.store import (
    BatchLease,
    BatchOutput,
    ReducedStage,
    ReduceInput,
    SampleArrays,
    StageAdvance,
    Store,
    StudyRecord,
    StudySpec,
)
from services.store.codec import decode
from services.studies import StudyRequestError
from services.studies.kinds import KINDS, KindPanel, StudyTerms
from services.studies.kinds.base import KindCli, KindHttp, batch_output, one_run_per_item
from worker.orchestrator import ContextCache, execute_batch


class SquaresRequest(BaseModel):
    """Square the numbers 0 .. n - 1."""

    model_config = ConfigDict(extra="forbid")
    n: int = Field(ge=1, le=50)
    name: str = "squares"


def squares_spec(store: Store, settings: Any, body: SquaresRequest) -> StudySpec:
    return StudySpec(
        name=body.name, case={}, dataset_ids=[], seed=0, n_samples=body.n, kind="squares"
    )


@dataclass
class SquaresRun:
    n: int

    @property
    def model_function(self):
        return lambda x: x**2

    def compute(self, store: Store, lease: BatchLease, model_function: Any) -> BatchOutput:
        x = np.arange(lease.chain_start, lease.chain_stop, dtype=float)
        nan = np.full(x.size, np.nan)
        return batch_output(lease, PointEvaluation(nan, model_function(x)[:, None], 0))

    def reducer(self, workers: int):
        def reduce(inp: ReduceInput) -> StageAdvance:
            y = np.concatenate([decode(b, PointEvaluation).responses for b in inp.results])
            x = np.arange(self.n, dtype=float)[:, None]
            nan = np.full(self.n, np.nan)
            reduced = ReducedStage(0, SampleArrays(x, nan, nan, y), self.n, 0)
            total = float(y.sum())
            return StageAdvance(reduced, final_status="completed", result={"sum": total})

        return reduce


@click.command()
@click.option("--n", type=click.IntRange(1, 50), required=True, help="How many numbers.")
def squares_command(n: int) -> None:
    """Sum the squares of 0 .. n - 1."""
    click.echo(f"sum {sum(k * k for k in range(n))}")


class SquaresFields(BaseModel):
    """What a study of squares shows beside the common fields."""

    largest: int


class SquaresKind:
    name = "squares"
    title = "sum of squares"
    http = KindHttp(
        path="/squares",
        request=SquaresRequest,
        spec=squares_spec,
        result=None,
        description="Squares and sums the first n integers.",
        fields=SquaresFields,
        fields_of=lambda study: SquaresFields(largest=study.n_samples - 1),
    )
    cli = KindCli("squares", "test_studies_kind_plugin:squares_command")
    collection = "/squares"
    posterior = False

    def __init__(self, templates) -> None:
        self.panel = KindPanel(template="squares_panel.html", counts="numbers", templates=templates)

    def build(self, store: Store, study: StudyRecord) -> SquaresRun:
        return SquaresRun(study.n_samples)

    def planned_runs(self, plan: bytes | None, batches: Sequence[range]) -> list[int]:
        return one_run_per_item(batches)

    def terms(self, study: StudyRecord) -> StudyTerms:
        return StudyTerms({"parameters": [{"name": "x"}]}, {}, {})


def test_a_new_kind_mounts_its_routes_runs_and_shows_its_panel(tmp_path, monkeypatch) -> None:
    panel_dir = tmp_path / "templates"
    panel_dir.mkdir()
    (panel_dir / "squares_panel.html").write_text(
        '<h2>Squares</h2><p id="squares-sum">{% if result %}sum {{ result.sum|num(6) }}'
        "{% else %}running{% endif %}</p>"
    )
    monkeypatch.setitem(KINDS, "squares", SquaresKind(panel_dir))
    with fresh_database("sqlite", tmp_path) as url, api_client(url) as client:
        assert "/squares" in client.get("/openapi.json").json()["paths"]
        r = client.post("/squares", json={"n": 10, "bad": 1}, headers=AUTH)
        assert r.status_code == 422 and "bad" in r.text  # its own request model
        r = client.post("/squares", json={"n": 10}, headers=AUTH)
        assert r.status_code == 201, r.text
        sid = r.json()["id"]
        with Store.open(url) as store:
            cache = ContextCache()
            while store.studies.get(sid).status == "running":
                pending = [b for b in store.batches.list(sid, 0) if b.status == "pending"]
                execute_batch(store, pending[0].key, cache, None)
        study = client.get(f"/squares/{sid}").json()
        assert study["status"] == "completed" and study["result"] == {"sum": 285.0}
        assert study["largest"] == 9 and study["n_samples"] == 10  # its own and the common
        listing = client.get("/squares").json()
        assert [s["largest"] for s in listing["items"]] == [9]
        schemas = client.get("/openapi.json").json()["components"]["schemas"]
        assert {"largest", "progress", "result"} <= set(schemas["SumOfSquaresOut"]["properties"])
        assert client.get(f"/studies/{sid}").json()["kind"] == "squares"
        listed = client.get("/", params={"kind": "squares"}).text
        assert "sum of squares" in listed  # the list's filter offers it by its title
        live = client.get(f"/ui/f/studies/{sid}/live").text
        assert "sum of squares" in live and "10 numbers" in live
        results = client.get(f"/ui/f/studies/{sid}/results").text
        assert '<p id="squares-sum">sum 285</p>' in results, results
        r = client.get(f"/studies/{sid}/summary")
        assert r.status_code == 409 and f"GET /squares/{sid}" in r.json()["detail"]


def test_a_new_kind_mounts_its_command_line_command(tmp_path, monkeypatch) -> None:
    """The kind's ``cli`` is a command of ``scm-calib``: listed in the help with its own
    help line, run with its options, its bad input a one-line error; the built-in kinds'
    commands come from the registry the same way."""
    from services.cli.main import cli, kind_commands

    assert {"calibrate", "sensitivity", "predict"} <= set(kind_commands())
    monkeypatch.setitem(KINDS, "squares", SquaresKind(tmp_path))
    runner = CliRunner()
    listed = runner.invoke(cli, ["--help"])
    assert listed.exit_code == 0 and "squares" in listed.output
    assert "Sum the squares" in listed.output
    ran = runner.invoke(cli, ["squares", "--n", "10"])
    assert ran.exit_code == 0 and ran.output.strip() == "sum 285"
    bad = runner.invoke(cli, ["squares", "--n", "0"])
    assert bad.exit_code == 2 and "--n" in bad.output


class TallyRequest(BaseModel):
    """Tally 0 .. n - 1, ``runs`` times."""

    model_config = ConfigDict(extra="forbid")
    n: int = Field(ge=1, le=50)
    runs: int = Field(1, ge=1, le=5)


def tally_specs(store: Store, settings: Any, body: TallyRequest) -> list[StudySpec]:
    """The kind's own request handling: a refusal naming the field, repeated runs."""
    if body.n == 13:
        raise StudyRequestError("n: 13 is not tallied")
    spec = StudySpec(name="tally", case={}, dataset_ids=[], seed=0, n_samples=body.n, kind="tally")
    return [replace(spec, name=f"tally {k + 1}", seed=k) for k in range(body.runs)]


@click.command()
@click.option("--n", type=click.IntRange(1, 50), required=True, help="How many numbers.")
def tally_command(n: int) -> None:
    """Tally 0 .. n - 1."""
    click.echo(f"tally {n}")


class TallyKind(SquaresKind):
    """A kind with only a create route of its own: its studies are read as every study is."""

    name = "tally"
    title = "tally run"
    http = KindHttp(
        path="/tallies",
        request=TallyRequest,
        spec=tally_specs,
        result=None,
        description="Tallies the first n integers, runs times.",
        reads=False,
        summary="Start a tally",
        statuses=(401, 422),
    )
    cli = KindCli("tally", "test_studies_kind_plugin:tally_command")
    collection = "/studies"


def _run(url: str, sid: int) -> None:
    with Store.open(url) as store:
        cache = ContextCache()
        while store.studies.get(sid).status == "running":
            pending = [b for b in store.batches.list(sid, 0) if b.status == "pending"]
            execute_batch(store, pending[0].key, cache, None)


def test_a_kind_with_its_own_create_route_is_mounted_the_same_way(tmp_path, monkeypatch) -> None:
    panel_dir = tmp_path / "templates"
    panel_dir.mkdir()
    (panel_dir / "squares_panel.html").write_text(
        '<p id="squares-sum">{% if result %}sum {{ result.sum|num(6) }}{% endif %}</p>'
    )
    monkeypatch.setitem(KINDS, "tally", TallyKind(panel_dir))
    with fresh_database("sqlite", tmp_path) as url, api_client(url) as client:
        spec = client.get("/openapi.json").json()
        assert set(spec["paths"]["/tallies"]) == {"post"}  # a create route, no reads
        assert spec["paths"]["/tallies"]["post"]["summary"] == "Start a tally"
        assert not any(p.startswith("/tallies/") for p in spec["paths"])
        assert client.post("/tallies", json={"n": 3}).status_code == 401  # a write
        r = client.post("/tallies", json={"n": 13}, headers=AUTH)
        assert r.status_code == 422 and r.json()["detail"] == "n: 13 is not tallied"
        r = client.post("/tallies", json={"n": 4, "runs": 3, "bad": 1}, headers=AUTH)
        assert r.status_code == 422 and "bad" in r.text  # its own request model
        assert client.get("/studies", params={"kind": "tally"}).json()["total"] == 0
        r = client.post("/tallies", json={"n": 4, "runs": 3}, headers=AUTH)
        assert r.status_code == 201, r.text
        study = r.json()  # the common study, read at /studies/{id}
        sid = study["id"]
        assert r.headers["Location"] == f"/studies/{sid}"
        assert study["kind"] == "tally" and study["runs"] == [sid, sid + 1, sid + 2]
        assert client.get("/studies", params={"kind": "tally"}).json()["total"] == 3
        _run(url, sid)
        read = client.get(f"/studies/{sid}").json()
        assert read["status"] == "completed" and read["result"] == {"sum": 14.0}
        assert "tally run" in client.get("/", params={"kind": "tally"}).text  # the filter
        listed = client.get("/ui/f/studies", params={"kind": "tally"}).text
        assert listed.count("<td>tally run</td>") == 3, listed  # the rows, by its title
        results = client.get(f"/ui/f/studies/{sid}/results").text
        assert '<p id="squares-sum">sum 14</p>' in results, results
    assert kind_posts()["tally"] == "/tallies"  # where the dashboard's forms would post it


def test_every_kinds_create_route_is_the_generic_mounts(tmp_path, monkeypatch) -> None:
    """One ``POST`` route per kind's declared path, made by the kinds' router (none by hand,
    the built-in kinds' included: the calibration's ``POST /studies``)."""
    monkeypatch.setitem(KINDS, "squares", SquaresKind(tmp_path))
    monkeypatch.setitem(KINDS, "tally", TallyKind(tmp_path))
    app = create_app(settings_for(f"sqlite:///{tmp_path / 'x.db'}"), start_local_runtime=False)
    posts: dict[str, list[str]] = {}
    for route in app.state.api_routes:  # every router's routes, as mounted
        if "POST" in route.methods:
            posts.setdefault(route.path, []).append(route.endpoint.__module__)
    declared = [k.http.path for k in KINDS.values() if k.http is not None]
    assert {"/studies", "/sensitivity", "/predictions", "/squares", "/tallies"} <= set(declared)
    for path in declared:
        assert posts[path] == ["services.api.routes.kinds"], (path, posts.get(path))


def test_a_kind_with_its_own_create_route_has_its_command(monkeypatch) -> None:
    from services.cli.main import cli

    monkeypatch.setitem(KINDS, "tally", TallyKind(None))
    runner = CliRunner()
    listed = runner.invoke(cli, ["--help"])
    assert listed.exit_code == 0 and "tally" in listed.output
    ran = runner.invoke(cli, ["tally", "--n", "4"])
    assert ran.exit_code == 0 and ran.output.strip() == "tally 4"
