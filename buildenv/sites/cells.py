"""Reading the rows and cells of a site's CSV files (``measurements.csv`` and ``settings.csv``).

:func:`_rows` yields each line's stripped cells with its line number (blank lines skipped, bad encoding or CSV
syntax a :class:`~buildenv.errors.SiteError`), :func:`_check_width` checks a row's number of cells,
:func:`_separator_hint` names a wrong column separator for a header error, and :func:`_parse_value` reads one
numeric cell (empty or NaN: missing). Every message is ``"<file>:<line>: <what is wrong>"``.
"""

from __future__ import annotations

import csv
import itertools
import math
from collections.abc import Iterator
from pathlib import Path

from buildenv.errors import SiteError


def _rows(path: Path, separators: str = ",") -> Iterator[tuple[int, list[str]]]:
    """``(line number, cells)`` of a CSV file, header included, blank lines skipped; cells stripped.

    ``separators``: the column separators allowed (the site's files: commas); of several, the first non-blank
    line's most frequent one separates the columns (a BMS export: ``",;\\t"``).
    """
    try:
        with path.open(encoding="utf-8-sig", newline="") as handle:
            lines: Iterator[str] = iter(handle)
            separator = separators
            if len(separators) > 1:
                head: list[str] = []
                for text in lines:  # blank lines, then the first that is not
                    head.append(text)
                    if text.strip():
                        break
                separator = max(separators, key=(head[-1] if head else "").count)
                lines = itertools.chain(head, lines)
            reader = csv.reader(lines, delimiter=separator)
            try:
                for cells in reader:
                    if not cells or (len(cells) == 1 and not cells[0].strip()):
                        continue  # blank line
                    yield reader.line_num, [c.strip() for c in cells]
            except csv.Error as exc:
                raise SiteError(f"{path}:{reader.line_num}: malformed CSV: {exc}") from exc
    except UnicodeDecodeError as exc:
        raise SiteError(
            f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start}); save the export as UTF-8 CSV"
        ) from exc
    except OSError as exc:
        raise SiteError(f"{path}: cannot read: {exc}") from exc


def _check_width(path: Path, line: int, cells: list[str], columns: tuple[str, ...]) -> None:
    if len(cells) != len(columns):
        many = "too many" if len(cells) > len(columns) else "too few"
        raise SiteError(f"{path}:{line}: {many} columns: {len(cells)} instead of {len(columns)} ({','.join(columns)})")


def _separator_hint(header: list[str]) -> str:
    if len(header) == 1 and ";" in header[0]:
        return " (columns must be separated by commas, this file uses ';')"
    if len(header) == 1 and "\t" in header[0]:
        return " (columns must be separated by commas, this file uses tabs)"
    return ""


def _parse_value(path: Path, line: int, column: str, text: str, *, missing_ok: bool = True) -> float:
    """A cell as float; empty or NaN -> NaN (when ``missing_ok``)."""
    if text == "" or text.lower() == "nan":
        if missing_ok:
            return math.nan
        raise SiteError(f"{path}:{line}: {column} is missing: every day needs the value in force")
    try:
        if "_" in text:  # float() reads '1_0' as 10
            raise ValueError(text)
        value = float(text)
    except ValueError:
        blank = ", leave the cell empty for a missing value" if missing_ok else ""
        raise SiteError(f"{path}:{line}: {column}: {text!r} is not a number (use '.' as decimal mark{blank})") from None
    if not math.isfinite(value):
        raise SiteError(f"{path}:{line}: {column}: {text!r} is not a finite number")
    return value
