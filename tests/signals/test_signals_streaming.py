"""Logs are read as a stream in chunks: same numbers and line numbers as a whole-file reader
(numpy's loadtxt), same content hashes as before streaming (pinned), physically absurd values
refused with their line and column, summaries bounded in size."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest

from scm_core.signals import LogFormatError, load_dataset, load_log, load_summary
from scm_core.signals.csvtext import CHUNK_ROWS, canonical_text, text_lines
from scm_core.signals.hashing import LOG_HASH_PREFIX, canonical_json, log_hash
from scm_core.signals.logformat import parse_log_stream
from scm_core.signals.summary import MAX_SUMMARY_BYTES

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "wf34_s020.csv"
HEADER = "time [s],drawbar_pull [N],torque [Nm],sinkage [mm]"
META = "# slip: 0.2\n# normal_load: 315 N\n"


def long_log(n: int) -> str:
    rng = np.random.default_rng(7)
    body = "\n".join(
        f"{i * 0.01:.10g},{20 + rng.normal():.12g},{5 + 0.1 * rng.normal():.12g},{12.5:.12g}"
        for i in range(n)
    )
    return META + HEADER + "\n" + body + "\n"


def test_chunked_parse_equals_a_whole_file_reader():
    """A log spanning several chunks gives exactly numpy.loadtxt's numbers (in SI) and the
    physical line number of every row."""
    n = 3 * CHUNK_ROWS + 17
    text = long_log(n)
    table = parse_log_stream(io.BytesIO(text.encode()))
    ref = np.loadtxt(io.StringIO(text), delimiter=",", comments="#", skiprows=3)
    assert ref.shape == (n, 4)
    np.testing.assert_array_equal(table.columns["time"], ref[:, 0])
    np.testing.assert_array_equal(table.columns["drawbar_pull"], ref[:, 1])
    np.testing.assert_array_equal(table.columns["torque"], ref[:, 2])
    np.testing.assert_array_equal(table.columns["sinkage"], ref[:, 3] * 1e-3)
    np.testing.assert_array_equal(table.lines, np.arange(4, 4 + n))


def test_error_in_a_late_chunk_names_its_physical_line():
    n = 3 * CHUNK_ROWS
    lines = long_log(n).split("\n")
    bad = 2 * CHUNK_ROWS + 123  # 0-based index into lines; line number is bad + 1
    lines[bad] = lines[bad].replace(",", ",x", 1)
    with pytest.raises(LogFormatError, match=rf"line {bad + 1}, column 'drawbar_pull \[N\]'"):
        parse_log_stream(io.BytesIO("\n".join(lines).encode()))


@pytest.mark.parametrize("ending", [b"\n", b"\r\n", b"\r"])
def test_line_endings_across_read_boundaries(ending):
    """Lines split at the 1 MB read boundary (a CR LF pair straddling it included) come out
    as the same lines as a whole-text split."""
    line = b"0123456789," * 9 + b"x"  # 100 bytes
    data = b"\xef\xbb\xbf" + ending.join([line] * 25_000) + ending
    for shift in range(0, 3):
        blob = b"a" * shift + data
        expected = blob.decode("utf-8-sig").replace("\r\n", "\n").replace("\r", "\n").split("\n")
        assert list(text_lines(io.BytesIO(blob))) == expected


def test_not_utf8_names_line_and_byte():
    text = (META + HEADER + "\n0,1,2,3\n").encode() + b"0.1,\xff,2,3\n"
    with pytest.raises(LogFormatError, match=r"line 5: file is not UTF-8 text \(byte 96\)"):
        list(text_lines(io.BytesIO(text)))


def test_content_hashes_are_those_of_the_whole_text_reader():
    """Streaming hashes the canonical text (sha256 of prefix, canonical text, metadata JSON):
    the pinned values were computed before logs were streamed, so databases keep matching."""
    raw = EXAMPLE.read_bytes()
    assert load_dataset(EXAMPLE).content_hash == (
        "758ff4db28e12c222b256aa06a29040529b89595d6fbeb71eb6b6161301add5e"
    )
    variants = [
        raw,
        b"\xef\xbb\xbf" + raw.replace(b"\n", b"\r\n") + b"\r\n\r\n  \n",
        raw.replace(b"\n", b"\r"),
    ]
    hashes = {load_dataset(v, {"W": 315.0}).content_hash for v in variants}
    assert hashes == {"1418311d89a87ff0f91c3e99ca01b2da80353b74e7441fc48b17e5fd2f9e70f1"}


@pytest.mark.parametrize("text", ["", "\n \n", "a\n\nb  \n\n", "a\r\nb\r\n\r\n"])
def test_streamed_hash_is_sha256_of_the_canonical_text(text):
    import hashlib

    meta = {"conditions": {"W": 1.0}}
    expected = hashlib.sha256(
        LOG_HASH_PREFIX + canonical_text(text).encode() + b"\n" + canonical_json(meta).encode()
    ).hexdigest()
    assert log_hash(text, meta) == expected


@pytest.mark.parametrize(
    ("column", "value", "message"),
    [
        ("drawbar_pull", "1e308", "'1e308' is 1e+308 N is outside the plausible range of a force"),
        ("drawbar_pull", "-2e6", "outside the plausible range of a force (|value| <= 1e+06 N"),
        ("torque", "3e5", "outside the plausible range of a torque (|value| <= 100000 Nm"),
        ("sinkage", "2e4", "20 m is outside the plausible range of a length (|value| <= 10 m"),
    ],
)
def test_absurd_values_are_refused_with_line_and_column(column, value, message):
    """1e308 is finite, but its square overflows; 20 m of sinkage is a unit mistake."""
    index = ["time", "drawbar_pull", "torque", "sinkage"].index(column)
    lines = long_log(600).split("\n")
    cells = lines[100].split(",")
    cells[index] = value
    lines[100] = ",".join(cells)
    with pytest.raises(LogFormatError) as info:
        load_log("\n".join(lines).encode(), offset=1.0)
    assert f"line 101, column '{HEADER.split(',')[index]}'" in str(info.value)
    assert message in str(info.value)


def test_absurd_metadata_and_summary_values_are_refused():
    with pytest.raises(LogFormatError, match=r"'W'.*1e\+300 N is outside the plausible range"):
        load_log(long_log(600).encode(), {"W": 1e300}, offset=1.0)
    doc = {
        "conditions": {"slip": 0.2, "W": 315},
        "responses": {"F": {"mean": 1e308, "sd": 1.0}},
        "n_trials": 3,
    }
    with pytest.raises(LogFormatError, match="mean 1e\\+308 N is outside the plausible range"):
        load_summary(json.dumps(doc).encode())
    trials = "# slip: 0.2\n# W: 315\ntrial,drawbar_pull [kN]\n1,20\n2,2000\n"
    with pytest.raises(LogFormatError, match=r"line 5, column 'drawbar_pull \[kN\]'"):
        load_summary(trials.encode())


def test_summaries_are_bounded_in_size():
    doc = {"conditions": {"slip": 0.2, "W": 315}, "responses": {"F": {"mean": 1, "sd": 1}},
           "n_trials": 3, "provenance": {"note": "x" * MAX_SUMMARY_BYTES}}  # fmt: skip
    with pytest.raises(LogFormatError, match="too large for a summary"):
        load_dataset(json.dumps(doc).encode())


def test_epoch_time_stamps_are_plausible():
    """Unix time in seconds (1.7e9 s) is a real lab convention and stays accepted."""
    lines = long_log(600).split("\n")
    for i in range(3, len(lines) - 1):
        t, rest = lines[i].split(",", 1)
        lines[i] = f"{1.7e9 + float(t):.12f},{rest}"
    ds = load_log("\n".join(lines).encode(), offset=1.0)
    assert ds.n_samples > 0
