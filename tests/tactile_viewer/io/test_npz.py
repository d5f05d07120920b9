"""NPZ recordings (tactile_viewer/io/npz.py): round trips, units, every malformed-archive path, declared
sizes and decompression bombs. What every format shares is in test_recording.py, the one load in test_files.py."""

import contextlib
import io
import struct
import tracemalloc
import zipfile

import numpy as np
import pytest

import tactile_viewer.io.npz as npz_module
from solver import SensorGrid
from tactile_viewer.io.files import load, save
from tactile_viewer.io.recording import Recording, RecordingError

# -- round trips ----------------------------------------------------------------------------------

def test_npz_round_trip(recording, tmp_path):
    path = save(recording, tmp_path / "r.npz")
    assert path == tmp_path / "r.npz" and path.is_file()
    back = load(path)
    np.testing.assert_array_equal(back.frames, recording.frames)
    np.testing.assert_array_equal(back.t, recording.t)
    np.testing.assert_array_equal(back.truth_forces, recording.truth_forces)
    np.testing.assert_array_equal(back.grid.positions, recording.grid.positions)
    assert back.grid.shape == (2, 3) and back.grid.pitch == 2e-3 and back.grid.thickness == 1.5e-3
    assert back.description == "five frames" and len(back) == 5


def test_npz_round_trip_of_an_irregular_layout(tmp_path):
    # explicit positions are kept (a (1, 3) "grid" whose middle sensor is off the line)
    positions = np.array([[0.0, 0.0], [1e-3, 0.2e-3], [2e-3, 0.0]])
    grid = SensorGrid(positions, 1e-3, 1e-3, (1, 3))
    back = load(save(Recording(grid, np.ones((2, 3)), [0.0, 1.0]), tmp_path / "irregular.npz"))
    np.testing.assert_array_equal(back.grid.positions, positions)
    assert not back.grid.is_regular and back.truth_forces is None and back.description == ""


def test_npz_without_t_counts_frames(tmp_path):
    path = tmp_path / "no_t.npz"
    np.savez(path, frames=np.ones((3, 4)), nx=2, ny=2, pitch=1e-3, thickness=1e-3)
    np.testing.assert_array_equal(load(path).t, [0.0, 1.0, 2.0])


# -- units ------------------------------------------------------------------------------------------

def test_npz_in_kilopascals(tmp_path):
    path = tmp_path / "k.npz"
    np.savez(path, frames=[[1.0, 2.5]], nx=2, ny=1, pitch=1e-3, thickness=1e-3, units="kPa")
    np.testing.assert_allclose(load(path).frames, [[1000.0, 2500.0]])


# -- malformed archives -------------------------------------------------------------------------------

def write_npz(path, **overrides):
    data = dict(frames=np.ones((2, 4)), t=[0.0, 0.1], nx=2, ny=2, pitch=1e-3, thickness=1e-3)
    data.update(overrides)
    np.savez(path, **{k: v for k, v in data.items() if v is not None})
    return path


