"""A results folder whose database was written before the lateral force was declared (three
responses per dataset in its sample rows) is read again by ``scm-calib calibrate``: its stage
tables get the Fy column, NaN where the old stages did not simulate it (issue 70)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import sqlalchemy as sa
from test_calib_cli import CASE, run_cli_here

from scm_core.signals.responses import N_FIRST, N_RESPONSES, RESPONSE_KEYS
from services.store import Store
from services.store.codec import f64_bytes
from services.store.models import Sample


def _make_old(db: Path) -> None:
    """Cut each dataset's fourth response out of every sample row, as the code before wrote."""
    store = Store.open(f"sqlite:///{db}")
    try:
        with store.db.write() as s:
            rows = s.execute(sa.select(Sample.stage_id, Sample.sample_index, Sample.responses))
            for stage_id, index, blob in rows.all():
                R = np.frombuffer(blob, dtype="<f8").reshape(-1, N_RESPONSES)[:, :N_FIRST]
                s.execute(
                    sa.update(Sample)
                    .where(Sample.stage_id == stage_id, Sample.sample_index == index)
                    .values(responses=f64_bytes(R.ravel()))
                )
    finally:
        store.close()


def test_an_old_folder_is_written_again_with_fy_nan(tmp_path: Path) -> None:
    synth = ("synth", "--set", "phi=27", "--set", "J=0.004", "--set", "dx=0.015")
    synth += ("--set", "dt=0.05", "--duration", "8", "--ramp", "1", "--out", "log.csv")
    assert run_cli_here(*synth, cwd=tmp_path).returncode == 0
    (tmp_path / "tiny.toml").write_text(CASE.replace("n_samples = 60", "n_samples = 20"))
    first = run_cli_here("calibrate", "tiny.toml", "--out", "out", "--no-plots", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    before = (tmp_path / "out" / "posterior.csv").read_text()
    _make_old(tmp_path / "out" / "study.db")
    again = run_cli_here("calibrate", "tiny.toml", "--out", "out", "--no-plots", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["status"] == "completed"
    with (tmp_path / "out" / "posterior.csv").open() as fh:
        rows = list(csv.reader(fh))
    names = [f"{r}[log]" for r in RESPONSE_KEYS]
    assert rows[0][-N_RESPONSES:] == names and all(len(r) == len(rows[0]) for r in rows)
    assert all(r[-1] == "nan" for r in rows[1:])  # Fy: not simulated then
    old = list(csv.reader(before.splitlines()))
    assert [r[:-1] for r in rows] == [r[:-1] for r in old][: len(rows)]  # the rest as it was
