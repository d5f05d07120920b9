"""The one load and save of every format (tactile_viewer/io/files.py): the suffix chooses the format,
only a regular file is opened, a missing or unknown file is named, a file that is no recording says what it is."""

from pathlib import Path

import numpy as np
import pytest

from tactile_viewer.io.files import load, save
from tactile_viewer.io.recording import RecordingError


@pytest.mark.parametrize("suffix", [".NPZ", ".Csv"])
def test_extension_is_case_insensitive(recording, tmp_path, suffix):
    path = save(recording, tmp_path / f"upper{suffix}")
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"upper{suffix}"]
    back = load(path)
    np.testing.assert_allclose(back.frames, recording.frames, rtol=1e-8)


# -- files of no format ------------------------------------------------------------------------------

MALFORMED = [
    # neither
    ("data.txt", lambda p: p.write_text("1 2 3"), r"unknown recording type '\.txt', expected one of \('\.mcap', '\.npz', '\.csv'\)"),
    ("noextension", lambda p: p.write_text("1 2 3"), r"unknown recording type '', expected one of \('\.mcap', '\.npz', '\.csv'\)"),
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


@pytest.mark.parametrize("name", ["missing.npz", "missing.csv"])
def test_missing_file(tmp_path, name):
    path = tmp_path / name
    with pytest.raises(RecordingError, match="No such file or directory") as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ")


@pytest.mark.parametrize("suffix", [".mcap", ".npz", ".csv"])
def test_only_a_regular_file_is_opened(tmp_path, suffix):
    import os
    import threading

    # a named pipe: open() would wait for a writer (File > Open froze the window)
    fifo = tmp_path / f"pipe{suffix}"
    os.mkfifo(fifo)
    outcome = []

    def opening():
        try:
            load(fifo)
        except RecordingError as exc:
            outcome.append(str(exc))
    thread = threading.Thread(target=opening, daemon=True)
    thread.start()
    thread.join(5)
    if thread.is_alive():  # release it, so the test fails instead of hanging
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        pytest.fail("load() blocked on a named pipe")
    assert outcome == [f"{fifo}: not a recording file: it is a named pipe (FIFO)"]
    # a device behind a link never ends; a folder is no file
    device = tmp_path / f"zeros{suffix}"
    device.symlink_to("/dev/zero")
    with pytest.raises(RecordingError, match=r"not a recording file: it is a device"):
        load(device)
    folder = tmp_path / f"folder{suffix}"
    folder.mkdir()
    with pytest.raises(RecordingError, match=r"not a recording file: it is a folder"):
        load(folder)


def test_save_rejects_an_unknown_extension(recording, tmp_path):
    with pytest.raises(RecordingError, match=r"r\.json: unknown recording type '\.json'"):
        save(recording, tmp_path / "r.json")
    assert not (tmp_path / "r.json").exists()


# -- what a file is, said plainly -------------------------------------------------------------------

def test_files_that_are_not_recordings_say_what_they_are(tmp_path):
    from tactile_viewer.io.forces import save_forces
    from tactile_viewer.io.foxglove_mcap import write_foxglove
    from tactile_viewer.model.force_tables import reconstruct_frames
    from tactile_viewer.model.viewer_model import ViewerModel

    (tmp_path / "empty.csv").write_text("")
    (tmp_path / "notes.npz").write_text("hello world\n")
    sample = load(Path(__file__).resolve().parents[3] / "sample_data" / "hertz_static.npz")
    table = reconstruct_frames(sample, ViewerModel.build(sample.grid, "point"), [0])
    for suffix in (".npz", ".csv"):
        save_forces(table, tmp_path / f"forces{suffix}")
    write_foxglove(tmp_path / "forces.mcap", table, sample.frames)
    cases = {"forces.mcap": r"an export of reconstructed forces for Foxglove .* not a recording: open it in Foxglove",
             "empty.csv": r"empty: a CSV recording has '# key=value' header lines \(nx, ny, pitch, thickness\)",
             "notes.npz": r"not an NPZ archive \(an NPZ is a zip of \.npy arrays; this file starts with b'hello",
             "forces.npz": r"a force export of this viewer \(forces per node, not the sensor stresses",
             "forces.csv": r"a force export of this viewer \(forces per node, not the sensor stresses"}
    for name, message in cases.items():
        with pytest.raises(RecordingError, match=message) as info:
            load(tmp_path / name)
        assert "allow_pickle" not in str(info.value) and name in str(info.value)