MALFORMED = [
    # NPZ
    ("garbage.npz", lambda p: p.write_bytes(b"\x00garbage" * 10), r"not an NPZ archive \(an NPZ is a zip of \.npy arrays; this file starts with b.\\x00garbage"),
    ("empty.npz", lambda p: p.write_bytes(b""), r"not an NPZ archive \(an NPZ is a zip of \.npy arrays; this file starts with b..\)"),
    ("nokey.npz", lambda p: write_npz(p, frames=None), "missing 'frames'"),
    ("nopitch.npz", lambda p: write_npz(p, pitch=None), "missing 'pitch'"),
    ("nonx.npz", lambda p: write_npz(p, nx=None), "missing 'nx'"),
    ("count.npz", lambda p: write_npz(p, frames=np.ones((2, 5))),
     r"declares a 2x2 grid \(4 taxels\) but its frames have 5 values each"),
    ("flat.npz", lambda p: write_npz(p, frames=np.ones(4)), r"frames must be a \(T, 4\) table for a 2x2 grid, got shape \(4,\)"),
    ("noframes.npz", lambda p: write_npz(p, frames=np.ones((0, 4)), t=[]), "no frames"),
    ("nan.npz", lambda p: write_npz(p, frames=np.array([[1, 2, 3, 4], [1, np.nan, 3, 4]])),
     "frame 1 taxel 1 is not a finite number"),
    ("inf.npz", lambda p: write_npz(p, frames=np.array([[1, 2, 3, -np.inf], [1, 2, 3, 4]])),
     "frame 0 taxel 3 is not a finite number"),
    ("pitch.npz", lambda p: write_npz(p, pitch=0.0),
     "impossible geometry: pitch must be a positive finite number of metres, got 0.0"),
    ("thick.npz", lambda p: write_npz(p, thickness=-1e-3),
     "impossible geometry: thickness must be a positive finite number of metres, got -0.001"),
    ("nx0.npz", lambda p: write_npz(p, nx=0, frames=np.ones((2, 0))),
     r"impossible geometry: nx must be a positive integer .* got 0"),
    ("nanpitch.npz", lambda p: write_npz(p, pitch=np.nan), "'pitch' must be finite, got nan"),
    ("textnx.npz", lambda p: write_npz(p, nx="two"), "'nx' must be a single number"),
    ("pairnx.npz", lambda p: write_npz(p, nx=[2, 2]), "'nx' must be a single number"),
    ("positions.npz", lambda p: write_npz(p, positions=np.zeros((3, 2))),
     r"impossible geometry: shape \(2, 2\) does not hold the 3 positions given"),
    ("time.npz", lambda p: write_npz(p, t=[0.1, 0.0]), "t must be finite and non-decreasing"),
    ("tlen.npz", lambda p: write_npz(p, t=[0.0]), r"t must have shape \(2,\), got \(1,\)"),
    ("truth.npz", lambda p: write_npz(p, truth_forces=np.zeros((2, 4))),
     r"truth_forces must have shape \(2, 4, 3\), got \(2, 4\)"),
    ("units.npz", lambda p: write_npz(p, units="psi"), r"units must be one of \['MPa', 'Pa', 'kPa'\], got 'psi'"),
    ("pickle.npz", lambda p: write_npz(p, frames=np.array([1, "a", None], dtype=object)), "allow_pickle=False"),
    ("nu.npz", lambda p: write_npz(p, poisson_ratio=0.7),
     r"impossible geometry: poisson_ratio must be a finite number in \[0, 0.5\], got 0.7$"),
    ("nutext.npz", lambda p: write_npz(p, poisson_ratio="abc"), r"'poisson_ratio' must be a single number, got 'abc'$"),
    ("nunan.npz", lambda p: write_npz(p, poisson_ratio=np.nan), "'poisson_ratio' must be finite, got nan$"),
    ("nupair.npz", lambda p: write_npz(p, poisson_ratio=[0.4, 0.45]), "'poisson_ratio' must be a single number"),
    ("taxel.npz", lambda p: write_npz(p, sensor_size=2e-3),
     r"impossible geometry: sensor_size must be at most the pitch \(taxels cannot overlap\), got 0.002 m with pitch 0.001 m$"),
    ("taxelneg.npz", lambda p: write_npz(p, sensor_size=-1e-4),
     r"impossible geometry: sensor_size must be a finite number of metres >= 0 .* got -0.0001$"),
    ("taxeltext.npz", lambda p: write_npz(p, sensor_size="big"), r"'sensor_size' must be a single number, got 'big'$"),
]


@pytest.mark.parametrize("name, make, message", MALFORMED, ids=[case[0] for case in MALFORMED])
def test_malformed_files_name_the_file_and_the_problem(tmp_path, name, make, message):
    path = tmp_path / name
    make(path)
    with pytest.raises(RecordingError, match=message) as info:
        load(path)
    # the message starts with the file's path
    assert str(info.value).startswith(f"{path}: ")
    assert isinstance(info.value, ValueError)  # callers catching ValueError see it too


def test_a_bare_npy_array_named_npz(tmp_path):
    path = tmp_path / "array.npz"
    with open(path, "wb") as handle:
        np.save(handle, np.ones(4))
    with pytest.raises(RecordingError) as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ")


def test_truncated_npz(recording, tmp_path):
    path = save(recording, tmp_path / "cut.npz")
    path.write_bytes(path.read_bytes()[:300])  # a crash while writing
    with pytest.raises(RecordingError, match="not a readable NPZ archive") as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ")


