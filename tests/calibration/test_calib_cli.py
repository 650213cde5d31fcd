"""``scm-calib synth``, ``calibrate`` and ``sensitivity``: files, resume, workers, errors."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

CASE = """
name = "tiny"
seed = 4
likelihood = "gaussian"

[parameters]
phi = { dist = "normal", mean = 30.0, sd = 5.7, lower = 11.5, upper = 37.3, unit = "deg" }
n = { dist = "normal", mean = 1.1, sd = 0.2, lower = 0.8, upper = 2.0 }

[nominal]
J = 0.004
sigma_F = 3.0
sigma_T = 0.4
sigma_z = 0.0005

[simulator]
duration = 8.0
dx = 0.015
dt = 0.05
offset_F = 4.0
offset_T = 4.0
offset_z = 4.0

[sampler]
n_samples = 60
moves = "leader"

[data]
files = ["log.csv"]
offset = 4.0

[reference]
phi = 30.0
n = 1.1
"""


def run_cli(*args, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "services.cli", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])},
    )


def run_cli_here(*args, cwd: Path) -> subprocess.CompletedProcess:
    """``scm-calib ARGS`` in this process (click's runner, from ``cwd``): the same command and
    error handling as :func:`run_cli` without an interpreter's start (seconds of imports), for
    the input errors that stop a command before it computes anything;
    :func:`test_the_entry_point_gives_the_in_process_error_lines` checks both agree."""
    from click.testing import CliRunner

    from services.cli.main import cli

    with contextlib.chdir(cwd):
        res = CliRunner().invoke(cli, [str(a) for a in args])
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise res.exception  # a traceback: the CLI must never give one
    return subprocess.CompletedProcess(list(args), res.exit_code, res.stdout, res.stderr)


def one_line_error(proc: subprocess.CompletedProcess, code: int = 2) -> str:
    assert proc.returncode == code, (proc.returncode, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    return lines[0]


def stage_files(out: Path) -> dict[str, bytes]:
    files = {p.name: p.read_bytes() for p in sorted((out / "samples").glob("stage_*.csv"))}
    files["posterior.csv"] = (out / "posterior.csv").read_bytes()
    return files


def folder_states(out: Path) -> list:
    """The stages of the results folder ``out`` as the commands read them (its database)."""
    from services.cli.results import results_stages
    from services.stages import stage_states

    summary = json.loads((out / "summary.json").read_text())
    with results_stages(out, summary) as stages:
        return stage_states(stages)


def done_stages(out: Path) -> int:
    """Stages the folder's database holds as done (0 before it has one), read while a
    command may be writing it."""
    import sqlite3

    try:
        with contextlib.closing(
            sqlite3.connect(f"file:{out / 'study.db'}?mode=ro", uri=True, timeout=5)
        ) as db:
            return db.execute("select count(*) from stages where status = 'done'").fetchone()[0]
    except sqlite3.OperationalError:  # no database or no table yet
        return 0


def as_older_folder(src: Path, dst: Path, work: Path, stages: int | None = None) -> Path:
    """``src`` as a folder written before folders held a database: its files without the
    database, its stages (the first ``stages``) as ``checkpoints/stage_NNN.json`` with the
    manifest such folders had (of ``tiny.toml`` on ``log.csv``)."""
    import shutil

    from scm_core.calibration import load_case
    from scm_core.signals import load_dataset
    from services.cli.export import write_stages
    from services.cli.folder_store import DB_FILE
    from services.cli.results import checkpoint_manifest
    from services.stages.folder import write_json

    skip = shutil.ignore_patterns(f"{DB_FILE}*", "predictions", "stages", ".scm-calib.lock")
    shutil.copytree(src, dst, ignore=skip)
    checkpoints = dst / "checkpoints"
    write_stages(src, checkpoints)
    for extra in sorted(checkpoints.glob("stage_*.json"))[stages:] if stages else []:
        extra.unlink()
    case = load_case(work / "tiny.toml")
    data = [load_dataset(work / "log.csv", offset=case.data.offset)]
    write_json(checkpoints / "manifest.json", checkpoint_manifest(case, data))
    return dst


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("cli")
    proc = run_cli(
        "synth",
        "--set",
        "phi=27",
        "--set",
        "J=0.004",
        "--set",
        "dx=0.015",
        "--set",
        "dt=0.05",
        "--duration",
        "8",
        "--ramp",
        "1",
        "--seed",
        "3",
        "--out",
        "log.csv",
        cwd=d,
    )
    assert proc.returncode == 0, proc.stderr
    (d / "tiny.toml").write_text(CASE)
    return d


@pytest.fixture(scope="module")
def reference(work: Path) -> Path:
    proc = run_cli("calibrate", "tiny.toml", "--out", "ref", cwd=work)
    assert proc.returncode == 0, proc.stderr
    assert "completed" in proc.stdout
    (work / "ref_stderr.txt").write_text(proc.stderr)
    return work / "ref"


def test_progress_lines_when_output_is_not_a_terminal(reference: Path) -> None:
    """Captured output (a log file) gets plain lines: a start, every 10 %, and a finished line
    per stage; no terminal control codes."""
    err = (reference.parent / "ref_stderr.txt").read_text()
    assert "\x1b[" not in err
    lines = err.splitlines()
    assert any(line.startswith("stage  1 started: p = ") for line in lines)
    progress = [line for line in lines if line.startswith("stage  1: ") and " % (" in line]
    assert progress and all("ETA" in line for line in progress)
    percents = [int(line.split(":")[1].split("%")[0]) for line in progress]
    assert percents == sorted(set(percents)) and percents[0] >= 10 and percents[-1] < 100
    assert len(progress) <= 9  # at most one line per tenth
    done = [line for line in lines if " done: p = " in line]
    summary = json.loads((reference / "summary.json").read_text())
    assert len(done) == summary["n_stages"] + 1  # stage 0 (prior draws) included


SUMMARY_WITHOUT_TORQUE = """# slip: 0.2
# normal_load: 315 N
# wheel_radius: 125 mm
trial,drawbar_pull [N],sinkage [mm]
1,{F1},{z1}
2,{F2},{z2}
3,{F3},{z3}
"""


def test_summary_without_torque_calibrates(work: Path, reference: Path) -> None:
    """A lab summary of F and z only: the case's T term is simply absent (never a dummy 0)."""
    ref = json.loads((reference / "summary.json").read_text())
    m = next(iter(ref["map_responses"].values()))["simulated"]
    F, z = m["F"], 1000 * m["z"]
    (work / "no_torque.csv").write_text(
        SUMMARY_WITHOUT_TORQUE.format(F1=F - 1, F2=F, F3=F + 1, z1=z - 0.2, z2=z, z3=z + 0.2)
    )
    proc = run_cli("calibrate", "tiny.toml", "--data", "no_torque.csv", "--out", "nt", cwd=work)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((work / "nt" / "summary.json").read_text())
    assert summary["status"] == "completed"
    assert summary["datasets"][0]["means"]["T"] is None
    measured = next(iter(summary["map_responses"].values()))["measured"]
    assert set(measured) == {"F", "z"}
    assert (work / "nt" / "figures" / "fit_map.png").stat().st_size > 0


def test_predict_bands_sweep_and_reproducible(work: Path, reference: Path) -> None:
    args = ("predict", "ref", "--data", "log.csv", "--draws", "12", "--seed", "3")
    proc = run_cli(*args, "--sweep", "slip=-0.5:0.6:3", "--json", cwd=work)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    (p,) = doc["datasets"]
    assert p["role"] == "calibration" and p["n_draws"] == 12
    for r in ("F", "T", "z"):
        band = p["responses"][r]
        for kind in ("simulated", "predictive"):
            assert band[kind]["lo"] <= band[kind]["median"] <= band[kind]["hi"]
        assert band["predictive"] != band["simulated"]  # the sigma's noise is added
        assert band["measured"] is not None and band["inside_predictive"] is not None
    assert [s["slip_symmetric"] for s in doc["sweep"]] == pytest.approx([-0.5, 0.05, 0.6])
    assert (work / "ref" / "predictions" / "predictions.png").stat().st_size > 0
    again = run_cli(*args, "--sweep", "slip=-0.5:0.6:3", "--json", "--no-plots", cwd=work)
    assert json.loads(again.stdout) == doc  # same seed, same numbers
    # the draws behind the bands go to ArviZ's posterior_predictive, beside observed_data
    for r in ("F", "T", "z"):
        draws = np.array(p["responses"][r]["draws"], dtype=float)
        assert draws.shape == (12,)
        assert np.median(draws) == pytest.approx(p["responses"][r]["predictive"]["median"])
    export = run_cli("export", "ref", "--out", "ref_ppc.nc", cwd=work)
    assert export.returncode == 0, export.stderr
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz as az

        idata = az.from_netcdf(str(work / "ref_ppc.nc"))
        az.plot_ppc(idata, var_names=["F"])
    ppc = idata.posterior_predictive
    assert ppc.sizes == {"chain": 1, "draw": 12, "dataset": 1}
    assert list(ppc["F"].dataset.values) == list(idata.observed_data["F"].dataset.values)
    for r in ("F", "T", "z"):
        assert np.array_equal(ppc[r].values[0, :, 0], np.array(p["responses"][r]["draws"]))


def test_predict_is_the_librarys_predict_bit_for_bit_also_from_an_older_folder(
    work: Path, reference: Path
) -> None:
    """``scm-calib predict`` runs prediction studies of the results folder's database (the
    service's kind): its bands and draws are ``scm_core``'s ``predict`` on the folder's
    posterior bit for bit; a folder without a database (written before folders held one)
    gets its posterior taken over from its checkpoints and predicts the same numbers."""
    from scm_core.calibration import load_case
    from scm_core.calibration.predict import predict
    from scm_core.signals import load_dataset
    from services.cli.folder_store import DB_FILE
    from services.cli.results import load_results

    args = ("--data", "log.csv", "--draws", "9", "--seed", "4", "--json", "--no-plots")
    proc = run_cli("predict", "ref", *args, "--out", "p_new", cwd=work)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    case, samples, _ = load_results(reference)
    data = [load_dataset(work / "log.csv", offset=load_case(work / "tiny.toml").data.offset)]
    (expected,) = predict(case, samples, data, draws=9, seed=4, roles=["calibration"])
    assert doc["datasets"] == [json.loads(json.dumps(expected.to_dict(draws=True)))]
    older = as_older_folder(reference, work / "ref_older", work)
    assert not (older / DB_FILE).exists()
    again = run_cli("predict", older, *args, cwd=work)
    assert again.returncode == 0, again.stderr
    assert json.loads(again.stdout)["datasets"] == doc["datasets"]


def test_predict_at_conditions_nobody_measured(work: Path, reference: Path) -> None:
    """--at gives bands with no measurement, the same numbers as a dataset with those
    conditions would get; units as in lab metadata."""
    proc = run_cli(
        "predict", "ref", "--at", "W=315 N,slip=0.3", "--at", "W=0.3 kN,slip=-0.2,"
        "slip_convention=symmetric", "--draws", "8", "--json", "--no-plots", cwd=work,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["datasets"] == [] and len(doc["conditions"]) == 2
    first, skid = doc["conditions"]
    assert first["role"] == "untested" and first["slip_symmetric"] == pytest.approx(0.3)
    assert skid["slip_symmetric"] == pytest.approx(-0.2)
    for r in ("F", "T", "z"):
        band = first["responses"][r]
        assert band["measured"] is None
        assert band["simulated"]["lo"] <= band["simulated"]["median"] <= band["simulated"]["hi"]
    # skidding brakes: the median drawbar pull at -0.2 is below the one at +0.3
    assert (
        skid["responses"]["F"]["simulated"]["median"]
        < first["responses"]["F"]["simulated"]["median"]
    )


def test_predict_sweeps_the_slip_angle_at_the_datasets_slip(work: Path, reference: Path) -> None:
    """``--sweep slip_angle=LO:HI:N``: the dataset's conditions (its slip 0.2, load, wheel) at
    each slip angle, named "slip_angle 30"; Fy is predicted (exactly 0 straight: the kernel's
    straight path) and the figure draws the sweep against the angle beside the straight
    dataset, which has no Fy."""
    args = ("--data", "log.csv", "--draws", "4", "--json", "--out", "p_beta")
    proc = run_cli("predict", "ref", *args, "--sweep", "slip_angle=0:60:3", cwd=work)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    (data,) = doc["datasets"]
    assert [s["name"] for s in doc["sweep"]] == ["slip_angle 0", "slip_angle 30", "slip_angle 60"]
    for s, beta in zip(doc["sweep"], (0.0, 30.0, 60.0), strict=True):
        assert s["conditions"] == {**data["conditions"], "slip_angle": beta}
        assert s["slip_symmetric"] == pytest.approx(0.2)
    fy = [s["responses"]["Fy"]["simulated"] for s in doc["sweep"]]
    assert fy[0] == {"median": 0.0, "lo": 0.0, "hi": 0.0}
    assert fy[1]["median"] > 0.0 and fy[2]["median"] > 0.0
    assert "Fy" not in data["responses"]
    assert (work / "p_beta" / "predictions.png").stat().st_size > 0


def test_predict_map_writes_the_force_map_a_vehicle_model_reads(
    work: Path, reference: Path
) -> None:
    """``--map``: force_map.csv, one row per slip x slip angle with F, T, z, Fy (median, 95 %
    band of the simulated means, SI) at the study's first dataset's load, and force_map.png;
    the prediction studies' numbers (predictions.json's "map"), which are the library's
    ``predict`` on ``map_targets``'s grid. Physics, with tolerances the simulator's tests
    justify (tests/simulator/test_sim_steering.py): a straight wheel's Fy is exactly 0 (the
    kernel's straight path), and the mirror angles +60 and -60 deg give the same F, T, z and
    opposite Fy per draw to 2e-3 relative (the two images sum rows in opposite orders), so
    their quantiles over the same draws agree to that too (a quantile moves no more than the
    values it is taken of; -Fy's lo is Fy's hi)."""
    import csv

    from scm_core.calibration import DatasetTerms
    from scm_core.calibration.predict import map_targets, predict
    from services.cli.results import load_results

    args = ("--draws", "6", "--seed", "2", "--out", "p_map")
    spec = "slip=-0.5:0.5:3,beta=-60:60:3"  # a lab's name of the slip angle
    proc = run_cli("predict", "ref", "--map", spec, *args, cwd=work)
    assert proc.returncode == 0, proc.stderr
    assert "force map of 9 points" in proc.stdout
    out = work / "p_map"
    assert (out / "force_map.png").stat().st_size > 0
    assert not (out / "predictions.png").exists()  # nothing but the map to draw
    lines = (out / "force_map.csv").read_text().splitlines()
    about = [line for line in lines if line.startswith("#")]
    columns, *body = csv.reader(line for line in lines if not line.startswith("#"))
    units = {"F": "N", "T": "N m", "z": "m", "Fy": "N"}
    assert columns == [
        "slip",
        "slip_angle [deg]",
        *(f"{r}_{q} [{u}]" for r, u in units.items() for q in ("median", "lo", "hi")),
        "n_failed",
    ]
    assert {"# draws: 6", "# seed: 2", "# W: 315 N", "# case: tiny"} <= set(about)
    data = np.array(body, dtype=float)
    assert data.shape == (9, 15)
    assert data[:, :2].tolist() == [[s, a] for s in (-0.5, 0, 0.5) for a in (-60, 0, 60)]
    col = {c.split(" ")[0]: data[:, k] for k, c in enumerate(columns)}
    assert not col["n_failed"].any()
    for r in units:
        assert np.all(col[f"{r}_lo"] <= col[f"{r}_median"])
        assert np.all(col[f"{r}_median"] <= col[f"{r}_hi"])
    straight, plus, minus = (data[:, 1] == a for a in (0, 60, -60))
    for q in ("median", "lo", "hi"):
        assert np.all(col[f"Fy_{q}"][straight] == 0.0)
        for r in ("F", "T", "z"):
            assert col[f"{r}_{q}"][minus] == pytest.approx(col[f"{r}_{q}"][plus], rel=2e-3)
    assert np.all(col["Fy_median"][plus] > 0.0)  # against the slide toward -y
    assert col["Fy_median"][minus] == pytest.approx(-col["Fy_median"][plus], rel=2e-3)
    assert col["Fy_lo"][minus] == pytest.approx(-col["Fy_hi"][plus], rel=2e-3)
    assert col["Fy_hi"][minus] == pytest.approx(-col["Fy_lo"][plus], rel=2e-3)
    # the CSV is predictions.json's map, and that the library's predict on the same grid
    doc = json.loads((out / "predictions.json").read_text())
    assert [p["role"] for p in doc["map"]] == ["map"] * 9
    medians = [p["responses"]["Fy"]["simulated"]["median"] for p in doc["map"]]
    assert col["Fy_median"] == pytest.approx(medians, rel=1e-6, abs=1e-9)
    case, samples, summary = load_results(reference)
    first = summary["datasets"][0]["conditions"]
    template = DatasetTerms("study", dict(first), (np.nan,) * 4)
    grid = map_targets(template, [-0.5, 0.0, 0.5], [-60.0, 0.0, 60.0])
    expected = predict(case, samples, grid, draws=6, seed=2, roles=["map"] * 9)
    for got, want in zip(doc["map"], expected, strict=True):
        for r, band in want.to_dict()["responses"].items():
            assert got["responses"][r]["simulated"] == pytest.approx(band["simulated"], rel=1e-9)


def test_sensitivity_stopped_and_resumed_gives_the_same_screening(work: Path, monkeypatch) -> None:
    """The screening is a study of OUT/study.db run by the service's kind: stopped (Ctrl-C)
    after its first batch, it exits 130 keeping that batch; the same command again runs only
    the other batches and writes the same sensitivity.json as a run never stopped."""
    import worker.here
    from services.cli.folder_store import DB_FILE
    from services.store import Store

    args = ("sensitivity", "tiny.toml", "--r", "2")
    assert run_cli_here(*args, "--out", "sens_ref", cwd=work).returncode == 0
    execute, calls = worker.here.execute_batch, []

    def stopped_after_one(*a, **k):
        if calls:
            raise KeyboardInterrupt
        calls.append(a[1])
        return execute(*a, **k)

    monkeypatch.setattr(worker.here, "execute_batch", stopped_after_one)
    proc = run_cli_here(*args, "--out", "sens_cut", cwd=work)
    assert proc.returncode == 130 and "re-run the same command" in proc.stderr
    assert not (work / "sens_cut" / "sensitivity.json").exists()
    monkeypatch.setattr(worker.here, "execute_batch", execute)
    assert run_cli_here(*args, "--out", "sens_cut", cwd=work).returncode == 0
    ref = json.loads((work / "sens_ref" / "sensitivity.json").read_text())
    assert json.loads((work / "sens_cut" / "sensitivity.json").read_text()) == ref
    with Store.open(f"sqlite:///{work / 'sens_cut' / DB_FILE}") as store:
        (study,) = store.studies.list().items
        done = [e for e in store.events.list(study.id) if e.kind == "batch_done"]
        batches = store.batches.list(study.id, 0)
    assert len(batches) > 1 and len(done) == len(batches)  # none ran twice
    assert all(b.attempts == 1 for b in batches)  # the stop counted no attempt
    # another screening into the same folder is refused, naming the folder
    line = one_line_error(run_cli_here(*args, "--seed", "9", "--out", "sens_cut", cwd=work))
    assert "sens_cut holds a sensitivity study of other inputs" in line


def test_a_folder_in_use_by_another_command_is_refused(work: Path, reference: Path) -> None:
    """One command at a time uses a results folder: while another holds its lock, a command
    on it stops with a one-line error naming the folder, and nothing of it changes."""
    import fcntl

    from services.cli.folder_store import DB_FILE, LOCK_FILE

    before = (reference / DB_FILE).read_bytes()
    with open(reference / LOCK_FILE, "a+b") as held:
        fcntl.flock(held.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        line = one_line_error(run_cli_here("calibrate", "tiny.toml", "--out", "ref", cwd=work))
        assert "--out ref: another scm-calib command is using this folder" in line
        line = one_line_error(run_cli_here("predict", "ref", "--data", "log.csv", cwd=work))
        assert "predict ref: another scm-calib command is using this folder" in line
    assert (reference / DB_FILE).read_bytes() == before


def test_a_batch_that_always_fails_ends_the_study_after_the_attempt_cap(
    work: Path, monkeypatch
) -> None:
    """A batch that raises is given back and tried again, as on the service; at the attempt
    cap the study fails and the command says so in one line (exit 1), no traceback; what the
    folder stored stays."""
    from services.cli.folder_store import DB_FILE
    from services.store import Store
    from services.studies.kinds.sensitivity import SensitivityRun

    def broken(self, store, lease, model_function):
        raise RuntimeError("the simulator is broken")

    monkeypatch.setattr(SensitivityRun, "compute", broken)
    proc = run_cli_here("sensitivity", "tiny.toml", "--r", "2", "--out", "sens_bad", cwd=work)
    line = one_line_error(proc, code=1)
    assert line.startswith("error: the screening ended failed: batch 0 of stage 0")
    assert "RuntimeError: the simulator is broken" in line
    with Store.open(f"sqlite:///{work / 'sens_bad' / DB_FILE}") as store:
        (study,) = store.studies.list().items
        batch = store.batches.list(study.id, 0)[0]
        assert study.status == "failed" and batch.attempts == store.db.max_attempts


def test_a_refused_screening_leaves_no_folder(work: Path) -> None:
    line = one_line_error(
        run_cli_here("sensitivity", "tiny.toml", "--bounds", "K=1:2", "--out", "no/sens", cwd=work)
    )
    assert line.startswith("error: --bounds") and "not screened" in line
    assert not (work / "no").exists()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("predict", "ref", "--at", "W"), "expected KEY=VALUE"),
        (("predict", "ref", "--at", "W=abc,slip=0.2"), "--at"),
        (("predict", "nowhere", "--data", "log.csv"), "no summary.json"),
        (("predict", "ref"), "nothing to predict"),
        (("predict", "ref", "--sweep", "slip=1:2"), "expected slip=LO:HI:N"),
        (("predict", "ref", "--sweep", "slip=-2:0.5:4"), "-1 <= LO < HI < 1"),
        (("predict", "ref", "--sweep", "slip_angle=0:100:4"), "--sweep 'slip_angle=0:100:4'"),
        (("predict", "ref", "--map", "slip=-0.9:0.9:30"), "210 points, over the limit of 200"),
        (("predict", "ref", "--data", "nope.csv"), "dataset nope.csv: no such file"),
    ],
)
def test_predict_bad_inputs_one_line_exit_2(work: Path, reference: Path, args, needle) -> None:
    assert needle in one_line_error(run_cli_here(*args, cwd=work))


