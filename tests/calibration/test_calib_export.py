"""``scm-calib export DIR --to netcdf``: an ArviZ InferenceData file that ArviZ itself reads
(``arviz.from_netcdf``), summarises (``az.summary``) and plots (``az.plot_pair``), whose posterior
is ``posterior.csv`` exactly (issue 44 item 2)."""

from __future__ import annotations

import csv
import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from test_calib_cli import CASE, run_cli


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    work = tmp_path_factory.mktemp("export")
    proc = run_cli(
        "synth", "--set", "phi=27", "--set", "J=0.004", "--set", "dx=0.015", "--set", "dt=0.05",
        "--duration", "8", "--ramp", "1", "--seed", "3", "--out", "log.csv", cwd=work,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    (work / "tiny.toml").write_text(CASE)
    proc = run_cli("calibrate", "tiny.toml", "--out", "ref", "--no-plots", cwd=work)
    assert proc.returncode == 0, proc.stderr
    return work / "ref"


def _columns(path: Path) -> dict[str, np.ndarray]:
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    return {h: np.array([float(r[i]) for r in rows[1:]]) for i, h in enumerate(rows[0])}


def test_netcdf_is_read_summarised_and_plotted_by_arviz(reference: Path, tmp_path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz as az

    proc = run_cli("export", reference, "--to", "netcdf", "--out", tmp_path / "t.nc", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "1 chain x" in proc.stdout and "completed" in proc.stdout
    idata = az.from_netcdf(tmp_path / "t.nc")
    assert {"posterior", "prior", "sample_stats", "observed_data", "tempering"} <= set(
        idata.groups()
    )

    summary = json.loads((reference / "summary.json").read_text())
    names = summary["parameters"]
    post = _columns(reference / "posterior.csv")
    prior = _columns(reference / "samples" / "stage_00.csv")
    for n in names:  # bit for bit: the CSV's repr of each float read back
        assert np.array_equal(idata.posterior[n].values[0], post[n])
        assert np.array_equal(idata.prior[n].values[0], prior[n])
        unit = (summary["units"] or {}).get(n)
        assert idata.posterior[n].attrs.get("units") == unit  # phi in deg; n has none
    stats = idata.sample_stats
    assert np.array_equal(stats["log_likelihood"].values[0], post["log_likelihood"])
    assert np.array_equal(stats["lp"].values[0], post["log_likelihood"] + post["log_prior"])
    exponents = idata.tempering["exponent"].values[0]
    assert exponents[0] == 0.0 and exponents[-1] == 1.0
    assert np.all(np.diff(exponents) > 0)  # tempering only increases
    log_z = idata.tempering["log_evidence"].values[0, -1]
    assert log_z == pytest.approx(summary["log_evidence"], rel=1e-12)

    # the measured steady means of the dataset, in SI units, with their standard errors
    obs = idata.observed_data
    means = summary["datasets"][0]["means"]
    assert obs["F"].values[0] == pytest.approx(means["F"], rel=1e-12)
    assert obs["z"].attrs["units"] == "m" and 0.0 < obs["z_se"].values[0] < abs(means["z"])
    attrs = idata.posterior.attrs
    assert attrs["status"] == "completed" and attrs["is_posterior"] == 1
    assert json.loads(attrs["case"])["name"] == summary["case"]["name"]
    assert set(json.loads(attrs["versions"])) == {"scm-calib", "numpy", "arviz"}

    # ArviZ's own summary: its mean and sd are numpy's over the draws
    table = az.summary(idata, kind="stats", round_to="none")
    for n in names:
        assert table.loc[n, "mean"] == pytest.approx(post[n].mean(), rel=1e-12)
        assert table.loc[n, "sd"] == pytest.approx(post[n].std(ddof=1), rel=1e-9)
    axes = az.plot_pair(idata, var_names=names, kind="kde", marginals=True)
    assert np.asarray(axes).shape == (len(names), len(names))


def test_export_refuses_a_folder_that_is_not_a_results_folder(tmp_path: Path) -> None:
    proc = run_cli("export", tmp_path, cwd=tmp_path)
    assert proc.returncode != 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "no summary.json" in lines[0], proc.stderr
