"""Building the solver for the source shown (no Qt): kernel, quality preset, and whether it still applies."""

import numpy as np
import pytest

from solver import SensorGrid
from tactile_viewer.io.recording import Recording
from tactile_viewer.model.solver_build import SolverBuild
from tactile_viewer.model.viewer_model import ViewerModel
from tactile_viewer.sources.source import RecordingSource

PRESET = object()  # a quality preset (a solver.quality.Configuration): only compared here


def source(nx=6):
    grid = SensorGrid.regular(nx, 5, 2e-3, 2e-3)
    return RecordingSource(Recording(grid, np.zeros((2, grid.size)), [0.0, 0.05]))


@pytest.fixture
def model():
    model = ViewerModel()
    shown = source()
    SolverBuild.for_source(model, shown).install(model, ViewerModel.build(shown.grid, "layer"))
    return model


def test_a_new_source_keeps_the_kernel_and_the_preset_of_its_geometry(model):
    model.configuration = PRESET
    same = SolverBuild.for_source(model, source())
    assert (same.kernel, same.configuration, same.rebuild) == (model.kernel, PRESET, False)
    other = SolverBuild.for_source(model, source(nx=7))  # a preset is measured on its own geometry
    assert other.configuration is None and other.kernel == model.kernel


def test_a_choice_already_in_use_builds_nothing_and_with_nothing_open_waits(model):
    assert SolverBuild.for_choice(model, model.kernel, model.configuration) is None
    empty = ViewerModel()
    assert SolverBuild.for_choice(empty, "cell", PRESET) is None
    assert empty.configuration is PRESET  # kept for the next source


def test_another_kernel_rebuilds_the_source_shown_and_keeps_its_frame(model):
    shown = model.source
    model.set_frame(1)
    build = SolverBuild.for_choice(model, "cell", None)
    assert (build.source, build.kernel, build.rebuild) == (shown, "cell", True)
    assert build.install(model, build.build())
    assert model.kernel == "cell" and model.source is shown and model.frame == 1


def test_a_rebuild_for_a_source_replaced_meanwhile_is_dropped(model):
    build = SolverBuild.for_choice(model, "cell", None)
    solver = build.build()
    newer = source()
    SolverBuild.for_source(model, newer).install(model, ViewerModel.build(newer.grid, "layer"))
    assert not build.install(model, solver)
    assert model.source is newer and model.kernel == "layer"
