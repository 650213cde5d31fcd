"""Low-level CSV text handling shared by the log and summary parsers (no numerics).

Layout: optional leading ``# key: value`` metadata lines (other ``#`` lines are comments), one
header row, then data rows (no ``#`` lines after the header). Blank lines are skipped.
Delimiter: comma, or semicolon/tab when the header holds no comma. Line numbers are 1-based
physical lines of the file.

Text is read as a stream of lines (:func:`text_lines`), so a large log is never held in memory
as one string: :class:`TableReader` yields its rows in chunks, and :class:`CanonicalDigest`
hashes the canonical text (:func:`canonical_text`) on the way.
"""

import codecs
import csv
import hashlib
import io
from collections.abc import Iterator
from dataclasses import dataclass
from typing import BinaryIO

from .errors import LogFormatError

#: rows per chunk handed to the column parsers (bounded memory: a few MB of cells per chunk)
CHUNK_ROWS = 8192
_READ_BYTES = 1 << 20
#: the longest line read [characters]: far beyond any row or metadata line of an SWT file (a
#: JSON dataset is read whole, not by lines)
MAX_LINE_CHARS = 1 << 20


@dataclass(frozen=True)
class CsvTable:
    """Split CSV text: metadata lines, header fields and data rows with their line numbers."""

    metadata_lines: list[tuple[int, str]]
    header: list[str]
    header_line: int
    rows: list[list[str]]
    row_lines: list[int]


def text_lines(stream: BinaryIO, max_line: int = MAX_LINE_CHARS) -> Iterator[str]:
    """Physical lines of UTF-8 bytes (BOM dropped, ``\\r\\n`` and ``\\r`` read as ``\\n``),
    without their line ending; read in 1 MB pieces. A line longer than ``max_line``
    characters is refused as soon as that much of it is read (memory: a few times
    ``max_line``, whatever the file holds)."""
    decoder = codecs.getincrementaldecoder("utf-8-sig")()
    pending: list[str] = []  # the pieces of the line not ended yet
    pending_len = 0
    carry_cr = False  # the last read ended in "\r": a "\r\n" may straddle two reads
    line_no = 1
    position = 0
    while True:
        chunk = stream.read(_READ_BYTES)
        try:
            text = decoder.decode(chunk, final=not chunk)
        except UnicodeDecodeError as exc:
            start = exc.start  # within this read (give or take a split character)
            line = line_no + chunk[:start].count(b"\n")
            raise LogFormatError(
                f"line {line}: file is not UTF-8 text (byte {position + start})"
            ) from None
        position += len(chunk)
        if carry_cr:
            text = "\r" + text
        carry_cr = bool(chunk) and text.endswith("\r")
        if carry_cr:
            text = text[:-1]
        lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
        last = lines.pop() if chunk else None
        if lines:
            lines[0] = "".join([*pending, lines[0]])
            pending, pending_len = [], 0
        for line in lines:
            if len(line) > max_line:
                raise _long_line(line_no, max_line)
            line_no += 1
            yield line
        if last is None:
            return
        pending.append(last)
        pending_len += len(last)
        if pending_len > max_line:
            raise _long_line(line_no, max_line)


def _long_line(line_no: int, max_line: int) -> LogFormatError:
    return LogFormatError(
        f"line {line_no}: longer than {max_line} characters (no SWT log, summary or metadata "
        "line is; is this a CSV file?)"
    )


def decode_text(data: bytes | str) -> str:
    """Decode UTF-8 (with or without BOM) into text with ``\\n`` line endings."""
    if isinstance(data, bytes):
        return "\n".join(text_lines(io.BytesIO(data)))
    return data.removeprefix("\ufeff").replace("\r\n", "\n").replace("\r", "\n")


