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

#: one worker runs the module: its module fixtures (a served API, a results folder) are
#: built once, not once per pytest-xdist worker
pytestmark = pytest.mark.xdist_group("test_calib_export")


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


# ---- Chrono (issue 44 item 3) ----------------------------------------------------------------


def _soil_rig(**changes):
    from scm_core.simulator import RigConfig, SoilParams

    soil = dict(k_phi=2.0e6, k_c=1.5e3, n=1.07, c=120.0, phi=31.5, J=0.012, K=4.0e7,
                D_soil=2.5e4, repose_angle=33.0, compaction=0.3)  # fmt: skip
    rig = {"shear": "displacement"}
    for k, v in changes.items():
        (rig if k in RigConfig.model_fields else soil)[k] = v
    return SoilParams(**soil), RigConfig(**rig)


def test_chrono_takes_each_parameter_in_its_units() -> None:
    from services.exports.chrono import chrono_soil

    soil, rig = _soil_rig()
    out, dropped = chrono_soil(soil, rig)
    assert dropped == []
    # Bekker: N/m^(n+2) is Pa/m^n, N/m^(n+1) is Pa/m^(n-1): the same numbers
    assert (out.Bekker_Kphi, out.Bekker_Kc, out.Bekker_n) == (2.0e6, 1.5e3, 1.07)
    assert (out.Mohr_cohesion, out.Mohr_friction) == (120.0, 31.5)  # Pa, deg
    assert out.Janosi_shear == 0.012  # m: the displacement form only
    assert (out.elastic_K, out.damping_R) == (4.0e7, 2.5e4)  # Pa/m, Pa s/m = N s/m^3
    assert out.erosion_angle == 33.0 and out.flow_factor == pytest.approx(0.7)
    # the same Bekker pressure at any plate width and sinkage (eq. 7 and Chrono's)
    b, z = 0.05, 0.012
    ours = (soil.k_c / b + soil.k_phi) * z**soil.n
    assert (out.Bekker_Kc / b + out.Bekker_Kphi) * z**out.Bekker_n == ours


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        ({"shear": "velocity"}, "J = 0.012 m/s"),
        ({"bearing_inclination": 2.0}, "bearing_inclination"),
        ({"ploughing": 0.2}, "ploughing = 0.2"),
        ({"bulk_density": 1330.0}, "bulk_density = 1330 kg/m^3"),
        ({"skid_ploughing": "sliding_face"}, "sliding_face"),
        ({"drive_digging": "mobilised"}, "mobilised"),
        ({"grouser_contact": "tip_circle"}, "tip_circle"),
        ({"interface_friction": 0.6}, "interface_friction = 0.6"),
    ],
)
def test_chrono_refuses_what_it_cannot_represent_unless_lossy(change, needle) -> None:
    from services.exports.chrono import ChronoExportError, chrono_soil

    soil, rig = _soil_rig(**change)
    with pytest.raises(ChronoExportError, match="--lossy") as info:
        chrono_soil(soil, rig)
    assert needle in str(info.value) and "\n" not in str(info.value)
    out, dropped = chrono_soil(soil, rig, lossy=True)
    assert len(dropped) == 1 and needle in dropped[0]
    assert (out.Janosi_shear is None) == ("shear" in change)
    assert out.Bekker_Kphi == soil.k_phi  # the rest carried over


def test_chrono_refuses_an_elastic_modulus_below_k_phi_even_lossy() -> None:
    from services.exports.chrono import ChronoExportError, chrono_soil

    soil, rig = _soil_rig(K=1.0e6)
    with pytest.raises(ChronoExportError, match="elastic_K > Bekker_Kphi"):
        chrono_soil(soil, rig, lossy=True)


def test_chrono_calls_compile_and_run(tmp_path: Path) -> None:
    """The C++ passes g++'s syntax check against a class with Chrono's signatures, the Python
    runs against an object with them; both pass the numbers in Chrono's order."""
    import shutil
    import subprocess

    from services.exports.chrono import chrono_soil, cpp_call, python_call

    soil, rig = _soil_rig()
    out, _ = chrono_soil(soil, rig)
    calls = []

    class Terrain:
        def SetSoilParameters(self, *args):
            calls.append(args)

        def SetBulldozingParameters(self, *args):
            calls.append(args)

    exec(python_call(out), {"terrain": Terrain()})
    assert calls == [(2.0e6, 1.5e3, 1.07, 120.0, 31.5, 0.012, 4.0e7, 2.5e4), (33.0, 0.7)]
    if shutil.which("g++") is None:
        pytest.skip("no C++ compiler")
    src = tmp_path / "t.cpp"
    src.write_text(
        "struct SCMTerrain { void SetSoilParameters(double, double, double, double, double,"
        " double, double, double) {} void SetBulldozingParameters(double, double) {} };\n"
        "int main() { SCMTerrain terrain;\n" + cpp_call(out, comment="test") + "return 0; }\n"
    )
    proc = subprocess.run(["g++", "-fsyntax-only", str(src)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_chrono_export_of_a_results_folder(reference: Path, tmp_path: Path) -> None:
    """The tiny case uses the velocity form of J: refused without --lossy (one line), exported
    with it (J left for the user to choose); the medians are posterior.csv's."""
    proc = run_cli(
        "export", reference, "--to", "chrono", "--out", tmp_path / "c.json", cwd=tmp_path
    )
    assert proc.returncode == 2  # a bad input (CLIError)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "m/s" in lines[0] and "--lossy" in lines[0], proc.stderr
    assert lines[0].startswith("error: the MAP soil: ")  # which set's J (issue 69)
    assert not (tmp_path / "c.json").exists()
    proc = run_cli(
        "export", reference, "--to", "chrono", "--out", tmp_path / "c.json", "--lossy",
        "--draws", "5", cwd=tmp_path,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "warning: dropped (--lossy): MAP: J =" in proc.stderr
    assert "warning: dropped (--lossy): posterior median: J =" in proc.stderr
    doc = json.loads((tmp_path / "c.json").read_text())
    post = _columns(reference / "posterior.csv")
    median = doc["sets"]["posterior median"]
    assert median["Mohr_friction"] == float(np.median(post["phi"]))
    assert median["Bekker_n"] == float(np.median(post["n"]))
    assert median["Janosi_shear"] is None and len(doc["draws"]) == 5
    assert set(doc["sets"]) == {"MAP", "posterior median"}
    assert "janosi_shear" in (tmp_path / "c.cpp").read_text()
    assert "SetSoilParameters(" in (tmp_path / "c.py").read_text()