def test_synth_writes_log_and_sidecar(work: Path) -> None:
    text = (work / "log.csv").read_text()
    assert "# slip: 0.2" in text and "time [s],drawbar_pull [N]" in text
    side = json.loads((work / "log.json").read_text())
    assert side["true_parameters"]["phi"] == 27.0 and side["seed"] == 3
    assert len(text.splitlines()) > 8 * 50


def test_calibrate_writes_samples_summary_and_figures(reference: Path) -> None:
    summary = json.loads((reference / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["parameters"] == ["phi", "n"]
    n_stages = summary["n_stages"]
    assert n_stages >= 2 and len(summary["stages"]) == n_stages + 1
    for key in (
        "exponent",
        "beta",
        "acceptance_rate",
        "ess",
        "n_unique",
        "failed_runs",
        "model_runs",
        "wall_time_s",
    ):
        assert key in summary["stages"][-1]
    post = summary["posterior"]
    for key in ("mean", "sd", "credible_interval_95", "map"):
        assert set(post[key]) == {"phi", "n"}
    assert set(post["quantiles"]) == {"0.025", "0.25", "0.5", "0.75", "0.975"}
    assert post["correlation"]["names"] == ["phi", "n"]
    assert isinstance(summary["log_evidence"], float)
    assert isinstance(summary["log_evidence_se"], float)
    # beside the reported error (the genealogy estimate), the stage-wise sum
    assert isinstance(summary["log_evidence_se_stagewise"], float)
    assert summary["log_evidence_se_stagewise"] > 0.0
    assert summary["datasets"][0]["content_hash"] and summary["wall_time_s"] > 0
    assert summary["settings"]["n_samples"] == 60 and summary["settings"]["tmcmc"]["moves"] == (
        "leader"
    )
    assert summary["map_responses"]["log"]["status"] == "ok"
    header = (reference / "posterior.csv").read_text().splitlines()[0]
    assert header == "phi,n,log_likelihood,log_prior,F[log],T[log],z[log],Fy[log]"
    assert len((reference / "samples" / "stage_00.csv").read_text().splitlines()) == 61
    assert len(list((reference / "samples").glob("stage_*.csv"))) == n_stages + 1
    for fig in ("prior_posterior.png", "posterior_pairs.png", "fit_map.png"):
        assert (reference / "figures" / fig).stat().st_size > 10_000
    # the stages are kept once, in the folder's database
    assert not (reference / "checkpoints").exists()
    assert len(folder_states(reference)) == n_stages + 1


def test_workers_give_identical_results(work: Path, reference: Path) -> None:
    proc = run_cli(
        "calibrate", "tiny.toml", "--out", "w2", "--workers", "2", "--quiet", "--no-plots", cwd=work
    )
    assert proc.returncode == 0, proc.stderr
    assert stage_files(work / "w2") == stage_files(reference)


def test_stopped_then_continued_is_identical(work: Path, reference: Path) -> None:
    proc = run_cli(
        "calibrate",
        "tiny.toml",
        "--out",
        "part",
        "--max-stages",
        "2",
        "--quiet",
        "--no-plots",
        cwd=work,
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((work / "part" / "summary.json").read_text())
    assert summary["status"] == "max_stages" and summary["n_stages"] == 2
    proc = run_cli("calibrate", "tiny.toml", "--out", "part", "--quiet", "--no-plots", cwd=work)
    assert proc.returncode == 0, proc.stderr
    assert stage_files(work / "part") == stage_files(reference)


def test_a_folder_from_before_study_databases_is_taken_over_not_rerun(
    work: Path, reference: Path
) -> None:
    """A results folder whose stages are only checkpoint files (written before a folder held
    its study's database), stopped after stage 2: the new database takes the stages over
    without running them, the run goes on to the reference's stages bit for bit, and writes
    no checkpoint file of its own."""
    from services.cli.folder_store import DB_FILE
    from services.store import Store

    out = as_older_folder(reference, work / "legacy", work, stages=3)
    proc = run_cli("calibrate", "tiny.toml", "--out", out, "--no-plots", cwd=work)
    assert proc.returncode == 0, proc.stderr
    assert "taking over stages 0-2" in proc.stderr
    assert stage_files(out) == stage_files(reference)
    assert len(list((out / "checkpoints").glob("stage_*.json"))) == 3  # none written
    with Store.open(f"sqlite:///{out / DB_FILE}") as store:
        (study,) = store.studies.list().items
        rows = store.stages.list(study.id)
    assert [r.n_batches for r in rows[:3]] == [0, 0, 0]  # taken over, not run
    assert all(r.n_batches > 0 for r in rows[3:])
    summary = json.loads((reference / "summary.json").read_text())
    assert study.model_runs == summary["model_runs"]
    again = run_cli("predict", out, "--data", "log.csv", "--draws", "3", "--no-plots", cwd=work)
    assert again.returncode == 0, again.stderr


def test_checkpoints_of_another_study_are_refused(work: Path, reference: Path) -> None:
    """A folder from before study databases whose checkpoints are another study's."""
    out = as_older_folder(reference, work / "legacy_other", work)
    proc = run_cli("calibrate", "tiny.toml", "--out", out, "--samples", "70", cwd=work)
    line = one_line_error(proc)
    assert "holds checkpoints of another study" in line and "the case" in line


def test_a_folder_of_another_study_is_refused(work: Path, reference: Path) -> None:
    proc = run_cli("calibrate", "tiny.toml", "--out", "ref", "--samples", "70", cwd=work)
    line = one_line_error(proc)
    assert "holds a calibration of other inputs" in line and "study.db" in line


def test_ctrl_c_then_rerun_resumes_identically(work: Path, reference: Path) -> None:
    args = [
        sys.executable,
        "-m",
        "services.cli",
        "calibrate",
        "tiny.toml",
        "--out",
        "intr",
        "--quiet",
        "--no-plots",
    ]
    proc = subprocess.Popen(
        args, cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    deadline = time.monotonic() + 300
    while done_stages(work / "intr") < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("interrupted: stages 0-"), err
    assert "re-run the same command to resume" in lines[0]
    done = run_cli(*args[3:], cwd=work)
    assert done.returncode == 0, done.stderr
    assert stage_files(work / "intr") == stage_files(reference)


def _children(pid: int) -> list[int]:
    """The child processes of ``pid`` (Linux /proc)."""
    kids: list[int] = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        kids += [int(k) for k in (task / "children").read_text().split()]
    return kids


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.slow  # fault injection (CI's slow tier, with the other killed-process tests)
def test_a_killed_worker_is_replaced_and_the_run_ends_the_same(work: Path, reference: Path) -> None:
    """A --workers process killed mid-run (a signal, the kernel's out-of-memory killer) is
    replaced and its batch given back at once (the embedded server's supervised pool): the
    run goes on to the same stages bit for bit, says so in a warning, and gives no
    traceback."""
    args = ["calibrate", "tiny.toml", "--out", "killed", "--workers", "2", "--quiet", "--no-plots"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "services.cli", *args],
        cwd=work,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 300
    while done_stages(work / "killed") < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    workers = [k for k in _children(proc.pid) if "spawn_main" in _cmdline(k)]
    assert workers, "no worker process found"
    os.kill(workers[0], signal.SIGKILL)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert "Traceback" not in err, err
    assert "died (killed by SIGKILL)" in err and "replacing it" in err, err
    assert stage_files(work / "killed") == stage_files(reference)


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def test_sensitivity_writes_json_and_figure(work: Path) -> None:
    proc = run_cli("sensitivity", "tiny.toml", "--r", "4", "--out", "sens", cwd=work)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((work / "sens" / "sensitivity.json").read_text())
    names = [f["name"] for f in doc["factors"]]
    assert names == ["k_star", "n", "c", "phi", "D_soil", "J"] and doc["joint_k"] is True
    assert doc["n_runs"] == 4 * 7
    for resp in ("F", "T", "z"):
        assert set(doc["linear_index"][resp]) == set(names)
        total = sum(v for v in doc["linear_index"][resp].values() if v is not None)
        assert total == pytest.approx(1.0)
    # the case's prior bounds are used for calibrated factors, defaults for the others
    bounds = {f["name"]: (f["lower"], f["upper"]) for f in doc["factors"]}
    assert bounds["phi"] == (11.5, 37.3) and bounds["D_soil"] == (0.0, 1.0e6)
    assert (work / "sens" / "sensitivity.png").stat().st_size > 10_000


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["calibrate", "missing.toml"], "cannot read case file missing.toml"),
        (["calibrate", "bad.toml"], "bad.toml: case file is not valid TOML"),
        (["calibrate", "unknown.toml"], "parameters.k_phy: unknown parameter 'k_phy'"),
        (["calibrate", "nodata.toml"], "no datasets"),
        (["calibrate", "tiny.toml", "--data", "nope.csv"], "dataset nope.csv: no such file"),
        (["calibrate", "tiny.toml", "--data", "garbage.csv"], "garbage.csv: "),
        (["calibrate", "tiny.toml", "--samples", "3"], "--samples"),
        (["sensitivity", "tiny.toml", "--levels", "3"], "--levels must be even"),
        (["sensitivity", "tiny.toml", "--bounds", "c=1"], "--bounds: expected NAME=LOWER:UPPER"),
        (["sensitivity", "tiny.toml", "--bounds", "K=1:2"], "not screened"),
        (["synth", "--set", "phi=95", "--out", "x.csv"], "phi"),
        (["synth", "--out", "x.csv", "--duration", "-1"], "duration"),
    ],
)
def test_bad_inputs_one_line_exit_2(work: Path, args: list[str], needle: str) -> None:
    (work / "bad.toml").write_text('name = "x"\n[parameters\n')
    (work / "unknown.toml").write_text(CASE.replace("\nn = {", "\nk_phy = {"))
    (work / "nodata.toml").write_text(CASE.replace('files = ["log.csv"]', "files = []"))
    (work / "garbage.csv").write_text("this is not, a log\n1,2\n")
    line = one_line_error(run_cli_here(*args, cwd=work))
    assert line.startswith("error: ") and needle in line, line


@pytest.mark.parametrize(
    "args",
    [
        ["calibrate", "missing.toml"],
        ["calibrate", "tiny.toml", "--data", "nope.csv"],
        ["sensitivity", "tiny.toml", "--levels", "3"],
    ],
)
def test_the_entry_point_gives_the_in_process_error_lines(work: Path, args: list[str]) -> None:
    """``python -m services.cli`` (the installed ``scm-calib``) gives the same one-line error
    and exit code as the in-process runs of the tests above."""
    here = one_line_error(run_cli_here(*args, cwd=work))
    assert one_line_error(run_cli(*args, cwd=work)) == here


@pytest.fixture(scope="module")
def second_log(work: Path) -> Path:
    """A second synthetic log of the same soil at slip 0.5 (the new test of an update)."""
    proc = run_cli(
        *("synth", "--set", "phi=27", "--set", "J=0.004", "--set", "slip=0.5"),
        *("--set", "dx=0.015", "--set", "dt=0.05", "--duration", "8", "--ramp", "1"),
        *("--seed", "5", "--out", "log50.csv"),
        cwd=work,
    )
    assert proc.returncode == 0, proc.stderr
    return work / "log50.csv"


def test_update_is_the_in_memory_update_bit_for_bit(
    work: Path, reference: Path, second_log: Path
) -> None:
    """``--update-of ref --data log50.csv``: stage 0 is ref's final population, the slip 0.2
    likelihood is the base density, the seed is ref's + 1; the samples are those of
    ``run_tmcmc(UpdateLikelihood(...), start=PopulationStart(...))`` bit for bit, the evidence
    reported is the increment with the total alongside, stage 1 starts with ref's final beta and
    acceptance rate, and a re-run resumes to the same files."""
    import numpy as np

    from scm_core.calibration import (
        PopulationStart,
        StudyModel,
        UpdateLikelihood,
        load_case,
        run_tmcmc,
    )
    from scm_core.signals import load_dataset

    proc = run_cli("calibrate", "--update-of", "ref", "--data", "log50.csv", "--no-plots", cwd=work)
    assert proc.returncode == 0, proc.stderr
    out = work / "ref_update"
    summary = json.loads((out / "summary.json").read_text())
    parent = json.loads((reference / "summary.json").read_text())
    assert summary["case"]["seed"] == parent["case"]["seed"] + 1
    assert [d["path"] for d in summary["datasets"]] == [
        str((work / "log.csv").resolve()),
        str(second_log.resolve()),
    ]
    upd = summary["update"]
    assert upd["parent_log_evidence"] == parent["log_evidence"]
    assert upd["log_evidence_increment"] == summary["log_evidence"]
    assert upd["log_evidence_total"] == pytest.approx(
        parent["log_evidence"] + summary["log_evidence"], abs=1e-12
    )

    case = load_case(work / "tiny.toml").with_changes(seed=5)
    data = [load_dataset(work / f, offset=case.data.offset) for f in ("log.csv", "log50.csv")]
    parent_final = folder_states(reference)[-1]
    expected = run_tmcmc(
        UpdateLikelihood(StudyModel(case, data), 1),
        case.prior(),
        case.sampler.n_samples,
        5,
        case.tmcmc_settings(),
        start=PopulationStart(
            parent_final.samples, (parent_final.beta, parent_final.acceptance_rate)
        ),
    )
    stages = folder_states(out)
    final = stages[-1]
    assert final.samples.tobytes() == expected.samples.tobytes()
    stage0 = stages[0]
    assert np.array_equal(stage0.samples, parent_final.samples)
    # stage 0 ran the new log only (the old one's responses there are ref's own), once per
    # distinct point of ref's population (a rejected move repeats a state)
    distinct = len(np.unique(parent_final.samples, axis=0))
    assert stage0.part_runs == stage0.model_runs == distinct
    assert expected.stages[0].part_runs == 2 * distinct
    before = stage_files(out)
    again = run_cli(
        "calibrate", "--update-of", "ref", "--data", "log50.csv", "--no-plots", cwd=work
    )
    assert again.returncode == 0, again.stderr
    assert "resuming" in again.stderr and stage_files(out) == before


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["calibrate"], "missing CASE_FILE"),
        (["calibrate", "tiny.toml", "--update-of", "ref", "--data", "log50.csv"], "no CASE_FILE"),
        (["calibrate", "--update-of", "ref"], "needs the new datasets"),
        (["calibrate", "--update-of", "ref", "--data", "log.csv"], "already in the posterior"),
        (["calibrate", "--update-of", "nowhere", "--data", "log50.csv"], "no summary.json"),
        (
            ["calibrate", "--update-of", "ref", "--data", "log50.csv", "--samples", "20"],
            "--moves and --samples",
        ),
        (
            ["calibrate", "--update-of", "ref", "--data", "log50.csv", "--seed", "9"],
            "drop --seed",
        ),
    ],
)
def test_bad_update_inputs_one_line_exit_2(
    work: Path, reference: Path, second_log: Path, args: list[str], needle: str
) -> None:
    line = one_line_error(run_cli_here(*args, cwd=work))
    assert line.startswith("error: ") and needle in line, line


