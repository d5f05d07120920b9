"""The MCAP reader (tactile_viewer/io/mcap_reader.py, its scan mcap_scan.py): files cut short at any
byte, foreign files, declared sizes, damage anywhere (chunks, their indexes, metadata, lengths) said and
read past, version 1 files."""

import struct
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import CompressionType, Writer

from tactile_viewer.io.files import load
from tactile_viewer.io.mcap_format import CHUNK_HEAD, MAGIC, RECORD, metadata_checksum
from tactile_viewer.io.mcap_reader import open_recording
from tactile_viewer.io.mcap_writer import Recorder
from tactile_viewer.io.recording import RecordingError, Tare
from tests.tactile_viewer.io.test_mcap_writer import record
from tests.tactile_viewer.skins import frames_for, grid32

# -- files cut short -------------------------------------------------------------------------------

def test_a_file_cut_at_any_byte_opens_with_every_complete_chunk(tmp_path):
    # a kill or a full disk leaves the file ended at some byte: whatever byte, the file opens with
    # exactly the frames of the chunks that were complete, and nothing else
    stress = frames_for(30, seed=5)  # fixed seed
    path = tmp_path / "whole.mcap"
    recorder = Recorder(path, grid32(), flush_interval=0.35, dtype="float64")
    ends = []  # (file size, frames in complete chunks) after each chunk
    for k in range(30):
        recorder.add(k, k / 10, stress[k])
        recorder.drain()
        if recorder.written and (not ends or ends[-1][1] != recorder.written):
            ends.append((path.stat().st_size, recorder.written))
    recorder.close()
    data = path.read_bytes()
    cut_path = tmp_path / "cut.mcap"
    for cut in range(len(data) - 1, 8, -7):
        cut_path.write_bytes(data[:cut])
        complete = max((frames for size, frames in ends if size <= cut), default=0)
        try:
            loaded = load(cut_path)
        except RecordingError as error:
            assert complete == 0 and "no frames" in str(error)
            continue
        assert len(loaded) >= complete  # a chunk whose index was cut off is walked instead
        np.testing.assert_array_equal(loaded.frames[:], stress[:len(loaded)])
        np.testing.assert_array_equal(loaded.sequence(), np.arange(len(loaded)))




def test_a_chunk_without_its_index_in_the_middle_is_read_from_its_own_records(tmp_path):
    stress = frames_for(30, seed=11)  # fixed seed
    path = tmp_path / "noindex.mcap"
    record(path, stress, dtype="float64")
    index = load(path).frames._index
    data = bytearray(path.read_bytes())
    second = index.chunks[1]
    # the record after chunk 1's records is its message index: an unknown opcode hides it
    at = second.data_offset + second.length
    assert data[at] == 0x07
    data[at] = 0x7F
    path.write_bytes(bytes(data))
    loaded = load(path)
    np.testing.assert_array_equal(loaded.frames[:], stress)
    np.testing.assert_array_equal(loaded.sequence(), np.arange(30) + 1000)
    assert [c.first for c in loaded.frames._index.chunks] == [c.first for c in index.chunks]


@pytest.mark.parametrize("where", ["the last chunk's frames", "the last chunk's header"])
def test_a_torn_last_chunk_leaves_the_chunks_before_it(tmp_path, where):
    # a power cut or a torn page: the file has its length, but the last chunk holds zeros
    stress = frames_for(30, seed=12)  # fixed seed
    path = tmp_path / "torn.mcap"
    record(path, stress, dtype="float64", close=False)
    chunks = load(path).frames._index.chunks
    last = chunks[-1]
    data = bytearray(path.read_bytes())
    start = last.data_offset if where == "the last chunk's frames" else last.data_offset - 40
    data[start:] = bytes(len(data) - start)
    path.write_bytes(bytes(data))
    loaded = load(path)
    assert loaded.truncated and len(loaded) == last.first
    np.testing.assert_array_equal(loaded.frames[:], stress[:last.first])


# -- declared sizes and foreign files ---------------------------------------------------------------

def metadata_record(name, fields):
    body = struct.pack("<I", len(name)) + name.encode()
    pairs = b"".join(struct.pack("<I", len(k)) + k.encode() + struct.pack("<I", len(v)) + v.encode()
                     for k, v in fields.items())
    body += struct.pack("<I", len(pairs)) + pairs
    return struct.pack("<BQ", 0x0C, len(body)) + body