def test_corrupted_npz_member(tmp_path):
    path = tmp_path / "flipped.npz"
    frames = np.arange(8.0).reshape(2, 4)
    write_npz(path, frames=frames)  # uncompressed, so the bytes of the values can be found
    raw = bytearray(path.read_bytes())
    raw[raw.index(frames.tobytes()[8:16])] ^= 1  # one bit of frames[0, 1]
    path.write_bytes(bytes(raw))
    with pytest.raises(RecordingError, match="damaged NPZ archive") as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ")


def flip_name_bit(path, name, bit):
    # one bit of a member's name in the zip's directory (its local header keeps the old name: numpy reads
    # the directory), as a damaged file may have it
    raw = bytearray(path.read_bytes())
    at = raw.index(name.encode(), raw.index(b"PK\x01\x02"))  # in the central directory
    raw[at] ^= 1 << bit
    path.write_bytes(bytes(raw))


@pytest.mark.parametrize("field, value, renamed", [
    ("t", [0.0, 0.1], "u"), ("units", "kPa", "tnits"), ("seq", [7, 8], "req"),
    ("positions", [[0, 0], [1e-3, 0], [0, 1e-3], [1e-3, 1e-3]], "qositions"),
    ("poisson_ratio", 0.45, "qoisson_ratio"), ("sensor_size", 1e-4, "rensor_size"),
])
def test_a_damaged_member_name_is_refused_not_read_as_a_missing_field(tmp_path, field, value, renamed):
    # a flipped bit in the directory's 't.npy' gave times 0, 1, 2 s; 'units' read kPa as Pa
    path = write_npz(tmp_path / "named.npz", **{field: value})
    flip_name_bit(path, f"{field}.npy", 0)
    assert f"{renamed}.npy" in zipfile.ZipFile(path).namelist()
    with pytest.raises(RecordingError, match=rf"member '{renamed}.npy' is no field of a recording and "
                                             rf"'{field}.npy' is missing: the archive's directory is damaged"):
        load(path)


def test_extra_members_beside_every_field_still_load(tmp_path):
    # a member of the user's own (notes) is no damaged name: nothing it could be is missing
    path = write_npz(tmp_path / "extra.npz", notes="run 4", u=[1.0])
    assert len(load(path)) == 2


def test_a_chunk_without_a_field_the_others_have_is_refused(tmp_path):
    path = tmp_path / "chunks.npz"
    np.savez(path, nx=2, ny=2, pitch=1e-3, thickness=1e-3, chunk000000_frames=np.ones((2, 4)),
             chunk000000_t=[0.0, 0.1], chunk000001_frames=np.ones((1, 4)), chunk000001_x=[0.2])
    with pytest.raises(RecordingError, match="chunk000001_x.npy' is no field .* 'chunk000001_t.npy' is missing"):
        load(path)
    np.savez(path, nx=2, ny=2, pitch=1e-3, thickness=1e-3, chunk000000_frames=np.ones((2, 4)),
             chunk000000_t=[0.0, 0.1], chunk000001_frames=np.ones((1, 4)), chunk000001_when=[0.2])
    with pytest.raises(RecordingError, match=r"chunk\(s\) chunk000001 have no 't' while the others have it"):
        load(path)


def test_a_bare_npy_array_named_npz_is_rejected(tmp_path):
    path = tmp_path / "array.npz"
    with open(path, "wb") as handle:
        np.save(handle, np.ones((2, 4)))
    with pytest.raises(RecordingError, match=r"array\.npz: not an NPZ archive \(a single array"):
        load(path)


def test_fractional_grid_size_in_npz(tmp_path):
    path = write_npz(tmp_path / "fraction.npz", nx=2.5)  # 2.5 x 2 "grid" with 4 values per frame
    with pytest.raises(RecordingError, match="'nx' must be a whole number, got 2.5"):
        load(path)


# -- declared sizes and decompression bombs ---------------------------------------------------------
# Files that declare more than they hold: a .npy header, a zip directory, a deflate stream or a CSV
# line. Each is refused with a RecordingError naming the field before anything of the declared size
# is made; tracemalloc sees numpy's allocations too (even untouched ones), so a load that believed
# the file would show its gigabytes here.


