"""The reader of MCAP recordings: :func:`open_recording`, lazily, and what is lost in a damaged file. No Qt.

:func:`open_recording` reads a file lazily: its metadata and an index at open
(through a :class:`~tactile_viewer.io.mcap_scan.Scan`), frames a chunk at a
time when indexed (:class:`~tactile_viewer.io.mcap_frames.FrameTable`). A file
cut short is complete up to its last whole chunk; of a damaged one, what is
good is read and what is not is said, a sentence each.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .mcap_format import MAGIC, MESSAGE_HEAD, RAW_DTYPES, VERSIONS
from .mcap_frames import Chunk, FrameTable, Index
from .mcap_scan import Scan
from .recording import MAX_TAXELS, Recording, RecordingError, StressCalibration, Tare, grid_from_fields
from .ros2_message import FRAME_ID, FrameMessage

__all__ = ["open_recording"]


def open_recording(path) -> Recording:
    """Open an MCAP recording lazily: metadata and an index now, frames on demand.

    A file cut short (a kill, a full disk) opens with every frame of its
    complete chunks. A damaged file opens with what is good and says what is
    not in :attr:`~tactile_viewer.io.recording.Recording.damage`: frames of a
    chunk that fails its checksum are left out (their numbers and times said
    when the chunk's record keeps them), a tare whose record is damaged or
    lost is said with the frames it may offset. Records around damage are
    found again by looking forward for the next record that checks out.

    Raises
    ------
    RecordingError
        Naming the file and what is wrong (not MCAP, missing or damaged
        metadata, sizes the file cannot hold).
    """
    path = Path(path)
    with open(path, "rb") as handle:
        if handle.read(len(MAGIC)) != MAGIC:
            raise RecordingError(f"{path}: not an MCAP recording (no MCAP magic at the start)")
        scan = Scan(path, handle).run()
        return _opened(scan)


def _opened(scan: Scan) -> Recording:
    path = scan.path
    if scan.cut and not scan.chunks:
        raise RecordingError(f"{path}: no frames (the file was cut short before its first chunk)")
    ours = [meta for meta in scan.metadata if meta.name.startswith("tactile-viewer.")]
    info = next((meta for meta in reversed(ours) if meta.name == "tactile-viewer.recording"), None)
    if info is None:
        raise RecordingError(f"{path}: missing metadata 'tactile-viewer.recording' (not a recording of "
                             "this viewer)")
    version = info.fields.get("version")
    if info.checksum == "bad":
        raise RecordingError(f"{path}: metadata 'tactile-viewer.recording' is damaged (checksum mismatch)")
    if version not in VERSIONS:
        raise RecordingError(f"{path}: recording version {version!r} is not read by this viewer "
                             f"(it reads {', '.join(VERSIONS)})")
    # version 1 wrote no checksums; from version 2 on every record of ours carries one
    good = [meta for meta in ours if meta.checksum == "good" or (version == "1" and meta.checksum == "none")]
    if version != "1":
        for meta in ours:
            if meta not in good:
                meta.checksum = "bad"
    metadata = {meta.name: meta.fields for meta in good}
    for name in ("geometry", "calibration"):
        name = f"tactile-viewer.{name}"
        if name not in metadata:
            damaged = any(meta.name == name for meta in ours)
            raise RecordingError(f"{path}: metadata {name!r} is damaged (checksum mismatch)" if damaged else
                                 f"{path}: missing metadata {name!r} (not a recording of this viewer)")
    info = metadata["tactile-viewer.recording"]
    dtype = info.get("dtype")
    if dtype not in RAW_DTYPES:
        raise RecordingError(f"{path}: 'dtype' must be one of {sorted(RAW_DTYPES)}, got {dtype!r}")
    try:
        taxels = int(info.get("taxels", ""))
    except ValueError:
        raise RecordingError(f"{path}: 'taxels' must be a whole number, got {info.get('taxels')!r}") from None
    if not 1 <= taxels <= MAX_TAXELS:
        raise RecordingError(f"{path}: 'taxels' must be in [1, {MAX_TAXELS}], got {taxels}")
    geometry = _loads(metadata["tactile-viewer.geometry"], "geometry", path)
    try:
        grid = grid_from_fields(width=taxels, **geometry)
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"{path}: impossible geometry: {exc}") from None
    # version 3: a ROS 2 message per frame; before, the raw values alone
    try:
        message = (FrameMessage.legacy(taxels, dtype) if version in ("1", "2") else
                   FrameMessage.ros2(taxels, dtype, info.get("frame_id", FRAME_ID)))
    except ValueError as exc:
        raise RecordingError(f"{path}: metadata 'tactile-viewer.recording': {exc}") from None
    tares = [meta for meta in ours if meta.name == "tactile-viewer.tare"]
    chunk_records = [meta for meta in good if meta.name == "tactile-viewer.chunk"]
    chunks, log_times, tares, damage, lost = _assemble(scan, chunk_records, tares,
                                                       MESSAGE_HEAD + message.size, version)
    try:
        calibration = StressCalibration.from_fields(
            taxels, **_loads(metadata["tactile-viewer.calibration"], "calibration", path),
            tares=[Tare.from_fields(taxels, **_loads(fields, "tare", path)) for fields in tares])
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"{path}: calibration: {exc}") from None
    if not len(log_times):
        raise RecordingError(f"{path}: no frames" + (" (the file was cut short before its first chunk)"
                                                     if scan.cut and not damage else "")
                             + "".join(f"; {what}" for what in damage))
    index = Index(path, chunks, log_times, metadata, scan.cut, damage, scan.data_end)
    frames = FrameTable(index, message, calibration)
    times = log_times.astype(np.int64)
    t = (times - times[0]) * 1e-9
    try:
        return Recording(grid, frames, t, None, info.get("description", ""), received=times[0] * 1e-9,
                         truncated=scan.cut, damage=damage, lost_spans=lost)
    except ValueError as exc:
        raise RecordingError(f"{path}: {exc}") from None


def _assemble(scan: Scan, metadata: list, tares: list, size: int, version: str):
    """Chunks, receive times, tares (numbered as loaded), what is lost and when, from a scan."""
    scan.attach_records(metadata)
    # kept: (chunk position, written number of its first frame or None, count, loaded number)
    chunks, log_times, lost, kept, gaps = [], [], [], [], []
    loaded = written = 0
    certain = True  # the written number of the next frame is known
    for found in sorted(scan.chunks.values(), key=lambda chunk: chunk.position):
        record = found.record
        first = record["first"] if record else (written if certain else None)
        if record and certain and first > written:  # a chunk and its record both lost
            gaps.append((written, first - written))
        frames = scan.frames(found, size, version)
        if frames is None:  # the chunk fails its CRC
            count = record["frames"] if record else None
            exact = bool(count) and found.times_recorded()
            lost.append((found.position, first, count,
                         found.index[1][[0, -1]] if exact else (found.start, found.stop), exact))
            certain = count is not None and first is not None
            written = first + count if certain else written
            continue
        offsets, times = frames
        if not len(offsets):
            continue
        chunks.append(Chunk(found.data_offset, found.length, found.crc, loaded, offsets))
        log_times.append(times)
        kept.append((found.position, first, len(offsets), loaded))
        certain = first is not None
        written = first + len(offsets) if certain else written
        loaded += len(offsets)
    times = np.concatenate(log_times) if log_times else np.zeros(0, np.uint64)
    origin = int(times[0]) if len(times) else 0
    damage = [_lost(*chunk, origin) for chunk in lost]
    spans = tuple(((int(span[0]) - origin) * 1e-9, (int(span[-1]) - origin) * 1e-9)
                  for _position, _first, _count, span, _exact in lost)
    for first, count in gaps:
        damage.append(f"frames {first} to {first + count - 1} as recorded are lost: their chunk is damaged "
                      "beyond finding")
    tares = _renumbered(tares, kept, scan, damage)
    return tuple(chunks), times, tares, tuple(damage), spans


def _lost(position, first, count, span, exact, origin) -> str:
    start, stop = ((int(end) - origin) * 1e-9 for end in (span[0], span[-1]))
    when = (f"t {start:.3f} to {stop:.3f} s" if start >= 0 else  # the first frames kept come after them
            f"{-start:.3f} to {-stop:.3f} s before the first frame kept")
    if not exact:
        when = "about " + when  # the chunk header's span, under no checksum
    if count is None:
        what = f"an unknown number of frames ({when})"
    elif first is None:
        what = f"{count} frames ({when})"
    else:
        what = f"frames {first} to {first + count - 1} as recorded ({count} frames, {when})"
    return f"{what} are lost: their chunk at byte {position} is damaged"


def _renumbered(tares: list, kept: list, scan: Scan, damage: list) -> list:
    # tares name the frame they apply from as numbered when written; frames lost before it move it.
    # A tare that cannot be placed, or whose record is damaged or lost, is said
    def loaded_after(position):  # the first frame kept from a chunk written after ``position``
        return next((loaded for at, _first, _count, loaded in kept if at > position), None)
    def offset_from(position):
        after = loaded_after(position)
        return f": frames from {after} on may be offset" if after is not None else ""
    known = [(first, count) for _at, first, count, _loaded in kept if first is not None]
    uncounted = len(known) < len(kept)
    placed = []
    for meta in tares:
        if meta.checksum == "bad":
            damage.append(f"the tare recorded at byte {meta.position} is damaged and not applied"
                          + offset_from(meta.position))
            continue
        fields = dict(meta.fields)
        try:
            written = int(json.loads(fields["from_frame"]))
        except (KeyError, ValueError, TypeError):
            placed.append(fields)  # Tare.from_fields says what is wrong, naming the file
            continue
        if uncounted and not any(first <= written < first + count for first, count in known):
            damage.append(f"the tare from frame {written} as recorded may apply from the wrong frame "
                          "(frames before it were lost in numbers not known)")
        fields["from_frame"] = json.dumps(sum(min(max(written - first, 0), count) for first, count in known))
        placed.append(fields)
    # each record of a chunk counts the tares written so far: fewer found means some are lost
    counted = [(chunk.position, chunk.record["tares"]) for chunk in scan.chunks.values() if chunk.record]
    missing = max((tares for _at, tares in counted), default=0) - len(tares)
    if missing > 0:
        at = min(at for at, count in counted if count > len(tares))
        damage.append(f"{missing} tare record{'s are' if missing > 1 else ' is'} lost" + offset_from(at - 1))
    return placed


def _loads(fields: dict, name: str, path) -> dict:
    try:
        return {key: json.loads(value) for key, value in fields.items() if key != "crc32"}
    except (ValueError, RecursionError):
        raise RecordingError(f"{path}: metadata {name!r} is not JSON values") from None

