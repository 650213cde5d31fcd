"""``POST /cases/check``: a TOML case file checked as the command line checks it (the
dashboard's case-file form). Nothing is stored; its errors are the command line's lines."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_api_support import AUTH, BACKENDS, api_client, detail, fresh_database, row_counts

from scm_core.calibration import CaseDefinition, load_case
from services.cli.common import CLIError, read_case

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.toml"))


@pytest.fixture(scope="module", params=BACKENDS)
def env(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory):
    directory = tmp_path_factory.mktemp(f"cases-{request.param}")
    with fresh_database(request.param, directory) as url, api_client(url) as client:
        yield client, url


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_every_example_case_file_gives_the_command_lines_case(env, path: Path) -> None:
    client, url = env
    before = row_counts(url)
    r = client.post("/cases/check", json={"toml": path.read_text()}, headers=AUTH)
    assert r.status_code == 200, r.text
    doc = r.json()["case"]
    expected = load_case(path).to_dict()
    for key in ("data",):  # files are the command line's business, not a study's
        doc.pop(key, None)
        expected.pop(key, None)
    assert doc == expected
    assert CaseDefinition.from_dict(doc).to_dict()["parameters"] == expected["parameters"]
    assert row_counts(url) == before


@pytest.mark.parametrize(
    "change",
    [
        ('dist = "uniform", lower = 15.0, upper = 45.0', 'dist = "uniform", lower = 45.0'),
        ('\nsinkage_datum = "rim"', '\nsinkage_datum = "axle"'),
        ("n_samples = 400", "n_samples = -4"),
        ("[parameters]", "[parameters"),
    ],
    ids=["prior", "simulator", "sampler", "syntax"],
)
def test_a_bad_case_file_answers_the_command_lines_message(env, tmp_path, change) -> None:
    client, url = env
    text = (ROOT / "examples" / "cmu_joint.toml").read_text()
    assert change[0] in text
    bad = text.replace(change[0], change[1], 1)
    path = tmp_path / "bad.toml"
    path.write_text(bad)
    with pytest.raises(CLIError) as cli:
        read_case(path)
    before = row_counts(url)
    r = client.post("/cases/check", json={"toml": bad}, headers=AUTH)
    assert r.status_code == 422
    message = detail(r)
    assert message == "toml: " + " ".join(cli.value.message.removeprefix("bad.toml: ").split())
    assert "\n" not in message
    assert row_counts(url) == before
