"""Fixtures for window tests: a real MainWindow under Xvfb (pytest-xvfb), no leaked plotters."""

import os
from pathlib import Path

import pytest

os.environ.setdefault("QT_API", "pyqt6")

SAMPLES = Path(__file__).resolve().parents[2] / "sample_data"


@pytest.fixture
def no_plotter_leak():
    from pyvista.plotting import plotter as pv_plotter

    before = set(pv_plotter._ALL_PLOTTERS)
    yield
    leaked = set(pv_plotter._ALL_PLOTTERS) - before
    assert not leaked, f"plotters left open: {leaked}"


@pytest.fixture
def window(qtbot, no_plotter_leak, monkeypatch):
    from PyQt6 import QtWidgets

    from tactile_viewer.main_window import MainWindow

    errors = []
    # dialogs would block a test: record them instead
    monkeypatch.setattr(QtWidgets.QMessageBox, "critical",
                        staticmethod(lambda parent, title, text, *a, **k: errors.append((title, text))))
    win = MainWindow()
    win.errors = errors
    qtbot.addWidget(win)
    win.show()
    qtbot.waitExposed(win)
    yield win
    win.close()


@pytest.fixture
def opened(window, qtbot):
    """The window showing the turning-shear sample."""
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(SAMPLES / "hertz_shear_turning.npz")
    return window