SKIN = dict(nx=16, ny=16, pitch=1e-3, thickness=1e-3)  # frames of 256 values, 2 KiB each
MIB = 2**20


@contextlib.contextmanager
def allocating_at_most(megabytes):
    """Fail when the block's traced allocations ever reach ``megabytes`` at once, even when the
    block failed otherwise (a load that allocated gigabytes is the news)."""
    tracemalloc.start()
    try:
        yield
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert peak < megabytes * MIB, f"peak {peak / MIB:.0f} MiB"


def npy_header(shape, descr="<f8", version=1):
    """The .npy header of an array of ``shape``, written by hand: no array of that size is made."""
    text = f"{{'descr': {descr!r}, 'fortran_order': False, 'shape': {tuple(shape)!r}, }}"
    width = 2 if version == 1 else 4  # bytes of the header's length
    text += " " * (-(8 + width + len(text) + 1) % 64) + "\n"  # numpy aligns the values to 64 bytes
    return b"\x93NUMPY" + bytes([version, 0]) + len(text).to_bytes(width, "little") + text.encode("latin1")


def npy(value):
    buffer = io.BytesIO()
    np.save(buffer, value)
    return buffer.getvalue()


def hostile_npz(path, members, compression=zipfile.ZIP_STORED):
    """An NPZ of ``members`` (name: .npy bytes) beside an honest 16x16 skin, written by zipfile alone."""
    with zipfile.ZipFile(path, "w", compression) as archive:
        for name, content in {**{key: npy(value) for key, value in SKIN.items()}, **members}.items():
            archive.writestr(f"{name}.npy", content)
    return path


