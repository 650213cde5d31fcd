"""Round trips: writer/reader, summary JSON vs CSV, content hashes, dict form, dispatch."""

import json

import numpy as np
import pytest

from scm_core.signals import (
    SWTDataset,
    TestConditions,
    from_dict,
    load_dataset,
    load_log,
    load_summary,
    to_dict,
    write_log,
)

META = {
    "W": 315.0,
    "slip": 0.2,
    "omega": 0.4,
    "R": 0.125,
    "b": 0.112,
    "n_grousers": 12,
    "grouser_height": 0.009,
    "soil": "WF34",
    "date": "2019-05-14",
    "operator": "A. Tester",
    "notes": "dry quartz sand\nsecond run of the day",
}


def series(seconds: float = 60.0, fs: float = 50.0, seed: int = 0):
    rng = np.random.default_rng(seed)
    t = np.arange(0, seconds, 1 / fs)
    F = 20 + np.sin(2 * np.pi * 0.2 * t) + rng.normal(0, 0.5, t.size)
    T = 5 + rng.normal(0, 0.1, t.size)
    z = 0.012 * (1 - np.exp(-t / 5)) + rng.normal(0, 1e-4, t.size)
    return t, F, T, z


def test_write_then_load_reproduces_data_and_metadata(tmp_path):
    t, F, T, z = series()
    Fz = np.full_like(t, 315.0)
    s = np.full_like(t, 0.2)
    path = write_log(tmp_path / "run1.csv", t, F, T, z, META, normal_force=Fz, slip=s)
    assert path.with_suffix(".json").is_file()
    ds = load_log(path)
    assert ds.name == "run1" and ds.source_kind == "timeseries"
    np.testing.assert_array_equal(ds.series.t, t)
    for key, x in (("drawbar_pull", F), ("torque", T), ("sinkage", z), ("normal_force", Fz)):
        np.testing.assert_array_equal(ds.series.raw[key], x)
    np.testing.assert_array_equal(ds.series.raw["slip"], s)
    conditions = {k: v for k, v in META.items() if k in TestConditions.model_fields}
    assert ds.conditions == TestConditions(**conditions)
    assert ds.provenance == {k: v for k, v in META.items() if k not in conditions}
    assert ds.offset == 40.0 and ds.window[0] == pytest.approx(40.0)
    assert ds.n_samples == int(np.sum(t >= 40.0))
    assert ds.means["F"] == pytest.approx(20.0, abs=0.1)
    assert ds.means["z"] == pytest.approx(0.012, rel=0.01)
    assert not ds.series.raw["torque"].flags.writeable


def test_write_without_sidecar_keeps_metadata_in_the_file(tmp_path):
    t, F, T, z = series()
    path = write_log(tmp_path / "run2.csv", t, F, T, z, META, sidecar=False)
    assert not path.with_suffix(".json").exists()
    text = path.read_text()
    assert text.startswith("# W: 315.0 N\n# slip: 0.2\n# slip_symmetric: 0.2\n")
    assert "# omega: 0.4 rad/s\n" in text and "# rim_speed: " in text
    assert "# notes: dry quartz sand second run of the day\n" in text
    ds = load_log(path)
    assert ds.conditions.W == 315.0 and ds.conditions.n_grousers == 12
    assert ds.provenance["notes"] == "dry quartz sand second run of the day"


def test_bytes_upload_with_metadata_dict_equals_file_with_sidecar(tmp_path):
    t, F, T, z = series()
    path = write_log(tmp_path / "run3.csv", t, F, T, z, {"W": 315, "slip": 0.2}, sidecar=False)
    sidecar = {"wheel_radius": "125 mm", "soil": "WF34"}
    path.with_suffix(".json").write_text(json.dumps(sidecar))
    from_file = load_log(path)
    from_bytes = load_log(path.read_bytes(), metadata=sidecar, name="run3")
    assert from_file == from_bytes
    assert pytest.approx(0.125) == from_file.conditions.R


def test_content_hash(tmp_path):
    t, F, T, z = series()
    path = write_log(tmp_path / "run4.csv", t, F, T, z, META, sidecar=False)
    data = path.read_bytes()
    first = load_log(data)
    assert load_log(data).content_hash == first.content_hash
    assert len(first.content_hash) == 64
    # the same content saved with CRLF line endings and a BOM is the same upload
    crlf = b"\xef\xbb\xbf" + data.replace(b"\n", b"\r\n")
    assert load_log(crlf).content_hash == first.content_hash
    # one changed value, or changed metadata, is a different upload
    changed = data.replace(b"\n0.02,", b"\n0.020000000000000001,", 1)
    assert changed != data
    assert load_log(changed).content_hash != first.content_hash
    lines = data.decode().split("\n")
    lines[20] = lines[20].replace(",", ",1", 1)
    assert load_log("\n".join(lines).encode()).content_hash != first.content_hash
    other = load_log(data, metadata={"operator": "someone else"})
    assert other.content_hash != first.content_hash
    # processing options do not change the content hash
    assert load_log(data, offset=30.0).content_hash == first.content_hash


