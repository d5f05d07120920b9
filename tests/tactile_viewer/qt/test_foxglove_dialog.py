"""File > Export for Foxglove in a real window (tactile_viewer/qt/foxglove_dialog.py), read back with the mcap
reader and its protobuf decoder."""

import numpy as np
from PyQt6 import QtWidgets

from tactile_viewer.io.files import load, save
from tactile_viewer.io.foxglove_mcap import METADATA_NAME, TOPICS
from tactile_viewer.io.recording import Recording
from tactile_viewer.model.force_tables import reconstruct_frames
from tests.tactile_viewer.conftest import SAMPLES
from tests.tactile_viewer.io.test_foxglove_mcap import arrow_vectors, read_back


def menu_action(window):
    actions = window.menuBar().actions()[0].menu().actions()
    return next(a for a in actions if "Foxglove" in a.text().replace("&", ""))


def open_short(window, qtbot, tmp_path, *, bad_frame=None):
    """Open the first 6 frames of the two-contact sample (one made unsolvable when ``bad_frame`` is given)."""
    sample = load(SAMPLES / "two_contacts.npz")
    frames = np.array(sample.frames[:6])
    if bad_frame is not None:
        frames[bad_frame, 10] = 1e200  # no solve takes it
    path = save(Recording(sample.grid, frames, sample.t[:6], description="six frames"), tmp_path / "six.npz")
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(path)
    return window.model.recording


def test_the_menu_writes_every_frame_as_the_window_solves_it(window, qtbot, tmp_path, monkeypatch):
    # before a recording (as for a live board) there is no whole recording to export
    assert not menu_action(window).isEnabled()
    assert not window.exports.foxglove.export(tmp_path / "none.mcap")
    assert window.errors.take() == [("Nothing to export", "a live source has no whole recording: record it first")]
    recording, model = open_short(window, qtbot, tmp_path), window.model
    model.set_parameters(shear_ratio=0.3, shear_direction=0.5)  # the sliders' parameters are the file's
    picked = tmp_path / "turning"  # no ending: .mcap is added
    monkeypatch.setattr(QtWidgets.QFileDialog, "getSaveFileName",
                        staticmethod(lambda *a, **k: (str(picked), "MCAP for Foxglove (*.mcap)")))
    action = menu_action(window)
    assert action.isEnabled()
    with qtbot.waitSignal(window.tasks.finished, timeout=60000):
        action.trigger()
    back = read_back(tmp_path / "turning.mcap")
    assert {t: len(m) for t, m in back["messages"].items()} == dict.fromkeys(TOPICS.values(), len(recording))
    expected = reconstruct_frames(recording, model.reconstructor, shear_ratio=0.3, shear_direction=0.5)
    for row, proto in enumerate(back["decoded"][TOPICS["forces"]]):
        nodes = next(e for e in proto.entities if e.id == "nodes")
        vectors = arrow_vectors(nodes.arrows)[1]
        # the window's own arrow scale (metres per newton), so the file reads as the scene does
        peak = np.abs(expected.forces[row]).max()
        np.testing.assert_allclose(vectors / model.display.arrow_scale, expected.forces[row] * [1, 1, -1],
                                   rtol=1e-6, atol=1e-6 * peak)
    meta = back["metadata"][METADATA_NAME]
    assert float(meta["resultant_scale_m_per_N"]) == model.display.resultant_scale
    assert meta["source"] == model.source.label and meta["mode"] == "manual"
    assert window.statusBar().currentMessage().startswith(f"saved {tmp_path / 'turning.mcap'}: "
                                                          f"{len(recording)} frames")
    # a folder gone: said, and nothing starts
    assert not window.exports.foxglove.export(tmp_path / "gone" / "x.mcap")
    assert window.errors.take() == [("Cannot export for Foxglove", f"{tmp_path / 'gone' / 'x.mcap'}: the "
                                     "folder does not exist")]
    assert not window.tasks.tasks


def test_frames_the_solver_refuses_are_named_and_the_rest_written(window, qtbot, tmp_path):
    open_short(window, qtbot, tmp_path, bad_frame=4)  # the window opens on frame 0
    with qtbot.waitSignal(window.tasks.finished, timeout=60000):
        assert window.exports.foxglove.export(tmp_path / "bad.mcap")
    (title, text), = window.errors.take()
    assert title == "Frames left out of the Foxglove export"
    assert text.startswith(f"{tmp_path / 'bad.mcap'} was saved with 5 frames; 1 could not be solved and are "
                           "not in it:\nframe 4: stress must be at most")
    back = read_back(tmp_path / "bad.mcap")
    assert [m["frame"] for m in back["decoded"][TOPICS["contacts"]]] == [0, 1, 2, 3, 5]