def _refuse_nonfinite(token: str) -> float:
    raise ValueError(f"non-standard JSON constant {token}")


@pytest.mark.slow  # every file of a whole CLI session (CI's slow tier)
def test_every_json_file_the_cli_wrote_is_strict_json(work: Path, reference: Path) -> None:
    """Exported stages, their manifest, summary, predictions and sensitivity are strict JSON
    (no NaN or Infinity tokens): they go through ``scm_core.jsondoc.dumps``, json.dumps with
    allow_nan=False and no encoder, so a non-JSON value fails where it is written. The stages
    exported are the database's bit for bit."""
    from scm_core.inference import StageState

    assert run_cli("predict", "ref", "--data", "log.csv", "--draws", "4", cwd=work).returncode == 0
    assert (
        run_cli("sensitivity", "tiny.toml", "--r", "2", "--out", "sens2", cwd=work).returncode == 0
    )
    exported = run_cli("export", "ref", "--to", "stages", "--out", "ref_stages", cwd=work)
    assert exported.returncode == 0, exported.stderr
    files = [
        *sorted((work / "ref_stages").glob("*.json")),
        reference / "summary.json",
        reference / "predictions" / "predictions.json",
        work / "sens2" / "sensitivity.json",
    ]
    assert len(files) >= 5
    for path in files:
        doc = json.loads(path.read_text(encoding="utf-8"), parse_constant=_refuse_nonfinite)
        assert isinstance(doc, dict), path
    stages = sorted((work / "ref_stages").glob("stage_*.json"))
    assert len(stages) == len(folder_states(reference))
    state = json.loads(stages[-1].read_text())
    assert isinstance(state["state"]["samples"], dict)  # an encoded array, not a raw list
    for path, kept in zip(stages, folder_states(reference), strict=True):
        again = StageState.from_dict(json.loads(path.read_text())["state"])
        assert again.samples.tobytes() == kept.samples.tobytes()
        assert again.log_evidence == kept.log_evidence
    refused = run_cli("export", "ref", "--to", "stages", "--out", "ref_stages", cwd=work)
    assert "holds stage files already" in one_line_error(refused)


