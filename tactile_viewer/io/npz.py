"""NPZ recordings (zips of .npy arrays): the reader, which checks the sizes they declare, and the writer.

NPZ keys: ``frames (T, m)`` pascals, ``t (T,)`` seconds, ``nx``, ``ny`` (or
``taxels`` and ``positions`` for an irregular layout), ``pitch``, ``thickness``
(metres), optional ``poisson_ratio`` (the elastomer's nu, default 0.5),
optional ``sensor_size`` (side of a square taxel, metres, default 0: point
sensors), optional ``positions (m, 2)``, optional ``truth_forces (T, m, 3)``
newtons, optional ``seq (T,)`` sequence numbers of live frames, ``units``,
``description``. Live recordings of earlier versions, written as NPZ chunks
``chunkNNNNNN_frames``, ``chunkNNNNNN_t``, ``chunkNNNNNN_seq`` and never
closed, load as one recording.

:func:`tactile_viewer.io.files.load` and :func:`tactile_viewer.io.files.save`
reach :func:`load_npz` and :func:`save_npz` by the file's suffix. No Qt.
"""

from __future__ import annotations

import io
import math
import zipfile
from pathlib import Path

import numpy as np

from .recording import (
    FORCE_EXPORT,
    MAX_RECORDING_BYTES,
    MAX_TAXELS,
    Recording,
    RecordingError,
    bytes_text,
    checked_frames,
    checked_shape,
    declared_grid,
    geometry_fields,
    unit_scale,
)

__all__ = ["load_npz", "save_npz"]

# -- sizes an archive declares (beside MAX_RECORDING_BYTES, which every format shares) --------------
# How many times a compressed NPZ member may expand. Deflate cannot pass about 1032:1, which only
# long runs of one byte reach. Measured with np.savez_compressed (zlib level 6): sensor noise 1.1:1,
# ADC counts stored as floats 3.5:1, 8 of 256 taxels pressed 30 to 67:1, a constant frame 660:1,
# all-zero 16x16 frames 982:1 (1000 frames) rising to 1028:1 (100000 frames). Past 1000:1 a member
# is one repeated byte: a bomb, or an idle skin, which _EXPANSION_ALLOWANCE lets load while small.
_MAX_EXPANSION = 1000
# Bytes, all members together, that may expand more than _MAX_EXPANSION times: an all-zero
# recording of up to 64 MiB (32768 frames of 16x16) loads, a bomb is refused before it is inflated.
_EXPANSION_ALLOWANCE = 64 * 2**20
# A field that is one number or one text (a megabyte is no description).
_MAX_FIELD_BYTES = 2**20
# np.load's own limit on a .npy header (its max_header_size), here checked before the header is read.
_MAX_NPY_HEADER = 10_000
# The NPZ fields that are arrays of numbers; every other field the loader reads is a single value.
_NPZ_ARRAYS = ("frames", "t", "seq", "truth_forces", "positions")
_NPZ_SINGLES = ("nx", "ny", "taxels", "pitch", "thickness", "poisson_ratio", "sensor_size", "units",
                "description")


def load_npz(path) -> Recording:
    """Read an NPZ recording (:func:`tactile_viewer.io.files.load` checks the path and names errors)."""
    with open(path, "rb") as handle:
        start = handle.read(24)
    # a zip (even a damaged one) or a bare .npy goes on to numpy, whose reasons say more
    if not start.startswith((b"PK", b"\x93NUMPY")):
        raise RecordingError(f"{path}: not an NPZ archive (an NPZ is a zip of .npy arrays; this file starts "
                             f"with {start!r})")
    # our own handle, closed whatever happens: np.load leaves a file it opened itself open when
    # the zip inside is broken
    with open(path, "rb") as handle:
        try:
            data = np.load(handle, allow_pickle=False)
        except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
            raise RecordingError(f"{path}: not a readable NPZ archive ({exc})") from None
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise RecordingError(f"{path}: not an NPZ archive (a single array, as .npy writes)")
        return _read(data, path)


