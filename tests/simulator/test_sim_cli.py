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
    parts = data["force_budget"]  # where F comes from: the parts add up to it
    assert sum(parts[k] for k in ("F_normal", "F_shear", "F_cap", "F_heap")) == pytest.approx(
        data["F_mean"], abs=1e-9
    )
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


def test_the_swt_figure_states_its_units_and_test_conditions():
    """Issue 69: the means in swt.png's legends carry their units and the title the test
    conditions and the wheel (it said "mean 126" under "SCM single-wheel test (ok)")."""
    from scm_core.simulator import RigConfig, WheelGeometry, simulate_swt
    from services.plots.swt import swt_figure

    result = simulate_swt(rig=RigConfig(duration=4.0, dt=0.02, offset_F=2.0, offset_T=2.0))
    fig = swt_figure(result, wheel=WheelGeometry())
    title = fig.axes[0].get_title()
    assert "slip 0.2, W 315 N" in title and "wheel R 125 mm, b 112 mm, 12 grousers" in title
    texts = [t.get_text() for ax in fig.axes for t in ax.get_legend().get_texts()]
    means = [t for t in texts if "mean" in t]
    assert [m.rsplit(" ", 1)[-1] for m in means] == ["N", "m", "mm"]  # N, N m, mm
    assert means[1].endswith(" N m")
    assert float(means[0].split()[1]) == pytest.approx(result.means.F, rel=1e-3)