def test_not_an_mcap_file(tmp_path):
    path = tmp_path / "text.mcap"
    path.write_text("frames,t\n1,2\n")
    with pytest.raises(RecordingError, match=r"text\.mcap: not an MCAP recording \(no MCAP magic"):
        load(path)


def test_an_mcap_file_of_another_program(tmp_path):
    path = tmp_path / "other.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream, compression=CompressionType.NONE)
        writer.start()
        writer.add_metadata("robot", {"arm": "left"})
        writer.add_message(writer.register_channel("/joints", "json", 0), log_time=1, data=b"{}", publish_time=1)
        writer.finish()
    with pytest.raises(RecordingError, match="missing metadata 'tactile-viewer.recording'"):
        open_recording(path)  # load gives it to the ROS 2 bag reader (io/ros2_bag.py)


def test_a_huge_metadata_record_is_refused_before_reading_it(tmp_path):
    path = tmp_path / "bomb.mcap"
    path.write_bytes(MAGIC + struct.pack("<BQ", 0x0C, 2**40) + b"x" * 100)
    loaded_error = pytest.raises(RecordingError, match="no frames|missing metadata")
    with loaded_error:
        load(path)  # the record claims more than the file holds: the file ends before it


@pytest.mark.parametrize(("field", "value", "message"), [
    ("taxels", "4000000000", r"'taxels' must be in \[1, 1000000\], got 4000000000"),
    ("taxels", "six", r"'taxels' must be a whole number, got 'six'"),
    ("dtype", "int8", r"'dtype' must be one of \['float32', 'float64'\], got 'int8'"),
])
def test_declared_sizes_are_checked_before_anything_is_read(tmp_path, field, value, message):
    # a damaged or hostile header: refused before any frame is read or any array of its size made
    path = tmp_path / "declared.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start()
        fields = {"version": "1", "description": "", "taxels": "6", "dtype": "float32", "channel": "1"}
        writer.add_metadata("tactile-viewer.recording", dict(fields, **{field: value}))
        writer.add_metadata("tactile-viewer.geometry", {"nx": "3", "ny": "2", "pitch": "0.002",
                                                       "thickness": "0.0015"})
        writer.add_metadata("tactile-viewer.calibration", {"units": '"Pa"', "gain": "1", "offset": "0"})
        writer.finish()
    with pytest.raises(RecordingError, match=message):
        load(path)


# -- damage outside the chunk checksums (issue 31, item 3) -------------------------------------------

def tared_recording(path, *, frames=30, tare_at=20):
    """30 frames in chunks of 6 (t = 0, 0.1, ... s), a tare of 50 Pa taken after frame ``tare_at - 1``.

    Returns the raw values and the stresses the file must give back (the tare applied from ``tare_at``).
    """
    raw = frames_for(frames, seed=14)  # fixed seed
    recorder = Recorder(path, grid32(), dtype="float64", flush_interval=0.5)
    for k in range(frames):
        recorder.add(1000 + k, k / 10, raw[k])
        if k == tare_at - 1:
            recorder.tare(Tare(0, np.full(6, 50.0), t=k / 10, frames=10))
    recorder.close()
    expected = raw.copy()
    expected[tare_at:] -= 50.0
    return raw, expected


def flipped(path, at, bit=0x01):
    data = bytearray(path.read_bytes())
    data[at] ^= bit
    path.write_bytes(bytes(data))


def chunk_positions(path):
    index = load(path).frames._index
    return [chunk.data_offset - RECORD.size - CHUNK_HEAD.size - 8
            for chunk in index.chunks]


def test_a_chunk_whose_opcode_is_flipped_is_found_through_its_record(tmp_path):
    # before: the chunk was skipped as an unknown record, its 6 frames dropped with no word and the
    # tare after it applied 6 frames late
    path = tmp_path / "opcode.mcap"
    _raw, expected = tared_recording(path)
    flipped(path, chunk_positions(path)[1], 0x20)
    loaded = load(path)
    np.testing.assert_allclose(loaded.frames[:], expected)
    np.testing.assert_allclose(loaded.t, np.arange(30) / 10, atol=1e-6)
    assert loaded.damage == ()