def _read(data, path) -> Recording:
    # the recording in an opened archive, which it closes
    with data:
        _check_member_names(data, path)
        # the members each field is read from: its own, or those of the chunks of a live recording
        parts = ({key: [key] for key in ("frames", "t", "seq") if key in data} if "frames" in data
                 else _joined_chunks(data))
        if "forces" in data:  # a recording's known forces are 'truth_forces'
            raise RecordingError(f"{path}: {FORCE_EXPORT}")
        if "frames" not in parts:
            raise RecordingError(f"{path}: missing 'frames'")
        parts.update({key: [key] for key in (*_NPZ_SINGLES, "positions", "truth_forces") if key in data})
        shapes = _npz_shapes(data, parts, path)  # from the headers alone: nothing is read before this
        declared = shapes["frames"]
        grid = declared_grid(data, path, data["positions"] if "positions" in data else None,
                     width=declared[1] if len(declared) == 2 else None)
        count = checked_shape(declared, grid, path)
        for key, shape in (("t", (count,)), ("seq", (count,)), ("truth_forces", (count, grid.size, 3))):
            if key in shapes and shapes[key] != shape:
                raise RecordingError(f"{path}: {key} must have shape {shape}, got {shapes[key]}")
        arrays = {key: data[names[0]] if len(names) == 1 else np.concatenate([data[name] for name in names])
                  for key, names in parts.items() if key in ("frames", "t", "seq")}
        units = str(data["units"]) if "units" in data else "Pa"
        frames = checked_frames(np.asarray(arrays["frames"], dtype=float), grid, path,
                                unit_scale(units, path))
        t = np.asarray(arrays["t"], dtype=float) if "t" in arrays else np.arange(len(frames), dtype=float)
        seq = arrays.get("seq")
        truth = np.asarray(data["truth_forces"], dtype=float) if "truth_forces" in data else None
        description = str(data["description"]) if "description" in data else ""
    try:
        return Recording(grid, frames, t, truth, description, seq)
    except ValueError as exc:
        raise RecordingError(f"{path}: {exc}") from None