@pytest.mark.slow
def test_first_run_says_it_compiles_the_simulator(work: Path, tmp_path: Path) -> None:
    """A fresh install (an empty numba cache) is told once that the simulator compiles
    (about 20 s, silent otherwise); the next run loads it from the cache and says nothing."""
    env = {
        **os.environ,
        "PYTHONPATH": str(Path(__file__).resolve().parents[2]),
        "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
    }

    def calibrate(out: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "services.cli", "calibrate", "tiny.toml",
             "--out", str(tmp_path / out), "--max-stages", "1", "--samples", "24", "--no-plots"],
            capture_output=True, text=True, cwd=work, timeout=600, env=env,
        )  # fmt: skip

    first = calibrate("first")
    assert first.returncode == 0, first.stderr
    assert "compiling the simulator, first run only" in first.stderr
    assert "simulator compiled in" in first.stderr
    second = calibrate("second")
    assert second.returncode == 0, second.stderr
    assert "compiling the simulator" not in second.stderr


def test_a_stopped_run_says_it_is_not_a_posterior(work: Path, reference: Path) -> None:
    """--max-stages 1 ends before the posterior: the table, a stderr warning and summary.json
    say so (the tempering exponent is below one)."""
    proc = run_cli(
        "calibrate", "tiny.toml", "--out", "stop1", "--max-stages", "1", "--no-plots", cwd=work
    )
    assert proc.returncode == 0, proc.stderr
    assert "NOT A POSTERIOR" in proc.stdout
    warning = [line for line in proc.stderr.splitlines() if line.startswith("warning:")]
    assert len(warning) == 1 and "--max-stages" in warning[0], proc.stderr
    summary = json.loads((work / "stop1" / "summary.json").read_text())
    assert summary["status"] == "max_stages" and summary["is_posterior"] is False
    assert 0.0 < summary["final_exponent"] < 1.0
    done = json.loads((reference / "summary.json").read_text())
    assert done["is_posterior"] is True and done["final_exponent"] == 1.0


