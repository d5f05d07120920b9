"""CSV recordings: a table of frames under ``#`` header lines, its reader and its writer.

``#`` header lines of ``key=value`` (nx, ny, pitch, thickness, optional
poisson_ratio and sensor_size, units, description, optional ``columns=seq,t``;
an irregular layout has ``taxels`` and ``positions=x,y;x,y;...`` metres instead
of nx and ny),
then one frame per row: ``t, v0, v1, ...`` (or ``seq, t, v0, v1, ...``).

:func:`tactile_viewer.io.files.load` and :func:`tactile_viewer.io.files.save`
reach :func:`load_csv` and :func:`save_csv` by the file's suffix. No Qt.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from solver import SensorGrid

from .recording import (
    FORCE_EXPORT,
    MAX_RECORDING_BYTES,
    MAX_TAXELS,
    Recording,
    RecordingError,
    bytes_text,
    checked_frames,
    declared_grid,
    geometry_fields,
    unit_scale,
)

__all__ = ["load_csv", "save_csv", "csv_geometry_header"]

# The longest line a CSV recording needs, in characters: 'positions=' of MAX_TAXELS x,y pairs of
# repr floats (at most 50 characters a pair). A line is read no further than this.
_MAX_CSV_LINE = 64 * 2**20
# Values parsed as Python floats (32 bytes each) before they are packed as float64 (8 bytes each).
_CSV_BLOCK = 2**16


def csv_geometry_header(grid: SensorGrid) -> str:
    """The ``# key=value`` lines of a CSV recording that declare ``grid`` (read by :func:`load_csv`)."""
    fields = geometry_fields(grid)
    positions = fields.pop("positions", None)
    lines = [f"# {key}={value!r}\n" for key, value in fields.items()]
    if positions is not None:
        lines.append("# positions=" + ";".join(f"{x!r},{y!r}" for x, y in positions.tolist()) + "\n")
    return "".join(lines)


def load_csv(path) -> Recording:
    """Read a CSV recording (:func:`tactile_viewer.io.files.load` checks the path and names errors)."""
    # What bounds the memory, whatever the file says: a line is read no further than _MAX_CSV_LINE
    # characters (reading one peaks at twice that), a row's values are counted before they are parsed
    # (at most MAX_TAXELS + 2), and rows are packed as float64, 8 bytes a value where the file spent at
    # least 2 characters ('0,'): at most four times the file (twice that while the blocks are joined)
    # and at most MAX_RECORDING_BYTES. 'positions' holds at most MAX_TAXELS pairs.
    meta, blocks, block, width, held, cut = {}, [], [], None, 0, False
    with open(path, encoding="utf-8") as handle:
        for number, line in enumerate(iter(lambda: handle.readline(_MAX_CSV_LINE + 1), ""), start=1):
            if len(line) > _MAX_CSV_LINE and not line.endswith("\n"):
                raise RecordingError(f"{path}: line {number} is longer than {_MAX_CSV_LINE} characters: "
                                     "not a recording")
            text = line.strip()
            if not text:
                continue
            if text.startswith("#"):
                key, sep, value = text[1:].partition("=")
                if sep:
                    meta[key.strip()] = value.strip()
                continue
            if not line.endswith("\n"):
                # the last row has no line end: the file was cut short, perhaps inside a value (1.25
                # read as 1.2); it is left out, and the recording says it was cut
                cut = True
                continue
            count = text.count(",") + text.count(";") + 1
            if count > MAX_TAXELS + 2:
                raise RecordingError(f"{path}: line {number} holds {count} values, more than a frame of the "
                                     f"largest skin this viewer opens ({MAX_TAXELS} taxels) has")
            try:
                row = [float(v) for v in text.replace(";", ",").split(",")]
            except ValueError:
                if text.replace(" ", "").startswith("frame,t,node,"):
                    raise RecordingError(f"{path}: {FORCE_EXPORT}") from None
                raise RecordingError(f"{path}: line {number}: not a row of numbers: {text[:60]!r}") from None
            if width is None:
                width = len(row)
            elif len(row) != width:
                raise RecordingError(f"{path}: line {number}: {len(row) - 1} values, "
                                     f"earlier rows have {width - 1}")
            held += width
            if held * 8 > MAX_RECORDING_BYTES:
                raise RecordingError(f"{path}: line {number}: the frames would take more than the "
                                     f"{bytes_text(MAX_RECORDING_BYTES)} this viewer loads (long "
                                     "recordings belong in MCAP, which opens lazily)")
            block += row
            if len(block) >= _CSV_BLOCK:
                blocks.append(np.array(block, dtype=float))
                block = []
    if width is None:
        if not meta:
            raise RecordingError(f"{path}: empty: a CSV recording has '# key=value' header lines (nx, ny, "
                                 "pitch, thickness) and then one frame per row (t, v0, v1, ...)")
        raise RecordingError(f"{path}: no frames" + (" (its one row has no line end: cut short)" if cut
                                                     else ""))
    table = np.concatenate([*blocks, np.array(block, dtype=float)]).reshape(-1, width)
    columns = meta.get("columns", "t")
    if columns not in ("t", "seq,t"):
        raise RecordingError(f"{path}: columns must be 't' or 'seq,t', got {columns!r}")
    first = 2 if columns == "seq,t" else 1
    positions = None
    if "positions" in meta:
        pairs = meta["positions"].count(";") + 1
        if pairs > MAX_TAXELS + 1:  # one more: a trailing ';'
            raise RecordingError(f"{path}: 'positions' holds {pairs} x,y pairs, more than the {MAX_TAXELS} "
                                 "taxels of the largest skin this viewer opens")
        try:
            positions = [[float(v) for v in pair.split(",")] for pair in meta["positions"].split(";")
                         if pair.strip()]  # a trailing ';' of a hand-edited file is no pair
        except ValueError:
            raise RecordingError(f"{path}: positions must be x,y pairs of metres separated by ';'") from None
    grid = declared_grid(meta, path, positions, width=table.shape[1] - first)
    frames = checked_frames(table[:, first:], grid, path, unit_scale(meta.get("units", "Pa"), path))
    seq = table[:, 0] if first == 2 else None
    try:
        return Recording(grid, frames, table[:, first - 1], None, meta.get("description", ""), seq,
                         truncated=cut)
    except ValueError as exc:
        raise RecordingError(f"{path}: {exc}") from None


def save_csv(recording: Recording, path) -> Path:
    """Write ``recording`` as ``.csv``: frames and geometry, nu included (see
    :func:`tactile_viewer.io.files.save`)."""
    path = Path(path)
    buffer = io.StringIO()
    buffer.write(csv_geometry_header(recording.grid))
    buffer.write("# units=Pa\n")
    if recording.description:
        buffer.write(f"# description={' '.join(recording.description.split())}\n")
    columns = [recording.t, recording.frames]
    if recording.seq is not None:
        buffer.write("# columns=seq,t\n")
        columns.insert(0, recording.seq)
    np.savetxt(buffer, np.column_stack(columns), delimiter=",", fmt="%.9g")
    path.write_text(buffer.getvalue(), encoding="utf-8")
    return path
