"""The lateral force Fy (issue 70) as lab files carry it: a column ``lateral_force`` [N] (short
name ``Fy``, also ``side_force``) in logs and summaries, positive against the side slip as the
CMU data's README has it; refused without its unit, naming the field; a file that carries no
lateral force hashes as it did before the column existed (values pinned with the code before
it); a lateral force without a slip angle is read at 0 deg, and ``check`` says so."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from scm_core.signals import LogFormatError, load_dataset, load_log, load_summary, write_log
from scm_core.signals.checks import dataset_warnings
from services.cli.check import check

ROOT = Path(__file__).resolve().parents[2]
#: the CMU smooth wheel locked at 30 deg (examples/cmu_steering/smooth/by_condition.csv)
META = "# slip_angle: 30 deg\n# normal_load: 20.6 N\n# slip: -1\n# slip_convention: symmetric\n"


def _log(header: str, fy_cell: str = "26.59", n: int = 600) -> str:
    rows = "\n".join(f"{0.1 * i:.6g},-38.86,{fy_cell},0.0533" for i in range(n))
    return META + header + "\n" + rows + "\n"


@pytest.mark.parametrize(
    ("name", "unit", "scale"),
    [("lateral_force", "N", 1.0), ("Fy", "kN", 1000.0), ("side_force", "N", 1.0), ("FY", "N", 1.0)],
)
def test_a_log_carries_the_lateral_force_by_any_of_its_names(name, unit, scale) -> None:
    cell = f"{26.59 / scale:.8g}"
    text = _log(f"time [s],drawbar_pull [N],{name} [{unit}],sinkage [m]", cell)
    ds = load_log(text.encode(), offset=10.0)
    assert set(ds.responses) == {"F", "z", "Fy"}
    assert ds.means["Fy"] == pytest.approx(26.59, rel=1e-9)
    assert ds.conditions.slip_angle == 30.0
    assert "lateral_force" in ds.series.raw


def test_a_log_of_the_lateral_force_alone_is_a_log() -> None:
    text = _log("time [s],drawbar [N],Fy [N],z [m]").replace("drawbar [N]", "note")
    ds = load_log(text.encode(), offset=10.0)
    assert set(ds.responses) == {"Fy", "z"}


@pytest.mark.parametrize("field", ["lateral_force", "Fy", "side_force"])
def test_a_lateral_force_column_without_a_unit_is_refused_naming_it(field) -> None:
    text = _log(f"time [s],drawbar_pull [N],{field},sinkage [m]")
    with pytest.raises(LogFormatError) as info:
        load_log(text.encode(), offset=10.0)
    message = str(info.value)
    assert f"column '{field}' (column 3" in message and "lateral_force" in message
    assert "has no unit in brackets" in message and f"'{field} [N]'" in message


def test_summaries_carry_the_lateral_force_and_refuse_it_without_a_unit() -> None:
    per_response = (
        META + "# n_trials: 3\nresponse,mean,sd,unit\nF,-38.86,0.57,N\nFy,26.59,0.8,N\n"
        "z,53.3,0.7,mm\n"
    )
    ds = load_summary(per_response.encode())
    assert ds.means["Fy"] == pytest.approx(26.59) and ds.standard_errors["Fy"] == pytest.approx(
        0.8 / np.sqrt(3)
    )
    per_trial = META + "trial,drawbar_pull [N],side_force [kN],sinkage [mm]\n"
    per_trial += "1,-38.3,0.0262,52.9\n2,-39.4,0.0270,53.7\n"
    ds = load_summary(per_trial.encode())
    assert ds.means["Fy"] == pytest.approx(26.6, rel=1e-12) and ds.n_trials == 2
    doc = {
        "conditions": {"slip_angle": 30, "normal_load": "20.6 N", "slip": 0.2},
        "responses": {"lateral_force": {"mean": 12.0, "sd": 1.0, "unit": "N"}},
        "n_trials": 3,
    }
    assert load_summary(json.dumps(doc).encode()).means == {"Fy": 12.0}
    # without the unit: refused naming the field, in each of the three spellings
    doc["responses"] = {"Fy": {"mean": 12.0, "sd": 1.0}}
    bad = [
        json.dumps(doc),
        per_response.replace("Fy,26.59,0.8,N", "Fy,26.59,0.8,"),
        per_trial.replace("side_force [kN]", "side_force"),
    ]
    for text in bad:
        with pytest.raises(LogFormatError, match=r"lateral_force.*(has )?no unit"):
            load_summary(text.encode())
    # the others keep their SI default
    assert load_summary(per_response.replace("F,-38.86,0.57,N", "F,-38.86,0.57,").encode())


def test_write_log_writes_the_lateral_force_that_load_log_reads(tmp_path) -> None:
    t = np.arange(0, 60, 0.1)
    fy = 13.0 + 0.1 * np.sin(t)
    path = write_log(
        tmp_path / "steered.csv",
        t,
        -5.0 + 0 * t,
        1.0 + 0 * t,
        0.02 + 0 * t,
        {"W": 20.0, "slip": 0.2, "slip_angle": 45.0},
        Fy=fy,
        units={"lateral_force": "kN"},
    )
    header = next(line for line in path.read_text().splitlines() if line.startswith("time"))
    assert "lateral_force [kN]" in header.split(",")
    ds = load_log(path, offset=20.0)
    assert ds.means["Fy"] == pytest.approx(float(np.mean(fy[t >= 20.0])), abs=0.02)


#: content hashes of straight lab files computed with the code before the lateral force
#: column was declared (a stored dataset is found again by its hash when re-uploaded)
PINNED = {
    "examples/cmu_smooth/cmu_smooth_sp050.csv": (
        "c06047578b31afa3e98d57a37d87f68ee82e601f84b2db224b177ef9022b95eb"
    ),
    "examples/cmu_grouser/cmu_grouser_sm050.csv": (
        "9daaea607ace4f857e8e2de2d016c09ec95aa960ddb3d9b6b9494a8d50a31d2d"
    ),
    "examples/wf34_s020.csv": "758ff4db28e12c222b256aa06a29040529b89595d6fbeb71eb6b6161301add5e",
}


@pytest.mark.parametrize("path", sorted(PINNED))
def test_a_straight_lab_file_hashes_as_before(path) -> None:
    assert load_dataset(ROOT / path).content_hash == PINNED[path]


def test_a_straight_summary_hashes_as_before() -> None:
    doc = {
        "name": "run 7",
        "conditions": {"slip": 0.2, "normal_load": "315 N", "soil": "WF34"},
        "responses": {
            "F": {"mean": 20.1, "sd": 1.2, "unit": "N"},
            "T": {"mean": 5.3, "sd": 0.4, "unit": "Nm"},
            "z": {"mean": 12.0, "sd": 1.0, "unit": "mm"},
        },
        "n_trials": 3,
    }
    assert load_summary(json.dumps(doc).encode()).content_hash == (
        "53c3d50288d17b0a8c6263ce203d4009015ebc3e16bb2a9bf970db57038fdcde"
    )


def test_a_lateral_force_without_a_slip_angle_reads_at_0_deg_and_check_says_so(
    tmp_path,
) -> None:
    text = _log("time [s],drawbar_pull [N],Fy [N],sinkage [m]")
    text = text.replace("# slip_angle: 30 deg\n", "")
    path = tmp_path / "no_angle.csv"
    path.write_text(text)
    ds = load_log(path, offset=10.0)
    assert ds.conditions.slip_angle is None  # straight: the simulator runs it at 0 deg
    assert "slip_angle" not in ds.conditions.to_sim_config()
    (warning,) = dataset_warnings(ds, str(path))
    assert "lateral force (Fy)" in warning and "slip_angle" in warning and "0 deg" in warning
    res = CliRunner().invoke(check, ["--json", str(path)])
    doc = json.loads(res.output)
    assert res.exit_code == 0 and doc["warnings"] == [warning]
    assert doc["datasets"][0]["responses"]["Fy"]["mean"] == pytest.approx(26.59)
    # with the angle, no such warning; and the table shows the lateral force's column
    steered = tmp_path / "steered.csv"
    steered.write_text(_log("time [s],drawbar_pull [N],Fy [N],sinkage [m]"))
    assert dataset_warnings(load_log(steered, offset=10.0), "x") == []
    table = CliRunner().invoke(check, [str(steered)]).output
    assert "Fy [N]" in table and "26.59" in table


def test_a_straight_files_check_table_has_no_lateral_force_column() -> None:
    out = CliRunner().invoke(check, [str(ROOT / "examples" / "wf34_s020.csv")]).output
    assert "F [N]" in out and "z [mm]" in out and "Fy" not in out