class CanonicalDigest:
    """sha256 of the canonical text, fed one physical line at a time: lines with trailing
    whitespace removed, trailing blank lines dropped, each line ended by ``\\n``."""

    def __init__(self, prefix: bytes = b"") -> None:
        self._hash = hashlib.sha256(prefix)
        self._blank = 0
        self._any = False

    def add(self, line: str) -> None:
        line = line.rstrip()
        if not line:
            self._blank += 1
            return
        self._hash.update(("\n" * self._blank + line + "\n").encode("utf-8"))
        self._blank = 0
        self._any = True

    def finish(self, *suffix: bytes) -> str:
        """Hex digest of the prefix, the canonical text and then ``suffix``; call once, after
        the last line."""
        if not self._any:
            self._hash.update(b"\n")
        for part in suffix:
            self._hash.update(part)
        return self._hash.hexdigest()


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


class TableReader:
    """One pass over CSV lines: metadata lines and header first (:meth:`read_head`), then the
    data rows in chunks (:meth:`row_chunks`); every physical line also goes to ``digest``."""

    def __init__(self, lines: Iterator[str], digest: CanonicalDigest | None = None) -> None:
        self._lines = lines
        self._digest = digest
        self._number = 0
        self.metadata_lines: list[tuple[int, str]] = []
        self.header: list[str] = []
        self.header_line = 0
        self._delimiter = ","

    def _next(self) -> str | None:
        line = next(self._lines, None)
        if line is not None:
            self._number += 1
            if self._digest is not None:
                self._digest.add(line)
        return line

    def read_head(self) -> None:
        """Read the metadata lines and the header; refuse a file without a header."""
        while (line := self._next()) is not None:
            if not line.strip():
                continue
            if line.lstrip().startswith("#"):
                self.metadata_lines.append((self._number, line))
                continue
            self._delimiter = _delimiter(line)
            self.header = [h.strip() for h in _split(line, self._delimiter)]
            self.header_line = self._number
            if all(_is_number(h) for h in self.header):
                shown = line.strip()
                shown = shown if len(shown) <= 40 else shown[:40] + "..."
                raise LogFormatError(
                    f"line {self._number}: no header row: the first row after the metadata "
                    f"holds numbers ({shown}); name the columns first, e.g. "
                    "'time [s],F [N],T [N m],z [mm]' for a log"
                )
            return
        what = "only metadata lines" if self.metadata_lines else "nothing"
        raise LogFormatError(f"empty file: {what}, no header row")

    @property
    def delimiter(self) -> str:
        return self._delimiter

    def line_chunks(self, size: int = CHUNK_ROWS) -> Iterator[tuple[list[str], list[int]]]:
        """(data lines, their line numbers) in chunks of at most ``size`` non-blank lines,
        unsplit; refuse ``#`` lines after the header."""
        lines: list[str] = []
        numbers: list[int] = []
        while (line := self._next()) is not None:
            if not line.strip():
                continue
            if line.lstrip().startswith("#"):
                raise LogFormatError(
                    f"line {self._number}: '#' line after the header (line {self.header_line}); "
                    "metadata and comments go before the header"
                )
            lines.append(line)
            numbers.append(self._number)
            if len(lines) >= size:
                yield lines, numbers
                lines, numbers = [], []
        if lines:
            yield lines, numbers

    def split_rows(self, lines: list[str], numbers: list[int]) -> list[list[str]]:
        """Fields of each line; refuse a row whose field count differs from the header's."""
        width = len(self.header)
        rows = []
        for line, number in zip(lines, numbers, strict=True):
            fields = _split(line, self._delimiter)
            if len(fields) != width:
                raise LogFormatError(
                    f"line {number}: {len(fields)} fields, but the header "
                    f"(line {self.header_line}) has {width}"
                )
            rows.append(fields)
        return rows


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def split_table(data: bytes | str) -> CsvTable:
    """Split CSV text into metadata lines, header and rows; refuse empty files and ragged rows."""
    lines = (
        text_lines(io.BytesIO(data))
        if isinstance(data, bytes)
        else iter(decode_text(data).split("\n"))
    )
    reader = TableReader(lines)
    reader.read_head()
    rows: list[list[str]] = []
    numbers: list[int] = []
    for lines, chunk_numbers in reader.line_chunks():
        rows.extend(reader.split_rows(lines, chunk_numbers))
        numbers.extend(chunk_numbers)
    return CsvTable(reader.metadata_lines, reader.header, reader.header_line, rows, numbers)
