"""Fixtures: a real MainWindow under Xvfb (pytest-xvfb) that leaks no plotter; a simulated board."""

import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

os.environ.setdefault("QT_API", "pyqt6")

SAMPLES = Path(__file__).resolve().parents[2] / "sample_data"


class ErrorsShown(list):
    """The error dialogs a window showed, as (title, text), and the errors it logged.

    A test that provokes an error takes it (:meth:`take`, :meth:`take_logged`);
    whatever is left when the test ends fails it: an error on screen is never a pass.
    """

    def __init__(self, caplog):
        super().__init__()
        self._caplog = caplog

    def take(self):
        """The dialogs shown so far, forgotten: the test expected them."""
        shown = list(self)
        self.clear()
        return shown

    def logged(self):
        """Errors (level ERROR and above) the app logged and no test took."""
        return [r for when in ("setup", "call") for r in self._caplog.get_records(when)
                if r.levelno >= logging.ERROR and r.name.startswith("tactile_viewer")]

    def take_logged(self):
        """The errors logged so far in the test, forgotten: the test expected them."""
        records = self.logged()
        self._caplog.clear()  # the test's own records (those of the window's set-up stay)
        return records


@pytest.fixture
def window(qtbot, no_plotter_leak, monkeypatch, caplog, request):
    """A real MainWindow, shown; fails the test on an error it did not take (:class:`ErrorsShown`).

    Two kinds of background work are off unless the test is marked for them: the quality
    presets' measurement once a geometry has settled (``@pytest.mark.presets``: a process of
    seconds of CPU) and the time plots' series of a recording (``@pytest.mark.series``).
    """
    from PyQt6 import QtWidgets

    from tactile_viewer.qt.main_window import MainWindow
    from tactile_viewer.qt.presets import PresetMeasurer
    from tactile_viewer.qt.time_plots import TimePlotsDock

    if request.node.get_closest_marker("presets") is None:
        monkeypatch.setattr(PresetMeasurer, "_measure_if_shown", lambda self: None)
    if request.node.get_closest_marker("series") is None:
        monkeypatch.setattr(TimePlotsDock, "_start", lambda self: None)
    errors = ErrorsShown(caplog)
    # dialogs would block a test: record them instead (and fail the test unless it takes them)
    monkeypatch.setattr(QtWidgets.QMessageBox, "critical",
                        staticmethod(lambda parent, title, text, *a, **k: errors.append((title, text))))
    win = MainWindow()
    win.errors = errors
    qtbot.addWidget(win)
    win.show()
    qtbot.waitExposed(win)
    yield win
    win.close()
    left, logged = list(errors), [f"{r.name}: {r.getMessage()}" for r in errors.logged()]
    assert not left and not logged, f"unexpected errors: dialogs {left}, logged {logged}"


@pytest.fixture
def opened(window, qtbot):
    """The window showing the turning-shear sample."""
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(SAMPLES / "hertz_shear_turning.npz")
    return window


class Board:
    """A tactile-sim subprocess behind a stable symlink, restartable at the same path."""

    def __init__(self, folder):
        self.link = folder / "board"
        self.layout = folder / "layout.json"
        self.process = None

    def start(self, *options, wait=True):
        """Start the board; with ``wait``, return once it streams (nothing else may be reading it)."""
        self.process = subprocess.Popen(
            [sys.executable, "-m", "tactile_viewer.cli.tactile_sim", "--link", str(self.link), "--layout",
             str(self.layout), *options], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.process.stdout.readline()  # the device path: the link and layout exist from here on
        if wait:
            self.wait_streaming()
        return self

    def wait_streaming(self, timeout=60.0):
        """Return once frames flow: the board computes its contact after it prints its path."""
        import time

        import serial

        deadline = time.monotonic() + timeout
        with serial.Serial(str(self.link), timeout=0.1) as port:
            while not port.read(64):
                assert time.monotonic() < deadline, "the simulated board sent nothing"
                assert self.process.poll() is None, "the simulated board exited"

    def stop(self):
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            self.process.communicate(timeout=10)


@pytest.fixture
def board(tmp_path):
    made = Board(tmp_path)
    yield made
    made.stop()


@pytest.fixture
def kill_log():
    """A function leaving a force log as a stream killed with it open leaves it; it returns the spool.

    Frames queued are written first; then the log's descriptors are closed and its writer
    stopped without :meth:`~tactile_viewer.model.force_log.ForceLog.close`, so the spool stays.
    """

    def kill(log):
        log.flush()
        for descriptor in log._files.values():
            os.close(descriptor)
        log._files = {}
        log._queue.put(None)
        log._writer.join()
        return log.spool

    return kill