def _npz_shapes(data, parts, path) -> dict:
    """The shape of each field of ``parts`` (field: its members), from the members' .npy headers alone.

    Every member is checked before any is read: an array, not pickled objects, of what its field
    holds, whose declared size fits the ceilings above (and MAX_RECORDING_BYTES), the file and the zip's
    directory.

    Raises
    ------
    RecordingError
        Naming the member and the rule it breaks.
    """
    file_size = Path(path).stat().st_size
    loaded = expanding = 0  # bytes the arrays will take; bytes of members expanding past _MAX_EXPANSION
    shapes = {}
    for field, names in parts.items():
        found = []
        for name in names:
            info, shape, dtype, header = _npy_header(data, name, path)
            values = math.prod(shape)
            stored = values * dtype.itemsize
            declares = f"{name!r} declares {_values_text(shape)} ({bytes_text(stored)})"
            if dtype.hasobject:
                raise RecordingError(f"{path}: {name!r} holds Python objects (dtype {dtype}), which only "
                                     "unpickling could read and no recording holds (allow_pickle=False)")
            if field in _NPZ_ARRAYS:
                if dtype.kind not in "biuf":
                    raise RecordingError(f"{path}: {name!r} must hold numbers, got dtype {dtype}")
                loaded += values * max(dtype.itemsize, 8)  # held as float64
            elif values != 1:
                kind = "text" if field in ("units", "description") else "number"
                raise RecordingError(f"{path}: {name!r} must be a single {kind}, got shape {shape}")
            elif stored > _MAX_FIELD_BYTES:
                raise RecordingError(f"{path}: {declares}, more than the {bytes_text(_MAX_FIELD_BYTES)} "
                                     "one field may hold")
            else:
                loaded += stored
            if field == "positions" and (len(shape) != 2 or shape[1] != 2 or shape[0] > MAX_TAXELS):
                raise RecordingError(f"{path}: 'positions' must be x, y pairs of metres (shape (m, 2), m at "
                                     f"most {MAX_TAXELS}), got shape {shape}")
            if loaded > MAX_RECORDING_BYTES:
                raise RecordingError(f"{path}: {declares}: the recording would take {bytes_text(loaded)}, "
                                     f"more than the {bytes_text(MAX_RECORDING_BYTES)} this viewer loads "
                                     "(long recordings belong in MCAP, which opens lazily)")
            member = header + stored  # what the member inflates to, were the header true
            if info.compress_type == zipfile.ZIP_STORED:
                if member > file_size:
                    raise RecordingError(f"{path}: {declares} but the file holds {bytes_text(file_size)}: "
                                         "not a recording")
            elif info.compress_size > file_size:
                raise RecordingError(f"{path}: damaged NPZ archive: its directory says {name!r} is "
                                     f"{bytes_text(info.compress_size)} compressed but the file holds "
                                     f"{bytes_text(file_size)}")
            elif member > _MAX_EXPANSION * info.compress_size:
                expanding += member
                if expanding > _EXPANSION_ALLOWANCE:
                    ratio = member / max(info.compress_size, 1)
                    raise RecordingError(f"{path}: {declares} from {bytes_text(info.compress_size)} "
                                         f"compressed, {ratio:.0f}:1, more than the {_MAX_EXPANSION}:1 any "
                                         "recording reaches: a decompression bomb, not a recording")
            if info.file_size != member or (info.compress_type == zipfile.ZIP_STORED
                                            and info.compress_size != member):
                raise RecordingError(f"{path}: damaged NPZ archive: its directory says {name!r} holds "
                                     f"{bytes_text(info.file_size)} but its array header declares "
                                     f"{bytes_text(member)}")
            found.append(shape)
        shapes[field] = _joined_shape(names, found, path)
    return shapes


def _npy_header(data, name, path):
    """``(zip info, shape, dtype, header bytes)`` of member ``name``, read without its values.

    The header's own length is bounded before the header is read: a version 2.0 header may declare
    4 GiB of itself, which np.load would read whole before its max_header_size refused it.
    """
    try:
        info = data.zip.getinfo(name)
    except KeyError:  # np.savez writes 'frames' as 'frames.npy'; NpzFile finds it by either name
        info = data.zip.getinfo(f"{name}.npy")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        # zipfile inflates a bzip2 or LZMA member a whole compressed block at a time, unbounded (a few
        # hundred bytes of bzip2 can be gigabytes of zeros): not even its header is read. numpy
        # writes members stored or deflated only.
        raise RecordingError(f"{path}: {name!r} is compressed by zip method {info.compress_type}, which "
                             "numpy never writes (only stored or deflated): not a recording")
    try:
        member = data.zip.open(info)
    except RuntimeError as exc:  # an encrypted member
        raise RecordingError(f"{path}: {name!r} cannot be read ({exc})") from None
    with member:
        prefix = member.read(8)  # the magic string and the format version
        try:
            version = np.lib.format.read_magic(io.BytesIO(prefix))
        except ValueError:
            raise RecordingError(f"{path}: {name!r} is not a NumPy array (.npy): not a recording") from None
        if version not in ((1, 0), (2, 0)):  # 3.0 is for field names only structured arrays have
            raise RecordingError(f"{path}: {name!r} is a version {version[0]}.{version[1]} .npy array, "
                                 "which no recording is")
        length_field = member.read(2 if version == (1, 0) else 4)
        length = int.from_bytes(length_field, "little")
        if length > _MAX_NPY_HEADER:
            raise RecordingError(f"{path}: {name!r} declares an array header of {length} bytes (at most "
                                 f"{_MAX_NPY_HEADER}): not a recording")
        text = member.read(length)
    read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    try:
        shape, _, dtype = read(io.BytesIO(length_field + text))
    except ValueError as exc:
        raise RecordingError(f"{path}: {name!r} has a damaged array header ({exc})") from None
    if any(size < 0 for size in shape):
        raise RecordingError(f"{path}: {name!r} has a damaged array header (shape {shape})")
    return info, shape, dtype, len(prefix) + len(length_field) + length


