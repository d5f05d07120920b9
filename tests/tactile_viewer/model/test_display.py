"""The display settings (no Qt): their checks and the scales a new source opens with."""

import math
from dataclasses import FrozenInstanceError, replace

import pytest

from tactile_viewer.model.display import Display, display_scales
from tactile_viewer.model.solved import Solved
from tactile_viewer.model.viewer_model import ViewerModel
from tactile_viewer.sources.source import RecordingSource


@pytest.mark.parametrize("name", ["arrow_scale", "resultant_scale", "threshold", "range_max"])
@pytest.mark.parametrize("value", [-1e-6, math.nan, math.inf, -math.inf])
def test_display_rejects_negative_and_non_finite_scales(name, value):
    with pytest.raises(ValueError, match=rf"{name} must be finite and >= 0, got {value!r}"):
        Display(**{name: value})
    with pytest.raises(ValueError, match=rf"{name} must be finite and >= 0"):
        replace(Display(), **{name: value})  # replace() runs the same checks


@pytest.mark.parametrize("kind", ["Pressure", "", "heat", None])
def test_display_rejects_unknown_maps(kind):
    with pytest.raises(ValueError, match=r"map must be one of \('pressure', 'stress', 'none'\)"):
        Display(map=kind)


def test_display_accepts_zero_and_every_map():
    for kind in ("pressure", "stress", "none"):
        assert Display(map=kind).map == kind
    zero = Display(arrow_scale=0.0, resultant_scale=0.0, threshold=0.0, range_max=0.0)
    assert zero.threshold == 0.0
    with pytest.raises(FrozenInstanceError):
        zero.threshold = 1.0


# -- solving -------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["hertz_static.npz", "two_contacts.npz", "three_contacts.npz"])
def test_the_fixed_map_range_holds_the_pressure_the_map_shows(name):
    # it came from the normal-only solve: the core of every contact saturated on most frames
    from pathlib import Path

    from tactile_viewer.io.files import load

    recording = load(Path(__file__).resolve().parents[3] / "sample_data" / name)
    solver = ViewerModel.build(recording.grid, "layer")
    scales = display_scales(RecordingSource(recording), solver)
    every = recording.frames[:: max(1, len(recording) // 15)]
    peaks = [Solved.of(recording.grid, b, solver.solve(b)).pressure.max() for b in every]
    assert max(peaks) <= scales["range_max"] <= 2 * max(peaks)  # held, and not washed out
