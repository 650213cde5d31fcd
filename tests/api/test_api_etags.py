"""Conditional GETs: the list, a study, its stages and its events carry an ETag from the
studies' versions; a matching ``If-None-Match`` is answered 304 from the studies table alone
(the SQL statements of the 304 are counted with SQLAlchemy's cursor events), and any change of
state (a batch stored, a stage done, a cancel, a new study) gives a new tag.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager

import sqlalchemy as sa
from test_api_support import AUTH, summary_doc, tiny_case

from services.store import Store
from worker.orchestrator import ContextCache, execute_batch

#: tables a 304 must not read
HEAVY = ("samples", "stages", "work_batches", "datasets", "events", "study_datasets")


@contextmanager
def statements(engine: sa.Engine) -> Iterator[list[str]]:
    """The SQL statements ``engine`` executes inside the block."""
    seen: list[str] = []

    def record(conn, cursor, statement, parameters, context, executemany) -> None:
        seen.append(statement)

    sa.event.listen(engine, "before_cursor_execute", record)
    try:
        yield seen
    finally:
        sa.event.remove(engine, "before_cursor_execute", record)


def tables_read(sql: list[str]) -> set[str]:
    words = {w.strip('"').lower() for s in sql for w in re.findall(r'[\w"]+', s)}
    return {t for t in HEAVY if t in words}


def _submit(client, ds: int, seed: int) -> int:
    r = client.post(
        "/studies", json={"case": tiny_case(), "dataset_ids": [ds], "seed": seed}, headers=AUTH
    )
    assert r.status_code == 201, r.text
    return r.json()["id"]


def _run_one_batch(url: str, study_id: int) -> None:
    with Store.open(url) as store:
        study = store.studies.get(study_id)
        pending = [
            b for b in store.batches.list(study_id, study.current_stage) if b.status == "pending"
        ]
        execute_batch(store, pending[0].key, ContextCache(), None)


def test_304_reads_only_the_studies_table_and_any_change_gives_a_new_tag(env) -> None:
    client, url = env
    engine = client.app.state.store.engine
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    sid = _submit(client, ds, 1)
    paths = [f"/studies/{sid}", f"/studies/{sid}/stages", f"/studies/{sid}/events", "/studies"]
    tags = {}
    for path in paths:
        r = client.get(path)
        assert r.status_code == 200, r.text
        tags[path] = r.headers["etag"]
        assert tags[path].startswith('W/"') and r.headers["cache-control"] == "no-cache"
    assert len(set(tags.values())) == len(paths)  # each resource its own tag
    assert client.get(f"/studies/{sid}").json()["version"] >= 2  # created, started

    for path in paths:
        with statements(engine) as sql:
            r = client.get(path, headers={"If-None-Match": tags[path]})
        assert r.status_code == 304 and r.content == b"" and r.headers["etag"] == tags[path]
        selects = [s for s in sql if s.lstrip().upper().startswith("SELECT")]
        assert 1 <= len(selects) <= 2, sql  # the version(s), and the count of a list
        assert tables_read(sql) == set(), sql

    # the weak comparison and lists of tags (RFC 9110): W/ prefix optional, "*" matches
    one = f"/studies/{sid}"
    opaque = tags[one].removeprefix("W/")
    for header in (opaque, f'W/"other", {tags[one]}', "*"):
        assert client.get(one, headers={"If-None-Match": header}).status_code == 304
    assert client.get(one, headers={"If-None-Match": 'W/"other"'}).status_code == 200

    # a stored batch changes the study, its stages' progress and its events: new tags
    _run_one_batch(url, sid)
    for path in paths:
        r = client.get(path, headers={"If-None-Match": tags[path]})
        assert r.status_code == 200 and r.headers["etag"] != tags[path], path
        tags[path] = r.headers["etag"]

    # another study: the list changes, this study does not
    sid2 = _submit(client, ds, 2)
    assert client.get("/studies", headers={"If-None-Match": tags["/studies"]}).status_code == 200
    assert client.get(one, headers={"If-None-Match": tags[one]}).status_code == 304
    # a filtered list or another page is another resource
    r = client.get("/studies", params={"status": "running"})
    assert r.headers["etag"] != tags["/studies"]
    running = r.headers["etag"]

    # cancel: the study and the running list change
    assert client.post(f"/studies/{sid2}/cancel", headers=AUTH).status_code == 200
    r = client.get("/studies", params={"status": "running"}, headers={"If-None-Match": running})
    assert r.status_code == 200 and [s["id"] for s in r.json()["items"]] == [sid]


def test_unknown_study_is_404_with_any_etag(env) -> None:
    client, _ = env
    for path in ("/studies/999", "/studies/999/stages", "/studies/999/events"):
        r = client.get(path, headers={"If-None-Match": "*"})
        assert r.status_code == 404 and "study 999 not found" in r.json()["detail"]


def test_sensitivity_study_has_an_etag(env) -> None:
    client, _ = env
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    r = client.post(
        "/sensitivity",
        json={"preset": "1", "dataset_id": ds, "r": 2, "levels": 4},
        headers=AUTH,
    )
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    tag = client.get(f"/sensitivity/{sid}").headers["etag"]
    assert client.get(f"/sensitivity/{sid}", headers={"If-None-Match": tag}).status_code == 304


def test_dashboard_polls_get_304_from_the_studies_table_alone(env) -> None:
    """The dashboard's live fragments (a list row, a study's progress and stages) carry the
    study's ETag in ``data-etag`` and answer a matching poll with 304 the same way."""
    client, url = env
    engine = client.app.state.store.engine
    # the figure warmer's own thread reads watched studies five times a second: not the polls'
    client.app.state.figure_warmer.stop()
    ds = client.post("/datasets", json=summary_doc(), headers=AUTH).json()["id"]
    sid = _submit(client, ds, 3)
    for path in (f"/ui/f/studies/{sid}/row", f"/ui/f/studies/{sid}/live", "/ui/f/studies"):
        r = client.get(path)
        assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
        tag = r.headers["etag"]
        assert f'data-etag="{tag}"' in r.text.replace("&#34;", '"')  # attribute-escaped
        with statements(engine) as sql:
            again = client.get(path, headers={"If-None-Match": tag})
        assert again.status_code == 304 and again.content == b""
        assert tables_read(sql) == set(), sql
        _run_one_batch(url, sid)
        assert client.get(path, headers={"If-None-Match": tag}).status_code == 200
