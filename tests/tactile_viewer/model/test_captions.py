"""The texts the viewer shows about its solver (no Qt)."""

import numpy as np

from solver import SensorGrid
from tactile_viewer.model.captions import geometry_text

PITCH, THICKNESS = 2e-3, 2e-3


def test_geometry_text_names_nu_and_the_taxel():
    assert geometry_text(SensorGrid.regular(6, 5, PITCH, THICKNESS)) == (
        "6x5 taxels, pitch 2 mm, thickness 2 mm, nu 0.5, point sensors")
    irregular = SensorGrid(np.zeros((3, 2)) + [[0, 0], [1e-3, 0], [0, 1e-3]], THICKNESS, PITCH, (3,),
                           poisson_ratio=0.45, sensor_size=1.5e-3)
    assert geometry_text(irregular) == "3 taxels, pitch 2 mm, thickness 2 mm, nu 0.45, taxel 1.5 mm"


def test_the_window_title_says_what_is_shown_and_its_state():
    from dataclasses import replace

    from tactile_viewer.io.recording import Recording
    from tactile_viewer.model.captions import recording_warnings, window_title
    from tactile_viewer.sources.source import RecordingSource

    grid = SensorGrid.regular(4, 4, PITCH, THICKNESS)
    recording = Recording(grid, np.zeros((2, grid.size)), [0.0, 0.05])
    shown = RecordingSource(recording, "takes/press.npz")
    assert window_title(None, None) == "tactile-viewer"
    assert window_title(shown, recording) == "tactile-viewer - press.npz"
    assert recording_warnings(shown, recording) == []
    damaged = replace(recording, truncated=True, damage=("chunk 2 damaged",))
    assert window_title(shown, damaged) == "tactile-viewer - press.npz (damaged)"
    (cut, _), (hurt, text) = recording_warnings(shown, damaged)
    assert (cut, hurt, text) == ("Recording cut short:", "Recording damaged:", "press.npz: chunk 2 damaged")
