"""The scene's fixtures: the frames drawn (a regular and an irregular layout) and an off-screen plotter
with a scene on it."""

import pytest
import pyvista as pv

from tactile_viewer.render.scene import Scene
from tests.tactile_viewer.render.hertz_frames import LAYOUTS, WINDOW, reconstruct, regular_grid


@pytest.fixture(scope="module", params=sorted(LAYOUTS))
def frame(request):
    """(grid, stress, reconstruction) for a regular and an irregular layout."""
    grid = LAYOUTS[request.param]()
    stress, result = reconstruct(grid)
    return grid, stress, result


@pytest.fixture(scope="module")
def regular_frame():
    grid = regular_grid()
    stress, result = reconstruct(grid)
    return grid, stress, result


@pytest.fixture
def plotter(no_plotter_leak):
    plotter = pv.Plotter(off_screen=True, window_size=list(WINDOW))
    yield plotter
    plotter.close()


@pytest.fixture
def scene(plotter):
    return Scene(plotter)