def zero_frames(path, name="frames", mebibytes=256, compression=zipfile.ZIP_DEFLATED):
    """Add ``mebibytes`` of all-zero frames of the 16x16 skin, compressed a block at a time (never
    held whole): a decompression bomb, about 1028:1 deflated."""
    with zipfile.ZipFile(path, "a", compression) as archive, \
            archive.open(f"{name}.npy", "w", force_zip64=True) as member:
        member.write(npy_header((mebibytes * MIB // 2048, 256)))
        block = bytes(MIB)
        for _ in range(mebibytes):
            member.write(block)
    return path


def forge_directory(path, name, compressed, uncompressed):
    """Rewrite the sizes the zip's central directory gives member ``name`` (None: keep that one); the
    data stay as they are."""
    raw = bytearray(path.read_bytes())
    at = raw.index(b"PK\x01\x02")  # the central directory's first entry
    while raw[at + 46:at + 46 + len(name)] != name.encode():
        at = raw.index(b"PK\x01\x02", at + 4)
    kept = struct.unpack_from("<II", raw, at + 20)
    struct.pack_into("<II", raw, at + 20, kept[0] if compressed is None else compressed,
                     kept[1] if uncompressed is None else uncompressed)
    path.write_bytes(bytes(raw))
    return path


def declared(shape):  # a member of values that are not there: its header alone
    return npy_header(shape)


def chunked_zero_frames(path, chunks=5, mebibytes=15):
    """A live recording of ``chunks`` chunks of zero frames, each under the allowance alone."""
    hostile_npz(path, {})
    for index in range(chunks):
        zero_frames(path, f"chunk{index:06d}_frames", mebibytes)
    return path


HUGE = (20000, 20000)  # 3.2 GB of float64 declared by a 128-byte header
HOSTILE_NPZ = [
    ("stored", lambda p: hostile_npz(p, {"frames": declared(HUGE)}),
     r"'frames' declares 20000x20000 values \(3\.2 GB\) but the file holds 1\.\d KB: not a recording"),
    ("deflated", lambda p: hostile_npz(p, {"frames": declared(HUGE)}, zipfile.ZIP_DEFLATED),
     r"'frames' declares 20000x20000 values \(3\.2 GB\) from \d+ B compressed, \d+:1, more than the 1000:1 "
     r"any recording reaches: a decompression bomb"),
    # the directory agrees with the header, and both lie about what the file holds
    ("forged-directory", lambda p: forge_directory(hostile_npz(p, {"frames": declared(HUGE)}), "frames.npy",
                                                   3_200_000_128, 3_200_000_128),
     r"'frames' declares 20000x20000 values \(3\.2 GB\) but the file holds 1\.\d KB: not a recording"),
    ("forged-compressed-size",
     lambda p: forge_directory(hostile_npz(p, {"frames": declared(HUGE)}, zipfile.ZIP_DEFLATED), "frames.npy",
                               3_200_000_000, 3_200_000_128),
     r"damaged NPZ archive: its directory says 'frames' is 3\.2 GB compressed but the file holds \d+ B"),
    ("ceiling", lambda p: hostile_npz(p, {"frames": declared((40000, 20000))}),
     r"'frames' declares 40000x20000 values \(6\.4 GB\): the recording would take 6\.4 GB, more than the "
     r"4\.3 GB this viewer loads"),
    # an honest header and a directory that disagrees with it: damage
    ("lying-directory", lambda p: forge_directory(hostile_npz(p, {"frames": npy(np.zeros((2, 256)))}),
                                                  "frames.npy", 10000, 10000),
     r"damaged NPZ archive: its directory says 'frames' holds 10\.0 KB but its array header declares 4\.2 KB"),
    ("lying-directory-deflated",
     lambda p: forge_directory(hostile_npz(p, {"frames": npy(np.zeros((2, 256)))}, zipfile.ZIP_DEFLATED),
                               "frames.npy", None, 10000),
     r"damaged NPZ archive: its directory says 'frames' holds 10\.0 KB but its array header declares 4\.2 KB"),
    # a directory too short for the header itself: zipfile's own check of the CRC ends the read
    ("short-directory", lambda p: forge_directory(hostile_npz(p, {"frames": npy(np.zeros((2, 256)))}),
                                                  "frames.npy", 100, 100),
     r"damaged NPZ archive \(Bad CRC-32 for file 'frames\.npy'\)"),
    ("object-frames", lambda p: hostile_npz(p, {"frames": npy_header((2, 256), "|O") + b"\x80\x04junk"}),
     r"'frames' holds Python objects \(dtype object\), .*\(allow_pickle=False\)"),
    ("object-nx", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256))), "nx": npy_header((), "|O")}),
     r"'nx' holds Python objects"),
    ("structured", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256), dtype=[("v", "<f8")]))}),
     r"'frames' must hold numbers, got dtype \[\('v', '<f8'\)\]"),
    ("huge-nx", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256))), "nx": declared(HUGE)}),
     r"'nx' must be a single number, got shape \(20000, 20000\)"),
    ("huge-description", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256))),
                                                   "description": npy_header((), "<U100000000")}),
     r"'description' declares 1 value \(400\.0 MB\), more than the 1\.0 MB one field may hold"),
    ("huge-positions", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256))),
                                                 "positions": declared((20000000, 2))}),
     r"'positions' must be x, y pairs of metres \(shape \(m, 2\), m at most 1000000\), got shape \(20000000, 2\)"),
    ("t-longer-than-frames", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256))),
                                                       "t": npy(np.zeros(100000))}, zipfile.ZIP_DEFLATED),
     r"t must have shape \(2,\), got \(100000,\)"),
    ("not-npy", lambda p: hostile_npz(p, {"frames": b"PK not an array" * 100}),
     r"'frames' is not a NumPy array \(\.npy\): not a recording"),
    # a version 2.0 header may say it is 4 GiB long: np.load would read that much before refusing it
    ("header-length", lambda p: hostile_npz(p, {"frames": npy_header((2, 256), version=2)[:8]
                                                + (2**32 - 1).to_bytes(4, "little")}),
     r"'frames' declares an array header of 4294967295 bytes \(at most 10000\)"),
    ("deflate-bomb", lambda p: zero_frames(hostile_npz(p, {})),
     r"'frames' declares 131072x256 values \(268\.4 MB\) from 2\d\d\.\d KB compressed, 10\d\d:1, more than the "
     r"1000:1 any recording reaches: a decompression bomb"),
    # zipfile would inflate a bzip2 member's block whole (here 128 MiB from some 200 bytes) to read 8 bytes
    ("bzip2-bomb", lambda p: zero_frames(hostile_npz(p, {}), mebibytes=128, compression=zipfile.ZIP_BZIP2),
     r"'frames' is compressed by zip method 12, which numpy never writes \(only stored or deflated\)"),
    # five chunks, each under the allowance alone, together over it
    ("chunked-bomb", chunked_zero_frames,
     r"'chunk000004_frames' declares 7680x256 values \(15\.7 MB\) from \d+\.\d KB compressed, 10\d\d:1"),
]


