"""Ten malformed lab files: ``scm-calib check`` names the file and the line or key in one
line and exits 1; ``POST /datasets`` refuses the same file with 422 and stores nothing."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner
from test_api_support import AUTH, detail, row_counts

from services.cli.check import check

HEADER = "time [s],drawbar_pull [N],torque [Nm],sinkage [mm]"
META = "# slip: 0.2\n# normal_load: 315 N\n"


def _rows(n: int = 600) -> list[str]:
    return [f"{i * 0.1:.6g},{20 + 0.1 * (i % 7)},5.0,12.0" for i in range(n)]


def _log(meta: str = META, header: str = HEADER, rows: list[str] | None = None) -> str:
    return meta + header + "\n" + "\n".join(_rows() if rows is None else rows) + "\n"


def _bad_row(line: int, text: str) -> str:
    rows = _rows()
    rows[line - 4] = text  # two metadata lines, the header on line 3
    return _log(rows=rows)


#: (name, text, what the message must name besides the file)
BAD = [
    ("empty", "", "empty file"),
    ("header_only", META + HEADER + "\n", "line 3"),
    ("bad_cell", _bad_row(50, "4.6,abc,5.0,12.0"), "line 50"),
    ("nan_cell", _bad_row(60, "5.6,nan,5.0,12.0"), "line 60"),
    ("short_row", _bad_row(70, "6.6,20.1"), "line 70"),
    ("slip_out_of_range", _log(meta="# slip: 1.5\n# normal_load: 315\n"), "slip"),
    ("no_load", _log(meta="# slip: 0.2\n"), "normal_load"),
    ("unknown_unit", _log(meta=META + "# wheel_radius: 12 furlong\n"), "furlong"),
    ("key_twice", _log(meta="# slip: 0.2\n# slip: 0.3\n# normal_load: 315\n"), "line 2"),
    ("grouser_too_tall", _log(meta=META + "# R: 0.1\n# grouser_height: 0.2\n"), "grouser"),
]


@pytest.mark.parametrize(("name", "text", "needle"), BAD, ids=[b[0] for b in BAD])
def test_check_names_file_and_place_in_one_line(tmp_path: Path, name, text, needle) -> None:
    path = tmp_path / f"{name}.csv"
    path.write_text(text)
    res = CliRunner().invoke(check, [str(path)])
    assert res.exit_code == 1, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, res.output
    assert f"{name}.csv" in errors[0] and needle in errors[0], errors[0]
    assert "Traceback" not in res.output


def test_the_service_stores_none_of_them(env) -> None:
    client, url = env
    before = row_counts(url)
    for name, text, _ in BAD:
        r = client.post(
            "/datasets", files={"file": (f"{name}.csv", text.encode(), "text/csv")}, headers=AUTH
        )
        assert r.status_code == 422, (name, r.status_code, r.text)
        assert "\n" not in detail(r)
    assert row_counts(url) == before