def test_a_lost_chunk_is_said_with_its_frames_and_the_tare_after_it_keeps_its_frame(tmp_path):
    path = tmp_path / "lost.mcap"
    _raw, expected = tared_recording(path)
    position = chunk_positions(path)[1]
    data_offset = load(path).frames._index.chunks[1].data_offset
    flipped(path, position, 0x20)  # its header unreadable, so it is walked, and then
    flipped(path, data_offset + 100)  # a value of it fails the chunk's CRC
    loaded = load(path)
    kept = np.r_[0:6, 11:30]  # chunks of frames 0-5, 6-10, 11-15, 16-20, ...
    np.testing.assert_allclose(loaded.frames[:], expected[kept])  # the tare still from frame 20 as recorded
    np.testing.assert_allclose(loaded.t, kept / 10, atol=1e-6)
    assert loaded.damage == (f"frames 6 to 10 as recorded (5 frames, t 0.600 to 1.000 s) are lost: their "
                             f"chunk at byte {position} is damaged",)
    assert not loaded.truncated


@pytest.mark.parametrize("name", ["geometry", "calibration", "recording"])
def test_damaged_metadata_is_refused_by_its_checksum(tmp_path, name):
    # before: a pitch of 0.002 m read as 4.002 m
    path = tmp_path / "meta.mcap"
    tared_recording(path)
    data = path.read_bytes()
    # pitch 0.002 to 4.002, gain 1.0 to 5.0, "live recording" to "hive recording"
    field, after = {"geometry": (b"pitch", 9), "calibration": (b"gain", 8), "recording": (b"live recording", 0)}[name]
    start = data.index(f"tactile-viewer.{name}".encode())
    flipped(path, data.index(field, start) + after, 0x04)
    with pytest.raises(RecordingError, match=rf"metadata 'tactile-viewer.{name}' is damaged \(checksum"):
        load(path)


def test_a_damaged_tare_record_is_said_not_applied(tmp_path):
    path = tmp_path / "tare.mcap"
    raw, _expected = tared_recording(path)
    data = path.read_bytes()
    tare = data.index(b"tactile-viewer.tare") - 13
    flipped(path, data.index(b"baseline", tare) + 12, 0x02)  # a digit of the baseline
    loaded = load(path)
    np.testing.assert_allclose(loaded.frames[:], raw)
    [said] = loaded.damage
    assert said == f"the tare recorded at byte {tare} is damaged and not applied: frames from 16 on may be offset"


def index_entries(path, chunk):
    # the (time, offset) pairs of the message index after ``chunk`` and where they are in the file
    at = chunk.data_offset + chunk.length
    data = path.read_bytes()
    opcode, length = struct.unpack_from("<BQ", data, at)
    assert opcode == 0x07
    count = struct.unpack_from("<I", data, at + 11)[0] // 16
    return at + 15, np.frombuffer(data, "<u8", count=2 * count, offset=at + 15).reshape(-1, 2).copy()


@pytest.mark.parametrize("change", ["a time", "a duplicate", "two swapped", "a dropped entry"])
def test_a_message_index_is_checked_against_what_vouches_for_it(tmp_path, change):
    # before: the index, under no checksum, dropped, duplicated or moved frames and changed times
    path = tmp_path / "index.mcap"
    _raw, expected = tared_recording(path)
    chunk = load(path).frames._index.chunks[2]
    at, pairs = index_entries(path, chunk)
    if change == "a time":
        pairs[3, 0] += 2**20  # a millisecond later
    elif change == "a duplicate":
        pairs[3, 1] = pairs[2, 1]
    elif change == "two swapped":
        pairs[[2, 3], 1] = pairs[[3, 2], 1]
    else:  # the last entry's offset says the first: one frame fewer once sorted and deduplicated
        pairs[-1] = pairs[0]
    data = bytearray(path.read_bytes())
    data[at:at + pairs.nbytes] = pairs.tobytes()
    path.write_bytes(bytes(data))
    loaded = load(path)
    np.testing.assert_allclose(loaded.frames[:], expected)
    np.testing.assert_array_equal(loaded.t, load_truth_t())
    assert loaded.damage == ()