def _joined_shape(names, shapes, path) -> tuple:
    # the chunks of a field join along their first axis: the other axes must agree
    if len(shapes) == 1:
        return shapes[0]
    for name, shape in zip(names, shapes, strict=True):
        if not shape or shape[1:] != shapes[0][1:]:
            raise RecordingError(f"{path}: {name!r} has shape {shape} but {names[0]!r} has {shapes[0]}: "
                                 "the chunks do not join")
    return (sum(shape[0] for shape in shapes), *shapes[0][1:])


def _values_text(shape) -> str:
    count = "x".join(map(str, shape)) if len(shape) > 1 else str(math.prod(shape))
    return f"{count} value{'' if count == '1' else 's'}"


def _check_member_names(data, path):
    """Refuse an archive whose directory names a member one character away from a missing field.

    The members' contents are under the zip's checksums; their names are not. One flipped bit in
    the directory turns ``t.npy`` into ``u.npy``, and the recording would load with times 0, 1,
    2 s (``units`` read as Pa, ``positions`` as a regular grid ...). So a member that is no field
    of a recording and differs by one character from a field that is missing is a damaged name;
    and every chunk of a live recording must hold the same fields.
    """
    names = data.zip.namelist()
    chunks = sorted({name.split("_", 1)[0] for name in names if name.startswith("chunk")})
    fields = [*_NPZ_ARRAYS, *_NPZ_SINGLES, "forces"]
    fields += [f"{c}_{key}" for c in chunks for key in ("frames", "t", "seq")]
    expected = {f"{field}.npy" for field in fields}
    missing = expected - set(names)
    for name in sorted(set(names) - expected):
        for field in sorted(missing):
            if len(name) == len(field) and sum(a != b for a, b in zip(name, field, strict=True)) == 1:
                raise RecordingError(f"{path}: member {name!r} is no field of a recording and {field!r} is "
                                     "missing: the archive's directory is damaged (one character of a name "
                                     "changed)")
    for key in ("t", "seq"):
        holding = [c for c in chunks if f"{c}_{key}.npy" in names]
        if holding and len(holding) != len(chunks):
            lacking = sorted(set(chunks) - set(holding))
            raise RecordingError(f"{path}: chunk(s) {', '.join(lacking)} have no {key!r} while the others "
                                 "have it: the archive is damaged")


def _joined_chunks(data) -> dict:
    # a live recording cut off before it was closed: for each field every chunk holds, its members in order
    names = sorted({name.split("_", 1)[0] for name in data.files if name.startswith("chunk")})
    if not names:
        return {}
    return {key: [f"{name}_{key}" for name in names] for key in ("frames", "t", "seq")
            if all(f"{name}_{key}" in data for name in names)}


def save_npz(recording: Recording, path) -> Path:
    """Write ``recording`` as ``.npz``: everything it holds (:func:`tactile_viewer.io.files.save`)."""
    path = Path(path)
    fields = geometry_fields(recording.grid)
    extra = {} if recording.truth_forces is None else {"truth_forces": recording.truth_forces}
    if recording.seq is not None:
        extra["seq"] = recording.seq
    fields.setdefault("positions", recording.grid.positions)
    # through a handle: np.savez would append ".npz" to a name ending ".NPZ"
    with open(path, "wb") as handle:
        np.savez_compressed(handle, frames=recording.frames, t=recording.t, units="Pa",
                            description=recording.description, **fields, **extra)
    return path
