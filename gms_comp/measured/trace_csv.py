"""Reading a CSV trace: its columns as float arrays and each sample's row in the file.

Sizes are bounded before anything is parsed: the file's bytes from the file system, its
header from the first bytes, its rows estimated from the first rows' length (a file of
millions of rows is refused in milliseconds) and then counted exactly in fixed-size
chunks, never holding the file. A UTF-8 byte-order mark is read as such; UTF-16 and
semicolon-separated files are refused with what to save instead. A file of plain numbers
is then parsed by numpy from the file in one streamed pass; any other file is read cell
by cell, so that an error names the row and column where the file is wrong.
"""

from __future__ import annotations

import codecs
import csv
import math
from pathlib import Path

import numpy as np

from gms_comp.errors import TraceError
from gms_comp.validation import MAX_TRACE_BYTES, MAX_TRACE_SAMPLES

#: Columns of a CSV trace (the canonical ones need 7; extra columns are read and ignored).
MAX_TRACE_COLUMNS = 64
#: Bytes of a CSV trace's header row (64 names of up to a kilobyte each).
MAX_HEADER_BYTES = 64 << 10
#: Mean bytes of a CSV trace's row (64 numbers of 17 digits need about 1.5 kB): a file of
#: a few giant rows would be parsed as a few giant strings.
MAX_ROW_BYTES = 16 << 10

# Bytes read at once when counting rows (the memory the count takes).
_CHUNK_BYTES = 1 << 20
# An estimate from the first rows' length this far over the cap refuses at once (rows
# vary in length: a file near the cap is counted exactly).
_ESTIMATE_MARGIN = 1.5


def read_csv(path: Path) -> tuple[dict[str, np.ndarray], list[int]]:
    """Columns of a CSV file as float arrays (the header row names them) and the file's
    line number of each sample, for error messages."""
    src = str(path)
    size = path.stat().st_size
    if size > MAX_TRACE_BYTES:
        raise TraceError(
            src, "", f"{size} bytes, more than the {MAX_TRACE_BYTES} a CSV trace may have"
        )
    with path.open("rb") as fh:
        head = fh.read(MAX_HEADER_BYTES + 4)
    bom = _encoding(head, src)
    header_end = head.find(b"\n", bom)
    if header_end < 0 and size > len(head):
        cells = head.count(b",") + 1
        if cells > MAX_TRACE_COLUMNS:
            raise TraceError(src, "row 1", f"{cells}+ columns, more than {MAX_TRACE_COLUMNS}")
        raise TraceError(src, "row 1", f"the header row is longer than {MAX_HEADER_BYTES} bytes")
    header = _header(head[bom : header_end if header_end >= 0 else len(head)], src)
    rows = _rows(path, size, head, header_end + 1 if header_end >= 0 else size)
    if rows == 0:
        raise TraceError(src, "", "no samples after the header row")
    plain = _plain_csv(path, header, rows)
    if plain is not None:
        return plain
    return _cell_by_cell(path, header)


def _encoding(head: bytes, src: str) -> int:
    """Bytes of a UTF-8 byte-order mark (0 without); other encodings are refused."""
    if head.startswith(codecs.BOM_UTF8):
        return len(codecs.BOM_UTF8)
    if head.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)) or b"\x00" in head:
        raise TraceError(src, "", "not UTF-8 text (UTF-16 or binary): save the trace as CSV UTF-8")
    return 0


def _header(line: bytes, src: str) -> list[str]:
    try:
        text = line.decode("utf-8")
    except UnicodeDecodeError as err:
        raise TraceError(src, "row 1", f"not a text file ({err.reason})") from None
    if not text.strip():
        raise TraceError(src, "row 1", "empty header row (expected the column names)")
    try:
        header = [h.strip() for h in next(csv.reader([text.rstrip("\r\n")]))]
    except csv.Error as err:
        raise TraceError(src, "row 1", f"not a valid CSV header ({err})") from None
    if len(header) == 1 and ";" in header[0]:
        raise TraceError(
            src, "row 1",
            "the columns are separated by ';': save the trace with ',' between columns and "
            "'.' as the decimal point",
        )  # fmt: skip
    if len(header) > MAX_TRACE_COLUMNS:
        raise TraceError(src, "row 1", f"{len(header)} columns, more than {MAX_TRACE_COLUMNS}")
    if "" in header:
        raise TraceError(src, "row 1", f"column {header.index('') + 1} has no name")
    if len(set(header)) != len(header):
        twice = sorted({h for h in header if header.count(h) > 1})
        raise TraceError(src, "row 1", f"duplicate column names in the header: {', '.join(twice)}")
    return header