SUMMARY = {
    "conditions": {"slip": 0.2, "normal_load": "315 N", "wheel_radius": "125 mm", "soil": "WF34"},
    "responses": {
        "F": {"mean": 20.1, "sd": 1.2, "unit": "N"},
        "T": {"mean": 5.3, "sd": 0.4, "unit": "Nm"},
        "z": {"mean": 12.0, "sd": 1.5, "unit": "mm"},
    },
    "n_trials": 3,
}
SUMMARY_CSV = """# slip: 0.2
# normal_load: 315 N
# wheel_radius: 125 mm
# soil: WF34
# n_trials: 3
response,mean,sd,unit
F,20.1,1.2,N
T,5.3,0.4,Nm
z,12.0,1.5,mm
"""


def test_summary_json_and_csv_give_the_same_dataset(tmp_path):
    (tmp_path / "run7.json").write_text(json.dumps(SUMMARY))
    (tmp_path / "run7.csv").write_text(SUMMARY_CSV)
    a = load_summary(tmp_path / "run7.json")
    b = load_summary(tmp_path / "run7.csv")
    assert a == b
    assert a.source_kind == "summary" and a.n_trials == 3 and a.series is None
    assert a.responses["F"].se == pytest.approx(1.2 / np.sqrt(3))
    assert a.responses["z"].mean == pytest.approx(0.012)
    assert a.responses["z"].sd == pytest.approx(0.0015)
    assert pytest.approx(0.125) == a.conditions.R
    assert a.provenance == {"soil": "WF34"}
    assert load_summary(SUMMARY, name="run7") == a  # an already-decoded dict
    changed = json.loads(json.dumps(SUMMARY))
    changed["responses"]["T"]["sd"] = 0.41
    assert load_summary(changed, name="run7").content_hash != a.content_hash


def test_per_trial_summary_csv(tmp_path):
    text = "# slip: 0.2\n# W: 315\ntrial,F [N],T [Nm],z [mm],comment\n"
    text += "1,19,5.0,11,ok\n2,20,5.5,12,ok\n3,21,6.0,13,wet\n"
    ds = load_summary(text.encode())
    assert ds.n_trials == 3
    assert ds.responses["F"].mean == pytest.approx(20.0)
    assert ds.responses["F"].sd == pytest.approx(1.0)
    assert ds.responses["T"].se == pytest.approx(0.5 / np.sqrt(3))
    assert ds.responses["z"].mean == pytest.approx(0.012)


def test_dict_round_trip_through_json(tmp_path):
    t, F, T, z = series()
    log = load_log(write_log(tmp_path / "run5.csv", t, F, T, z, META))
    (tmp_path / "run7.json").write_text(json.dumps(SUMMARY))
    summ = load_summary(tmp_path / "run7.json")
    for ds in (log, summ):
        back = from_dict(json.loads(json.dumps(to_dict(ds))))
        assert back == ds
    slim = SWTDataset.from_dict(log.to_dict(include_series=False))
    assert slim.series is None and slim.responses == log.responses
    assert slim.content_hash == log.content_hash


def test_load_dataset_dispatch(tmp_path):
    t, F, T, z = series()
    log_path = write_log(tmp_path / "run6.csv", t, F, T, z, META)
    assert load_dataset(log_path) == load_log(log_path)
    (tmp_path / "s.json").write_text(json.dumps(SUMMARY))
    (tmp_path / "s.csv").write_text(SUMMARY_CSV)
    assert load_dataset(tmp_path / "s.json") == load_summary(tmp_path / "s.csv")
    assert load_dataset(SUMMARY_CSV.encode()).source_kind == "summary"
    assert load_dataset(json.dumps(SUMMARY).encode()).source_kind == "summary"
    stored = tmp_path / "stored.json"
    stored.write_text(json.dumps(load_log(log_path).to_dict()))
    assert load_dataset(stored) == load_log(log_path)
    assert load_dataset(log_path.read_bytes(), offset=30.0).offset == 30.0
