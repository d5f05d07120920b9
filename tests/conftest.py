"""Settings for every test: hypothesis draws the same examples on every run (derandomized), so CI
sees what a developer saw and a failure reproduces as it is; the compiled contact fit is ready
before the first test; the viewer's settings files (what the window remembers) go to a folder of
each test's own, never the user's, in this process and the commands it starts; a test that
leaves a pyvista plotter open fails (no_plotter_leak)."""

import pytest
from hypothesis import settings

from solver.warmup import warm_up

settings.register_profile("repeatable", derandomize=True)
settings.load_profile("repeatable")


@pytest.fixture(scope="session", autouse=True)
def compiled_contact_fit():
    # numba compiles solver.search on its first call: seconds, once per checkout (then cached).
    # Done here, every path of the search, so that no test's timeout includes it.
    warm_up()


@pytest.fixture(autouse=True)
def own_settings_folder(monkeypatch, tmp_path_factory):
    monkeypatch.setenv("TACTILE_VIEWER_CONFIG", str(tmp_path_factory.mktemp("settings")))


@pytest.fixture
def no_plotter_leak():
    from pyvista.plotting import plotter as pv_plotter

    before = set(pv_plotter._ALL_PLOTTERS)
    yield
    leaked = set(pv_plotter._ALL_PLOTTERS) - before
    assert not leaked, f"plotters left open: {leaked}"