def load_truth_t():
    return (np.round(np.arange(30) / 10 * 1e9).astype(np.int64) - 0) * 1e-9


@pytest.mark.parametrize("record", ["the tare", "a message index", "a chunk"])
def test_a_flipped_length_hides_nothing_after_it(tmp_path, record):
    # before: one flipped length bit ended the file there (every later chunk hidden) or refused it
    path = tmp_path / "length.mcap"
    raw, expected = tared_recording(path)
    data = path.read_bytes()
    chunks = load(path).frames._index.chunks
    at = {"the tare": data.index(b"tactile-viewer.tare") - 13,
          "a message index": chunks[1].data_offset + chunks[1].length,
          "a chunk": chunk_positions(path)[2]}[record]
    flipped(path, at + 1 + 5, 0x10)  # a high byte of the record's length: past the end of the file
    loaded = load(path)
    assert len(loaded) == 30 and not loaded.truncated
    if record == "the tare":
        np.testing.assert_allclose(loaded.frames[:], raw)
        # the chunk of frames 16 to 20, written after the tare, is the first it may apply in
        assert loaded.damage == ("1 tare record is lost: frames from 16 on may be offset",)
    else:
        np.testing.assert_allclose(loaded.frames[:], expected)
        assert loaded.damage == ()


def version_1_file(path, raw, tare_at):
    # a recording as this viewer wrote it before checksummed metadata and chunk records: metadata
    # without checksums, a chunk of 6 frames at a time, a tare record between chunks
    with open(path, "wb") as stream:
        writer = Writer(stream, compression=CompressionType.NONE, chunk_size=2**31)
        writer.start(profile="tactile-viewer", library="tactile-viewer")
        writer.add_metadata("tactile-viewer.recording", {"version": "1", "description": "old", "taxels": "6",
                                                         "dtype": "float64", "channel": "1"})
        writer.add_metadata("tactile-viewer.geometry", {"nx": "3", "ny": "2", "pitch": "0.002",
                                                       "thickness": "0.0015"})
        writer.add_metadata("tactile-viewer.calibration", {"units": '"Pa"', "gain": "1", "offset": "0"})
        channel = writer.register_channel("/tactile/raw", "tactile-raw/float64-le", schema_id=0)
        for k, values in enumerate(raw):
            writer.add_message(channel, log_time=k * 10**8, data=values.tobytes(), publish_time=k * 10**8,
                               sequence=k)
            if k % 6 == 5:
                writer.flush()
            if k == tare_at - 1:
                writer.add_metadata("tactile-viewer.tare", {"from_frame": str(tare_at),
                                                            "baseline": "[50, 50, 50, 50, 50, 50]"})
        writer.finish()


def test_a_version_1_recording_still_opens(tmp_path):
    path = tmp_path / "old.mcap"
    raw = frames_for(30, seed=15)  # fixed seed
    version_1_file(path, raw, tare_at=20)
    loaded = load(path)
    expected = raw.copy()
    expected[20:] -= 50.0
    np.testing.assert_allclose(loaded.frames[:], expected)
    assert loaded.description == "old" and loaded.damage == () and not loaded.truncated


def test_an_unknown_version_is_refused(tmp_path):
    path = tmp_path / "future.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream, compression=CompressionType.NONE)
        writer.start()
        writer.add_metadata("tactile-viewer.recording", {"version": "9", "taxels": "6", "dtype": "float64"})
        writer.add_message(writer.register_channel("/tactile/raw", "x", 0), log_time=1, data=bytes(48),
                           publish_time=1)
        writer.finish()
    with pytest.raises(RecordingError, match=r"recording version '9' is not read by this viewer \(it reads 1, 2, 3\)"):
        load(path)



# -- recordings of version 2, before frames were ROS 2 messages (issue 32, item 1) -------------------

