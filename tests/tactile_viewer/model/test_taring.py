"""Changing a tare (no Qt): the one model method every caller uses, for recordings and live boards."""

import numpy as np
import pytest

from solver import SensorGrid
from tactile_viewer.io.layout import SensorLayout
from tactile_viewer.io.recording import Recording
from tactile_viewer.model.taring import keeps_raw_values, retare_source
from tactile_viewer.model.viewer_model import ViewerModel
from tactile_viewer.sources.live import LiveSource
from tactile_viewer.sources.source import RecordingSource


class Board(LiveSource):
    """A live board that is never started: its calibration is all a tare needs."""

    def _open(self):
        raise OSError("not connected")

    def _read(self, connection):
        return b""

    def _close(self, connection):
        pass


def test_only_recordings_with_raw_values_keep_a_tare_to_change():
    grid = SensorGrid.regular(4, 4, 2e-3, 2e-3)
    assert not keeps_raw_values(None)
    assert not keeps_raw_values(RecordingSource(Recording(grid, np.zeros((1, grid.size)), [0.0])))
    with pytest.raises(ValueError, match="only a recording that keeps raw values"):
        retare_source(None, "clear")


def test_a_live_board_is_tared_from_its_next_frames_through_the_model():
    grid = SensorGrid.regular(4, 4, 2e-3, 2e-3)
    board = Board("test://board", SensorLayout(grid, "kPa"))
    model = ViewerModel()
    model.set_source(board, ViewerModel.build(grid, "layer"))
    assert not model.retarable  # the Recording menu's tares are a recording's
    assert model.retare("here", frames=3) == "taring: averaging the next 3 frames"
    assert board.calibration.taring
    with pytest.raises(ValueError, match="a live board's tare is taken 'here'"):
        model.retare("clear")
