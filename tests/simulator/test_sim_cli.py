"""``scm-calib simulate``: JSON output, files, and one-line errors with exit code 2."""

import json
import subprocess
import sys

import pytest


def run_cli(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "services.cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


def test_simulate_json_files(tmp_path):
    out, fig = tmp_path / "series.csv", tmp_path / "fig.png"
    proc = run_cli(
        "simulate",
        "--set",
        "duration=25",
        "--set",
        "phi=28",
        "--json",
        "--out",
        str(out),
        "--plot",
        str(fig),
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["status"] == "ok"
    for key in ("F_mean", "T_mean", "z_mean", "wall_time_s"):
        assert isinstance(data[key], float)
    assert data["config"]["soil"]["phi"] == 28.0
    header = out.read_text().splitlines()[0]
    assert header.startswith("time [s],drawbar_pull [N],torque [Nm],sinkage [m]")
    assert fig.stat().st_size > 10_000


@pytest.mark.parametrize(
    ("arg", "needle"),
    [
        ("bogus=1", "unknown key 'bogus'"),
        ("dt=abc", "dt=abc"),
        ("offset_F=60", "averaging offset"),
        ("slip=-0.5", "slip_convention"),
        ("carriage_speed=0", "carriage_speed"),
        ("border_taper=maybe", "border_taper"),
        ("n_grousers=2.5", "n_grousers"),
        ("novalue", "KEY=VALUE"),
    ],
)
def test_bad_overrides_one_line_exit_2(arg, needle):
    proc = run_cli("simulate", "--set", arg)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0]
    assert "Traceback" not in proc.stderr
