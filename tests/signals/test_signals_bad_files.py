"""Bad SWT logs and summaries are refused with one-line messages naming line, column, unit."""

import json

import pytest

from scm_core.signals import LogFormatError, load_dataset, load_log, load_summary

HEADER = "time [s],drawbar_pull [N],torque [Nm],sinkage [mm]"
META = "# slip: 0.2\n# normal_load: 315 N\n"
FIRST_DATA_LINE = 4  # two metadata lines, header on line 3


def rows(n: int = 600, dt: float = 0.1) -> list[str]:
    return [f"{i * dt:.6g},{20 + 0.1 * (i % 7)},{5.0},{12.0}" for i in range(n)]


def log_text(lines: list[str] | None = None, header: str = HEADER, meta: str = META) -> str:
    return meta + header + "\n" + "\n".join(rows() if lines is None else lines) + "\n"


def with_row(line_no: int, text: str) -> str:
    data = rows()
    data[line_no - FIRST_DATA_LINE] = text
    return log_text(data)


def refuse(tmp_path, text: str | bytes, **kwargs) -> str:
    path = tmp_path / "bad.csv"
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    with pytest.raises(LogFormatError) as info:
        load_log(path, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("bad.csv: ")
    return message


def test_error_is_value_error():
    assert issubclass(LogFormatError, ValueError)


@pytest.mark.parametrize("text", ["", "\n\n", "# slip: 0.2\n# normal_load: 315\n"])
def test_empty_file(tmp_path, text):
    assert "empty file" in refuse(tmp_path, text)


def test_header_without_rows(tmp_path):
    assert "no data rows after the header (line 3)" in refuse(tmp_path, META + HEADER + "\n")


def test_missing_time_column_is_named(tmp_path):
    text = log_text([r.split(",", 1)[1] for r in rows()], header=HEADER.split(",", 1)[1])
    msg = refuse(tmp_path, text)
    assert "missing required column(s) time" in msg
    assert "line 3" in msg


def test_log_without_any_response_is_refused_naming_the_header(tmp_path):
    header = HEADER.replace("drawbar_pull", "drawbr").replace("torque", "torqe")
    header = header.replace("sinkage", "sinkge")
    msg = refuse(tmp_path, log_text(header=header))
    assert "missing required column(s) drawbar_pull, torque, sinkage or lateral_force" in msg
    assert "torqe [Nm]" in msg


def test_log_without_torque_has_the_other_responses(tmp_path):
    """A log may carry any subset of F, T, z: no torque column, no torque response."""
    data = [",".join(r.split(",")[:2] + r.split(",")[3:]) for r in rows()]
    header = ",".join(HEADER.split(",")[:2] + HEADER.split(",")[3:])
    path = tmp_path / "log.csv"
    path.write_text(log_text(data, header=header))
    ds = load_log(path)
    assert set(ds.means) == {"F", "z"} and "T" not in ds.responses


def test_duplicate_column_via_alias(tmp_path):
    header = "time [s],F [N],drawbar_pull [N],torque [Nm],sinkage [mm]"
    data = [r.replace(",", ",1.0,", 1) for r in rows()]
    msg = refuse(tmp_path, log_text(data, header=header))
    assert "duplicate column 'drawbar_pull'" in msg
    assert "column 2" in msg and "column 3" in msg


def test_duplicate_identical_header_field(tmp_path):
    header = HEADER + ",sinkage [mm]"
    msg = refuse(tmp_path, log_text([r + ",1" for r in rows()], header=header))
    assert "duplicate column 'sinkage [mm]' (columns 4 and 5)" in msg


def test_text_in_number(tmp_path):
    msg = refuse(tmp_path, with_row(10, "0.6,20,abc,12"))
    assert "line 10, column 'torque [Nm]': 'abc' is not a number" in msg


def test_decimal_comma_is_text(tmp_path):
    msg = refuse(tmp_path, with_row(10, '0.6,"20,1",5,12'))
    assert "line 10, column 'drawbar_pull [N]': '20,1' is not a number" in msg


@pytest.mark.parametrize("bad", ["nan", "NaN", "inf", "-Infinity"])
def test_non_finite_cell(tmp_path, bad):
    msg = refuse(tmp_path, with_row(12, f"0.8,20,5,{bad}"))
    assert f"line 12, column 'sinkage [mm]': non-finite value '{bad}'" in msg


def test_empty_cell(tmp_path):
    msg = refuse(tmp_path, with_row(7, "0.3,20,,12"))
    assert "line 7, column 'torque [Nm]': empty cell" in msg


def test_time_not_increasing(tmp_path):
    msg = refuse(tmp_path, with_row(20, "1.5,20,5,12"))
    assert "line 20: time not strictly increasing" in msg
    assert "line 19" in msg


def test_repeated_time(tmp_path):
    msg = refuse(tmp_path, with_row(20, "1.5,20,5,12"))  # line 19 holds t = 1.5 s
    assert "1.5 s after 1.5 s" in msg


def test_shorter_than_offset(tmp_path):
    msg = refuse(tmp_path, log_text(rows(300)))  # 29.9 s
    assert "run lasts 29.9 s" in msg
    assert "averaging offset 40 s" in msg


def test_too_few_samples_in_window(tmp_path):
    msg = refuse(tmp_path, log_text(rows(46, dt=1.0)))  # 45 s at 1 Hz
    assert "averaging window [40, 45] s holds 6 sample(s); need at least 20" in msg


def test_unknown_unit(tmp_path):
    msg = refuse(tmp_path, log_text(header=HEADER.replace("[Nm]", "[kgm]")))
    assert "line 3, column 'torque [kgm]'" in msg
    assert "unknown torque unit 'kgm'" in msg
    assert "accepted: Nm" in msg and "lbf*ft" in msg


def test_missing_unit_brackets(tmp_path):
    msg = refuse(tmp_path, log_text(header=HEADER.replace("sinkage [mm]", "sinkage")))
    assert "column 'sinkage' (column 4) has no unit in brackets" in msg


def test_ragged_row(tmp_path):
    msg = refuse(tmp_path, with_row(15, "1.1,20,5"))
    assert "line 15: 3 fields, but the header (line 3) has 4" in msg


def test_sample_rate_too_low(tmp_path):
    msg = refuse(tmp_path, log_text(rows(30, dt=10.0)))
    assert "sample rate 0.1 Hz outside [1, 100000] Hz" in msg


def test_sample_rate_too_high(tmp_path):
    msg = refuse(tmp_path, log_text(rows(100, dt=1e-6)))
    assert "sample rate 1e+06 Hz outside [1, 100000] Hz (check the time unit)" in msg


def test_metadata_after_header(tmp_path):
    msg = refuse(tmp_path, with_row(30, "# slip: 0.3"))
    assert "line 30: '#' line after the header (line 3)" in msg


def test_irregular_sampling(tmp_path):
    data = rows()
    del data[100]  # a dropped sample: the step from line 103 to 104 is 0.2 s
    msg = refuse(tmp_path, log_text(data))
    assert "irregular sampling" in msg
    assert "lines 103 and 104" in msg
    assert "median step 0.1 s" in msg


@pytest.mark.parametrize(
    ("meta", "expected"),
    [
        ("# slip: 1.5\n# normal_load: 315\n", "slip = 1.5"),
        ("# slip: 150 %\n# normal_load: 315\n", "slip = 1.5"),
        ("# slip: 0.2\n# normal_load: -3\n", "W = -3.0"),
        ("# slip: 0.2\n", "'W' (or 'normal_load') is required"),
        ("# normal_load: 315\n", "'slip' is required"),
        ("# slip: 0.2\n# normal_load: 315\n# wheel_radius: 12 furlong\n", "unknown length unit"),
        ("# slip: 0.2\n# normal_load: 315\n# n_grousers: 12.5\n", "whole number"),
        ("# slip: 0.2\n# normal_load: heavy\n", "'heavy' is not a number"),
        (
            "# slip: 0.2\n# slip: 0.3\n# normal_load: 315\n",
            "line 2: metadata key 'slip' given twice",
        ),
        (
            "# slip: 0.2\n# normal_load: 315\n# R: 0.1\n# grouser_height: 0.2\n",
            "grouser_height must be smaller than the wheel radius R",
        ),
    ],
)
def test_invalid_metadata(tmp_path, meta, expected):
    msg = refuse(tmp_path, meta + HEADER + "\n" + "\n".join(rows()) + "\n")
    assert expected in msg


def test_invalid_caller_metadata(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text(log_text(meta=""))
    with pytest.raises(LogFormatError, match=r"metadata 'omega'.*unknown angular velocity unit"):
        load_log(path, metadata={"slip": 0.2, "W": 315, "omega": "3 rad"})


def test_conflicting_metadata(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text(log_text())
    (tmp_path / "bad.json").write_text(json.dumps({"slip": 0.3}))
    with pytest.raises(LogFormatError, match=r"'slip' conflicts: 0.2 in the file header, 0.3"):
        load_log(path)


def test_sidecar_not_json(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text(log_text())
    (tmp_path / "bad.json").write_text("{slip: 0.2")
    with pytest.raises(LogFormatError, match=r"sidecar bad.json: not valid JSON"):
        load_log(path)


def test_not_utf8(tmp_path):
    assert "not UTF-8" in refuse(tmp_path, log_text().encode("utf-16"))


def test_bad_cutoff_is_a_parameter_error(tmp_path):
    path = tmp_path / "ok.csv"
    path.write_text(log_text())
    with pytest.raises(ValueError, match="Nyquist"):
        load_log(path, cutoff_hz=6.0)  # 10 Hz sampling


# --- summaries -------------------------------------------------------------------------------

CONDITIONS = {"slip": 0.2, "normal_load": 315}


def summary(**changes) -> dict:
    doc = {
        "conditions": dict(CONDITIONS),
        "responses": {
            "F": {"mean": 20.1, "sd": 1.2, "unit": "N"},
            "T": {"mean": 5.3, "sd": 0.4, "unit": "Nm"},
            "z": {"mean": 12.0, "sd": 1.0, "unit": "mm"},
        },
        "n_trials": 3,
    }
    doc.update(changes)
    return doc


def refuse_summary(tmp_path, doc: dict | str, suffix: str = ".json") -> str:
    path = tmp_path / f"sum{suffix}"
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    with pytest.raises(LogFormatError) as info:
        load_summary(path)
    assert str(info.value).startswith(f"sum{suffix}: ")
    return str(info.value)


def test_summary_without_any_response(tmp_path):
    doc = summary()
    doc["responses"] = {}
    assert "no response; give at least one of F" in refuse_summary(tmp_path, doc)


def test_summary_negative_sd(tmp_path):
    doc = summary()
    doc["responses"]["F"]["sd"] = -1.2
    msg = refuse_summary(tmp_path, doc)
    assert "response 'F'" in msg and "sd = -1.2 N is negative" in msg


def test_summary_unknown_response(tmp_path):
    doc = summary()
    doc["responses"]["Q"] = {"mean": 1.0, "sd": 0.1}
    assert "response 'Q': unknown response" in refuse_summary(tmp_path, doc)


def test_summary_unknown_unit(tmp_path):
    doc = summary()
    doc["responses"]["z"]["unit"] = "furlong"
    msg = refuse_summary(tmp_path, doc)
    assert "response 'z'" in msg and "unknown length unit 'furlong'" in msg


@pytest.mark.parametrize("n", [0, 2.5, "three", True])
def test_summary_bad_trial_count(tmp_path, n):
    assert "n_trials" in refuse_summary(tmp_path, summary(n_trials=n))


def test_summary_missing_trial_count(tmp_path):
    doc = summary()
    del doc["n_trials"]
    assert "missing 'n_trials'" in refuse_summary(tmp_path, doc)


def test_summary_invalid_conditions(tmp_path):
    doc = summary(conditions={"slip": 1.5, "W": 315})
    assert "slip = 1.5" in refuse_summary(tmp_path, doc)


def test_summary_not_json(tmp_path):
    assert "not valid JSON" in refuse_summary(tmp_path, '{"responses": ')


def test_summary_csv_negative_sd(tmp_path):
    text = "# slip: 0.2\n# W: 315\n# n_trials: 3\nresponse,mean,sd,unit\n"
    text += "F,20.1,-1.2,N\nT,5.3,0.4,Nm\nz,12,1,mm\n"
    msg = refuse_summary(tmp_path, text, ".csv")
    assert "line 5, response 'F': sd = -1.2 N is negative" in msg


def test_summary_csv_missing_trial_count(tmp_path):
    text = "# slip: 0.2\n# W: 315\nresponse,mean,sd\nF,20.1,1.2\nT,5.3,0.4\nz,0.012,0.001\n"
    assert "missing '# n_trials: <count>'" in refuse_summary(tmp_path, text, ".csv")


def test_summary_csv_text_in_number(tmp_path):
    text = "# slip: 0.2\n# W: 315\n# n_trials: 2\nresponse,mean,sd\nF,20.1,1.2\nT,x,0.4\n"
    assert "line 6, column 'mean': 'x' is not a number" in refuse_summary(tmp_path, text, ".csv")


def test_per_trial_csv_needs_two_trials(tmp_path):
    text = "# slip: 0.2\n# W: 315\nF [N],T [Nm],z [mm]\n20,5,12\n"
    assert "1 trial row(s); need at least 2" in refuse_summary(tmp_path, text, ".csv")


def test_load_dataset_reports_bad_bytes():
    with pytest.raises(LogFormatError, match="empty file"):
        load_dataset(b"")
    data = log_text(rows(300)).encode()
    with pytest.raises(LogFormatError, match=r"run lasts 29\.9 s"):
        load_dataset(data)
