"""SWT datasets: parse, validate and process single-wheel-test logs and summaries.

Time-series logs are filtered (zero-phase low-pass) and averaged after an offset (paper
section 4.3) into steady means of F (N), T (Nm), z (m) with autocorrelation-aware standard
errors; summary datasets carry reported means and standard deviations.
"""

from .conditions import TestConditions
from .dataset import SWTDataset, SWTSeries, from_dict, to_dict
from .errors import LogFormatError
from .loaders import load_dataset, load_log, load_summary, read_sidecar, write_log
from .logformat import COLUMNS, format_log, parse_log_text
from .metadata import Metadata, merge_metadata
from .processing import (
    ResponseStat,
    SteadyResponse,
    autocorrelation,
    integrated_autocorr_time,
    lowpass,
    standard_error,
    steady_response,
    steady_stat,
)
from .responses import RESPONSE_KEYS, RESPONSES, Response, response
from .summary import parse_summary_csv, parse_summary_json
from .units import UNITS
from .validation import check_time_axis, window_mask

__all__ = [
    "COLUMNS",
    "RESPONSES",
    "RESPONSE_KEYS",
    "UNITS",
    "LogFormatError",
    "Metadata",
    "Response",
    "ResponseStat",
    "SWTDataset",
    "SWTSeries",
    "SteadyResponse",
    "TestConditions",
    "autocorrelation",
    "check_time_axis",
    "format_log",
    "from_dict",
    "integrated_autocorr_time",
    "load_dataset",
    "load_log",
    "load_summary",
    "lowpass",
    "merge_metadata",
    "parse_log_text",
    "parse_summary_csv",
    "parse_summary_json",
    "read_sidecar",
    "response",
    "standard_error",
    "steady_response",
    "steady_stat",
    "to_dict",
    "window_mask",
    "write_log",
]