# Written by the Recorder of commit 70bfe6e (frames in the private encoding tactile-raw/<dtype>-le, no
# schema) and kept as they were: 30 frames of a 3x2 skin (nu 0.45, taxels 1 mm), 0.1 s apart from UNIX
# time 1.7e9, in chunks of 5 or 6, sequence 1000 on; raw values version2_expected.npz["raw"] in kPa with
# gain 2 and offset 0.25, a tare of 10 Pa from the start and one of 30 Pa from frame 20
DATA = Path(__file__).parent / "data"


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_a_version_2_recording_still_opens_with_the_same_values(dtype):
    path = DATA / f"version2_{dtype}.mcap"
    raw = np.load(DATA / "version2_expected.npz")["raw"].astype(dtype)
    loaded = load(path)
    np.testing.assert_array_equal(loaded.frames.raw(slice(None)), raw)
    expected = 2.0 * (raw.astype(float) - 0.25) * 1e3
    expected[:20] -= 10.0  # each tare's baseline replaces the one before
    expected[20:] -= 30.0
    np.testing.assert_allclose(loaded.frames[:], expected, rtol=1e-12)
    np.testing.assert_allclose(loaded.t, np.arange(30) / 10, atol=1e-6)
    np.testing.assert_array_equal(loaded.sequence(), np.arange(30) + 1000)
    assert loaded.received == pytest.approx(1.7e9) and loaded.description == f"version 2 {dtype}"
    assert loaded.grid.shape == (2, 3) and loaded.grid.poisson_ratio == 0.45 and loaded.grid.sensor_size == 1e-3
    assert [(tare.from_frame, tare.t) for tare in loaded.calibration.tares] == [(0, 0.0), (20, 1.95)]
    assert loaded.damage == () and not loaded.truncated and loaded.frames.verify() == []


def test_a_version_2_recording_cut_at_any_byte_opens_with_every_complete_chunk(tmp_path):
    data = (DATA / "version2_float32.mcap").read_bytes()
    raw = np.load(DATA / "version2_expected.npz")["raw"].astype(np.float32)
    cut_path = tmp_path / "cut.mcap"
    opened = set()
    for cut in range(len(data) - 1, 8, -11):
        cut_path.write_bytes(data[:cut])
        try:
            loaded = load(cut_path)
        except RecordingError as error:
            assert "no frames" in str(error) or "missing metadata" in str(error)
            continue
        opened.add(len(loaded))
        np.testing.assert_array_equal(loaded.frames.raw(slice(None)), raw[:len(loaded)])
        np.testing.assert_array_equal(loaded.sequence(), np.arange(len(loaded)) + 1000)
    assert len(opened) >= 6  # every chunk's end was met


def test_a_flipped_length_of_the_schema_record_loses_its_chunk_and_says_so(tmp_path):
    # the first chunk holds the schema and channel records before its frames; before the length
    # was checked, a length past the chunk's end read past the file
    path = tmp_path / "schema.mcap"
    _raw, expected = tared_recording(path)
    first, position = load(path).frames._index.chunks[0], chunk_positions(path)[0]
    assert path.read_bytes()[first.data_offset] == 0x03  # the schema record opens the first chunk's records
    flipped(path, first.data_offset + 1 + 6, 0x10)  # a high byte of its length
    loaded = load(path)
    np.testing.assert_allclose(loaded.frames[:], expected[6:])
    assert loaded.damage == ("frames 0 to 5 as recorded (6 frames, 0.600 to 0.100 s before the first frame kept) "
                             f"are lost: their chunk at byte {position} is damaged",)


def test_a_frame_id_that_no_ros_2_header_can_hold_is_refused(tmp_path):
    # version 3 frames are laid out around their header's frame_id: one that cannot be there is damage
    path = tmp_path / "frame_id.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start(profile="ros2", library="tactile-viewer")
        fields = {"recording": {"version": "3", "description": "", "taxels": "6", "dtype": "float32",
                                "channel": "1", "frame_id": "skin\u00e9"},
                  "geometry": {"nx": "3", "ny": "2", "pitch": "0.002", "thickness": "0.0015"},
                  "calibration": {"units": '"Pa"', "gain": "1", "offset": "0"}}
        for name, values in fields.items():
            writer.add_metadata(f"tactile-viewer.{name}", dict(values, crc32=metadata_checksum(values)))
        writer.finish()
    with pytest.raises(RecordingError, match=r"frame_id\.mcap: metadata 'tactile-viewer.recording': frame_id must "
                                             r"be printable ASCII of at most 255 characters, got 'skin\u00e9'"):
        load(path)