@pytest.mark.parametrize("make, message", [case[1:] for case in HOSTILE_NPZ], ids=[case[0] for case in HOSTILE_NPZ])
def test_declared_sizes_are_checked_before_anything_is_allocated(tmp_path, make, message):
    path = make(tmp_path / "hostile.npz")
    with allocating_at_most(200), pytest.raises(RecordingError, match=message) as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ")


def test_the_ceiling_counts_every_member_together(tmp_path, monkeypatch):
    # gigabytes of real data are too slow for a test: the same rule under a ceiling of 14000 bytes,
    # which frames (4096 bytes) and truth_forces (12288) each fit alone
    monkeypatch.setattr(npz_module, "MAX_RECORDING_BYTES", 14000)
    path = hostile_npz(tmp_path / "both.npz", {"frames": npy(np.zeros((2, 256))),
                                               "truth_forces": npy(np.zeros((2, 256, 3)))})
    with pytest.raises(RecordingError, match=r"'truth_forces' declares 2x256x3 values \(12\.3 KB\): the "
                                             r"recording would take 16\.4 KB, more than the 14\.0 KB"):
        load(path)


def test_a_field_that_does_not_fit_the_frames_is_refused_before_it_is_read(tmp_path):
    # 60 MiB of times for 2 frames: within every ceiling (zeros inflate past 1000:1, but within the
    # allowance), refused by its shape alone
    path = hostile_npz(tmp_path / "times.npz", {"frames": npy(np.zeros((2, 256)))})
    with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED) as archive, archive.open("t.npy", "w") as member:
        member.write(npy_header((60 * MIB // 8,)))
        for _ in range(60):
            member.write(bytes(MIB))
    with allocating_at_most(20), pytest.raises(RecordingError, match=r"t must have shape \(2,\), got \(7864320,\)"):
        load(path)


def test_the_tiny_file_of_the_report_is_tiny(tmp_path):
    # the fault report's case: some 1.6 KB declaring a 20000x20000 grid (3.2 GB)
    path = hostile_npz(tmp_path / "tiny.npz", {"frames": declared(HUGE)})
    assert path.stat().st_size < 2000


@pytest.mark.parametrize("count", [1000, 16384])
def test_an_honest_all_zero_recording_still_loads(tmp_path, count):
    # a skin that never felt anything is the legitimate worst case of compression: 16384 frames of
    # 16x16 (32 MiB) inflate past 1000:1 and load through the allowance
    grid = SensorGrid.regular(16, 16, 1e-3, 1e-3)
    path = save(Recording(grid, np.zeros((count, 256)), np.arange(count) / 1000), tmp_path / "idle.npz")
    with zipfile.ZipFile(path) as archive:
        member = archive.getinfo("frames.npy")
    assert (member.file_size > 1000 * member.compress_size) == (count == 16384)
    back = load(path)
    assert back.frames.shape == (count, 256) and not back.frames.any()


def test_an_honest_chunked_recording_still_joins(tmp_path):
    path = tmp_path / "chunks.npz"
    np.savez(path, **SKIN, chunk000000_frames=np.ones((2, 256)), chunk000000_t=[0.0, 0.1],
             chunk000001_frames=np.ones((1, 256)), chunk000001_t=[0.2])
    back = load(path)
    assert back.frames.shape == (3, 256) and back.t.tolist() == [0.0, 0.1, 0.2]
    np.savez(path, **SKIN, chunk000000_frames=np.ones((2, 256)), chunk000001_frames=np.ones((1, 255)))
    with pytest.raises(RecordingError, match=r"'chunk000001_frames' has shape \(1, 255\) but "
                                             r"'chunk000000_frames' has \(2, 256\): the chunks do not join"):
        load(path)
