"""Low-level CSV text handling shared by the log and summary parsers (no numerics).

Layout: optional leading ``# key: value`` metadata lines (other ``#`` lines are comments), one
header row, then data rows (no ``#`` lines after the header). Blank lines are skipped.
Delimiter: comma, or semicolon/tab when the header holds no comma. Line numbers are 1-based
physical lines of the file.
"""

import csv
from dataclasses import dataclass

from .errors import LogFormatError


@dataclass(frozen=True)
class CsvTable:
    """Split CSV text: metadata lines, header fields and data rows with their line numbers."""

    metadata_lines: list[tuple[int, str]]
    header: list[str]
    header_line: int
    rows: list[list[str]]
    row_lines: list[int]


def decode_text(data: bytes | str) -> str:
    """Decode UTF-8 (with or without BOM) into text with ``\\n`` line endings."""
    if isinstance(data, bytes):
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise LogFormatError(f"file is not UTF-8 text (byte {exc.start})") from None
    else:
        text = data.removeprefix("\ufeff")
    return text.replace("\r\n", "\n").replace("\r", "\n")


def canonical_text(data: bytes | str) -> str:
    """Text with unified line endings, trailing whitespace and trailing blank lines removed."""
    lines = [line.rstrip() for line in decode_text(data).split("\n")]
    while lines and not lines[-1]:
        lines.pop()
    return "\n".join(lines) + "\n"


def _split(line: str, delimiter: str) -> list[str]:
    if '"' in line:
        return next(csv.reader([line], delimiter=delimiter))
    return line.split(delimiter)


def _delimiter(header: str) -> str:
    if "," in header:
        return ","
    if ";" in header:
        return ";"
    return "\t" if "\t" in header else ","


def split_table(data: bytes | str) -> CsvTable:
    """Split CSV text into metadata lines, header and rows; refuse empty files and ragged rows."""
    lines = decode_text(data).split("\n")
    meta: list[tuple[int, str]] = []
    header: list[str] | None = None
    header_line = 0
    delimiter = ","
    rows: list[list[str]] = []
    row_lines: list[int] = []
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        if header is None:
            if line.lstrip().startswith("#"):
                meta.append((number, line))
                continue
            delimiter = _delimiter(line)
            header = [h.strip() for h in _split(line, delimiter)]
            header_line = number
            continue
        if line.lstrip().startswith("#"):
            raise LogFormatError(
                f"line {number}: '#' line after the header (line {header_line}); "
                "metadata and comments go before the header"
            )
        fields = _split(line, delimiter)
        if len(fields) != len(header):
            raise LogFormatError(
                f"line {number}: {len(fields)} fields, but the header (line {header_line}) "
                f"has {len(header)}"
            )
        rows.append(fields)
        row_lines.append(number)
    if header is None:
        what = "only metadata lines" if meta else "nothing"
        raise LogFormatError(f"empty file: {what}, no header row")
    return CsvTable(meta, header, header_line, rows, row_lines)