@pytest.mark.slow  # a second calibration of the reference case (CI's slow tier)
def test_seed_option_overrides_the_case_seed(work: Path, reference: Path) -> None:
    """--seed 4 is the case's own seed: the same bits (its first stages); another seed gives
    another population, recorded in the summary's case."""
    same = run_cli(
        "calibrate", "tiny.toml", "--out", "s4", "--seed", "4", "--max-stages", "1", "--quiet",
        "--no-plots", cwd=work,
    )  # fmt: skip
    assert same.returncode == 0, same.stderr
    for stage in ("stage_00.csv", "stage_01.csv"):
        assert (work / "s4" / "samples" / stage).read_bytes() == (
            reference / "samples" / stage
        ).read_bytes()
    other = run_cli(
        "calibrate", "tiny.toml", "--out", "s5", "--seed", "5", "--max-stages", "1", "--quiet",
        "--no-plots", cwd=work,
    )  # fmt: skip
    assert other.returncode == 0, other.stderr
    assert json.loads((work / "s5" / "summary.json").read_text())["case"]["seed"] == 5
    stage0 = (work / "s5" / "samples" / "stage_00.csv").read_bytes()
    assert stage0 != (reference / "samples" / "stage_00.csv").read_bytes()
    bad = run_cli("calibrate", "tiny.toml", "--seed", "-1", cwd=work)
    assert bad.returncode == 2 and "--seed" in bad.stderr


