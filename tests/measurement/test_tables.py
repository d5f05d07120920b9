"""The one table formatter (measurement/tables.py)."""

import math
from dataclasses import dataclass

from measurement.tables import Column, format_table, value

COLUMNS = (
    Column("name", 6, value("name"), align="<"),
    Column("ratio", 6, value("ratio", ".2f")),
    Column("error", 7, value("error", ".1f", scale=100, unit="%")),
    Column("note", 0, value("note"), align="<", gap=2),
)


def test_headers_and_cells_share_each_column_width():
    rows = [dict(name="a", ratio=0.25, error=0.031, note="*"), dict(name="bb", ratio=1.5, error=0.5, note="")]
    assert format_table(rows, COLUMNS).splitlines() == [
        "name    ratio   error  note",
        "a        0.25    3.1%  *",
        "bb       1.50   50.0%",  # trailing spaces dropped
    ]


def test_a_missing_value_leaves_its_cell_empty_and_nan_is_printed():
    lines = format_table([dict(name="median", error=math.nan)], COLUMNS, header=False).splitlines()
    assert lines == ["median           nan%"]


def test_a_long_cell_pushes_the_line_right_and_objects_are_rows_too():
    @dataclass
    class Row:
        name: str
        ratio: float
        error: float
        note: str = ""

    line = format_table([Row("longer name", 0.5, 0.1)], COLUMNS, header=False)
    assert line == "longer name   0.50   10.0%"
    assert format_table([], COLUMNS) == "name    ratio   error  note"
