"""A flight's rows as CSV: one row per control step, written as it happens.

Each row is flushed when written, so a crash, a killed process or Ctrl-C loses nothing that
was flown.  The columns carry their units in their names.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
import operator
from pathlib import Path

from bfsitl.errors import BfsitlError
from bfsitl.mission.flight_row import COLUMNS, FlightRow


def _cell(value: object) -> str:
    if isinstance(value, float):  # most cells: asked first (a bool is no float)
        # Unknown values (no simulated truth on a real board) are empty cells, not "nan".
        return f"{value:.4f}" if math.isfinite(value) else ""
    if isinstance(value, bool):
        return "1" if value else "0"
    return str(value)


_values = operator.attrgetter(*COLUMNS)


def _cells(row: FlightRow) -> list[str]:
    """:func:`_cell` of every column, inlined for the common cell (a finite float): a row is
    written every control step, and one call per cell was a fifth of the step's recording."""
    isfinite = math.isfinite
    return [
        f"{value:.4f}" if type(value) is float and isfinite(value) else _cell(value)
        for value in _values(row)
    ]


class CsvFlightLog:
    """Writes :class:`FlightRow` lines to a CSV file, flushed row by row."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file: io.TextIOWrapper | None = self.path.open("w", newline="")
        except OSError as exc:
            raise BfsitlError(f"cannot write the flight log {self.path}: {exc}") from exc
        self._writer = csv.writer(self._file)
        self._writer.writerow(COLUMNS)
        self._file.flush()
        self.rows_written = 0

    def write(self, row: FlightRow, sample: object = None) -> None:
        if self._file is None:
            raise BfsitlError(f"flight log {self.path} is closed")
        self._writer.writerow(_cells(row))
        self._file.flush()
        self.rows_written += 1

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> CsvFlightLog:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def read_flight_log(path: str | Path) -> list[dict[str, str]]:
    """The rows of a log as dicts of strings (for tools and tests)."""
    with Path(path).open(newline="") as file:
        reader = csv.DictReader(file)
        if reader.fieldnames is None or tuple(reader.fieldnames) != COLUMNS:
            raise BfsitlError(f"{path} is not a bfsitl flight log (columns {reader.fieldnames})")
        return list(reader)


def _typed(name: str, text: str) -> object:
    kind = _KINDS[name]
    if kind == "bool":
        return text == "1"
    if kind == "int":
        return int(text)
    if kind == "str":
        return text
    return float(text) if text else math.nan


#: Each column's type, from FlightRow's annotations (strings: ``from __future__``).
_KINDS = {f.name: str(f.type) for f in dataclasses.fields(FlightRow)}


def read_flight_rows(path: str | Path) -> list[FlightRow]:
    """A log read back as :class:`FlightRow` (empty cells are NaN): what the analysers
    read (``bfsitl log check flight.csv``)."""
    try:
        rows = read_flight_log(path)
        return [
            FlightRow(**{name: _typed(name, row[name]) for name in COLUMNS})  # type: ignore[arg-type]
            for row in rows
        ]
    except (OSError, ValueError, KeyError, UnicodeDecodeError, csv.Error) as exc:
        raise BfsitlError(f"cannot read the flight log {path}: {exc}") from exc