def test_runs_give_a_verdict_and_a_pooled_posterior(work: Path, reference: Path) -> None:
    """--runs 2: run_1 is the case's own seed (the same bits as a plain run), run_2 the next
    seed; runs.json's R-hat is what `diagnose` prints for the same folders; the pooled file is
    the runs' posteriors one after the other."""
    proc = run_cli("calibrate", "tiny.toml", "--runs", "2", "--out", "grp", "--no-plots", cwd=work)
    assert proc.returncode == 0, proc.stderr
    assert "Warning" not in proc.stderr, proc.stderr  # no dependency's notice (issue 69)
    grp = work / "grp"
    assert stage_files(grp / "run_1") == stage_files(reference)
    assert json.loads((grp / "run_2" / "summary.json").read_text())["case"]["seed"] == 5
    doc = json.loads((grp / "runs.json").read_text())
    assert doc["runs"] == 2 and set(doc["parameters"]) == {"phi", "n"}
    assert doc["verdict"] in proc.stdout.replace("\n", " ") or doc["verdict"][:40] in proc.stdout
    assert doc["converged"] == all(p["rhat"] <= 1.01 for p in doc["parameters"].values())
    pooled = (grp / "posterior_pooled.csv").read_text().splitlines()
    runs = [(grp / f"run_{k}" / "posterior.csv").read_text().splitlines() for k in (1, 2)]
    assert pooled[0] == "run," + runs[0][0]
    assert pooled[1:] == [
        f"{k},{row}" for k, rows in ((1, runs[0]), (2, runs[1])) for row in rows[1:]
    ]
    again = run_cli("diagnose", reference, grp / "run_2", "--out", "diag", cwd=work)
    assert again.returncode == (0 if doc["converged"] else 1), again.stderr
    redone = json.loads((work / "diag" / "runs.json").read_text())
    assert redone["parameters"] == doc["parameters"] and redone["verdict"] == doc["verdict"]
    # the group as ArviZ InferenceData: one chain per run, exactly the runs' posteriors
    export = run_cli("export", "grp", "--out", "grp.nc", cwd=work)
    assert export.returncode == 0, export.stderr
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz as az

        idata = az.from_netcdf(str(work / "grp.nc"))
        rhat = az.rhat(idata)
    assert idata.posterior.sizes["chain"] == 2
    for k in (0, 1):
        rows = [r.split(",") for r in runs[k][1:]]
        for name in ("phi", "n"):
            col = runs[k][0].split(",").index(name)
            expected = np.array([float(r[col]) for r in rows])
            assert np.array_equal(idata.posterior[name].values[k], expected)
            assert float(rhat[name]) == pytest.approx(doc["parameters"][name]["rhat"], rel=1e-12)
    assert idata.posterior.attrs["verdict"] == doc["verdict"]
    # issue 69: every command that takes a results folder takes the group: diagnose its runs,
    # the Chrono export of the pooled posterior (median, and the MAP of all runs' samples);
    # predict says in one line which folder it wants
    diag = run_cli_here("diagnose", "grp", cwd=work)
    assert diag.returncode == (0 if doc["converged"] else 1), diag.stderr
    assert doc["verdict"][:40] in diag.stdout.replace("\n", " ")
    chrono = run_cli_here("export", "grp", "--to", "chrono", "--lossy", "--out", "g.json", cwd=work)
    assert chrono.returncode == 0, chrono.stderr
    soil = json.loads((work / "g.json").read_text())
    assert soil["study"]["status"] == "completed, 2 runs pooled"
    header = runs[0][0].split(",")
    rows = [[float(v) for v in r.split(",")] for k in (0, 1) for r in runs[k][1:]]
    post = [r[header.index("log_likelihood")] + r[header.index("log_prior")] for r in rows]
    best = rows[int(np.argmax(post))]
    n_col = header.index("n")
    assert soil["sets"]["MAP"]["Bekker_n"] == pytest.approx(best[n_col], rel=1e-12)
    median_n = float(np.median([r[n_col] for r in rows]))
    assert soil["sets"]["posterior median"]["Bekker_n"] == pytest.approx(median_n, rel=1e-12)
    # an update starts from one study: the group's folder is refused in one line naming a run
    upd = run_cli_here("calibrate", "--update-of", "grp", "--data", "log.csv", cwd=work)
    wants = one_line_error(upd)
    assert "a group of runs" in wants and str(Path("grp") / "run_1") in wants
    # a re-run finds every run finished and gives the same verdict
    rerun = run_cli("calibrate", "tiny.toml", "--runs", "2", "--out", "grp", "--no-plots", cwd=work)
    assert rerun.returncode == 0, rerun.stderr
    assert json.loads((grp / "runs.json").read_text())["parameters"] == doc["parameters"]


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["diagnose", "ref"], "at least two runs"),
        (["diagnose", "ref", "ref"], "the same seed"),
        (["diagnose", "ref", "nowhere"], "nowhere"),
        (["calibrate", "--update-of", "ref", "--data", "log.csv", "--runs", "2"], "--runs"),
        (["calibrate", "tiny.toml", "--runs", "0"], "--runs"),
    ],
)
def test_bad_run_group_inputs_one_line_exit_2(
    work: Path, reference: Path, args: list[str], needle: str
) -> None:
    assert needle in one_line_error(run_cli_here(*args, cwd=work))
