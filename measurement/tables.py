"""The one plain-text table formatter of the measurements.

A table is rows (mappings or objects with attributes) and columns
(:class:`Column`: a header, a width and the function that writes one row's cell). Every table the
measurements print (per case, kernels against media, speed against accuracy,
large skins, the functionals' summary) is :func:`format_table` over its own
columns.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

__all__ = ["Column", "format_table", "value", "print_report", "NORMAL", "TANGENTIAL", "DIRECTION"]


@dataclass(frozen=True)
class Column:
    """One column of a table.

    Attributes
    ----------
    header : str
    width : int
        Characters the header and the cells are padded to; a longer cell
        pushes the rest of its line right, it is never cut.
    cell : callable
        ``row -> str``, the row's text in this column (see :func:`value`).
    align : {">", "<"}
        Right (default, numbers) or left (names).
    gap : int
        Spaces before the column (default 1).
    """

    header: str
    width: int
    cell: Callable[[object], str]
    align: str = ">"
    gap: int = 1


def format_table(rows, columns, *, header: bool = True) -> str:
    """``rows`` under ``columns``' headers, one line each (``header=False``: the rows alone,
    for a table printed a row at a time); trailing spaces dropped."""
    lines = [_line([c.header for c in columns], columns)] if header else []
    lines += [_line([c.cell(row) for c in columns], columns) for row in rows]
    return "\n".join(lines)


def print_report(cases: str, title: str, summary: str, *, quiet: bool = False) -> None:
    """Print a set's per-case table (unless ``quiet``), then the line naming the set and its summary."""
    if not quiet:
        print(cases)
        print()
    print(title)
    print(summary)


def _line(cells, columns) -> str:
    text = "".join(" " * c.gap * (k > 0) + f"{cell:{c.align}{c.width}}"
                   for k, (cell, c) in enumerate(zip(cells, columns, strict=True)))
    return text.rstrip()


def value(key: str, spec: str = "", *, scale: float = 1.0, unit: str = "") -> Callable[[object], str]:
    """A cell writing ``row[key]`` (or ``row.key``) times ``scale`` in the format ``spec``, then ``unit``.

    A row without ``key`` (or with None there) gets an empty cell: a median row
    under per-case columns, say.
    """

    def cell(row) -> str:
        found = row.get(key) if isinstance(row, Mapping) else getattr(row, key, None)
        if found is None:
            return ""
        return f"{found * scale if scale != 1 else found:{spec}}{unit}"

    return cell


# the median errors every table shows (solver.metrics.compare): normal and tangential totals
# relative to |F|, direction error in degrees
NORMAL = Column("normal", 7, value("normal_total", ".2f", scale=100, unit="%"))
TANGENTIAL = Column("tang", 6, value("tangential_total", ".1f", scale=100, unit="%"))
DIRECTION = Column("dir deg", 7, value("direction_deg", ".1f"))