def _rows(path: Path, size: int, head: bytes, body_start: int) -> int:
    """Rows after the header (lines; a last line without a newline counts), refused over
    ``MAX_TRACE_SAMPLES`` first by an estimate from the first rows, then by a count in
    chunks that stops at the cap."""
    src = str(path)
    sample = head[body_start:]
    newlines = sample.count(b"\n")
    if newlines and size > len(head):
        estimate = (size - body_start) * newlines / len(sample)
        if estimate > _ESTIMATE_MARGIN * MAX_TRACE_SAMPLES:
            raise TraceError(
                src, "",
                f"about {estimate:.3g} rows ({size} bytes, rows of {len(sample) / newlines:.0f} "
                f"bytes), more than the {MAX_TRACE_SAMPLES} samples a trace may have; cut the "
                "record into parts",
            )  # fmt: skip
    rows, last = 0, b"\n"
    with path.open("rb") as fh:
        fh.seek(body_start)
        while chunk := fh.read(_CHUNK_BYTES):
            if b"\x00" in chunk:
                at = rows + chunk[: chunk.index(b"\x00")].count(b"\n") + 2
                raise TraceError(src, f"row {at}", "holds a NUL byte: not a text file")
            rows += chunk.count(b"\n")
            last = chunk[-1:]
            if rows > MAX_TRACE_SAMPLES:
                raise TraceError(
                    src, f"row {MAX_TRACE_SAMPLES + 2}",
                    f"more than {MAX_TRACE_SAMPLES} samples; cut the record into parts",
                )  # fmt: skip
    rows += last != b"\n"
    if rows and (size - body_start) / rows > MAX_ROW_BYTES:
        raise TraceError(
            src, "", f"rows of {(size - body_start) / rows:.0f} bytes on average, more than "
            f"the {MAX_ROW_BYTES} of a trace's row",
        )  # fmt: skip
    return rows


def _plain_csv(
    path: Path, header: list[str], rows: int
) -> tuple[dict[str, np.ndarray], list[int]] | None:
    """:func:`read_csv`'s result for a file of plain numbers, one per cell, a row per line
    (no quotes, no blank rows), parsed by numpy streaming from the file (a trace of
    131 000 rows: 0.08 s against 0.38 s cell by cell); None for any other file, which
    the cell-by-cell reader then reads or says where it is wrong. A non-finite number is
    refused here with its row."""
    try:
        with path.open(encoding="utf-8-sig", newline="") as fh:
            table = np.loadtxt(fh, delimiter=",", skiprows=1, comments=None, ndmin=2, dtype=float)
    except (UnicodeDecodeError, ValueError):
        return None
    if table.shape != (rows, len(header)):
        return None
    lines = list(range(2, rows + 2))
    bad = np.argwhere(~np.isfinite(table))
    if bad.size:
        i, j = (int(k) for k in bad[0])
        raise TraceError(
            str(path), f"row {lines[i]}, column {header[j]}", f"{table[i, j]} is not finite"
        )
    return {name: table[:, i] for i, name in enumerate(header)}, lines


def _cell_by_cell(path: Path, header: list[str]) -> tuple[dict[str, np.ndarray], list[int]]:
    values: list[list[float]] = []
    lines: list[int] = []
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            next(reader)
            for line, row in enumerate(reader, start=2):
                if not row or all(not c.strip() for c in row):
                    continue
                if len(row) != len(header):
                    raise TraceError(
                        str(path), f"row {line}", f"{len(row)} cells, the header has {len(header)}"
                    )
                lines.append(line)
                values.append([_number(path, line, header[i], c) for i, c in enumerate(row)])
    except UnicodeDecodeError as err:
        raise TraceError(str(path), "", f"not a text file ({err.reason})") from err
    except csv.Error as err:
        raise TraceError(str(path), "", f"not valid CSV ({err})") from err
    if not values:
        raise TraceError(str(path), "", "no samples after the header row")
    table = np.array(values, dtype=float).reshape(len(values), len(header))
    return {name: table[:, i] for i, name in enumerate(header)}, lines


def _number(path: Path, line: int, column: str, cell: str) -> float:
    try:
        value = float(cell)
    except ValueError:
        raise TraceError(
            str(path), f"row {line}, column {column}", f"not a number {cell!r}"
        ) from None
    if not math.isfinite(value):
        raise TraceError(str(path), f"row {line}, column {column}", f"{cell.strip()} is not finite")
    return value
