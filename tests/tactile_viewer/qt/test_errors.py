"""Unexpected errors are logged and shown, never fatal (tactile_viewer/qt/errors.py)."""

import logging
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pytest

from tactile_viewer.qt import errors

ROOT = Path(__file__).resolve().parents[3]

# The real app (tactile_viewer.cli.tactile_viewer.run_window) in a fresh process: pytest-qt installs its own
# hook in this one, which would hide the PyQt6 default that aborts the process.
SCRIPT = textwrap.dedent("""
    import sys, threading
    from PyQt6 import QtCore, QtWidgets
    from tactile_viewer.cli import tactile_viewer as entry
    from tactile_viewer.qt.main_window import MainWindow

    def broken(self, *args):
        raise RuntimeError("injected fault in a slot")
    MainWindow.open_dialog = broken  # File > Open recording...

    app = QtWidgets.QApplication(sys.argv[:1])
    warming = []  # the solver's code loaded ahead, on a thread of its own
    entry.warm_in_background = lambda log, start=entry.warm_in_background: warming.append(start(log))

    def window():
        return next(w for w in app.topLevelWidgets() if isinstance(w, MainWindow))

    def poke():
        action = next(a for a in window().menuBar().actions()[0].menu().actions() if "Open" in a.text())
        action.trigger()
        # and an error on another thread (a reader, a worker)
        def fail():
            raise OSError("injected fault in a thread")
        threading.Thread(target=fail, name="reader").start()
        QtCore.QTimer.singleShot(500, check)

    def check():
        print("alive", window().isVisible(), app.reporter.count, flush=True)
        print("warming", [thread.name for thread in warming], flush=True)
        app.quit()

    QtCore.QTimer.singleShot(300, poke)
    sys.exit(entry.run_window())
""")


def test_an_error_in_a_slot_does_not_end_the_app(tmp_path):
    env = {**__import__("os").environ, "TACTILE_VIEWER_DATA": str(tmp_path)}
    run = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert "alive True 2" in run.stdout, run.stdout + run.stderr
    assert "warming ['solver warm-up']" in run.stdout  # started by the app itself
    logged = (tmp_path / errors.LOG_NAME).read_text()
    assert "RuntimeError: injected fault in a slot" in logged  # with its traceback
    assert "Traceback" in logged and "OSError: injected fault in a thread" in logged
    assert "unexpected error in reader" in logged


def test_the_reporter_counts_a_burst_in_one_dialog(qtbot, tmp_path):
    path = errors.setup_logging(tmp_path)
    reporter = errors.Reporter(path)
    for k in range(3):
        with qtbot.waitSignal(reporter.reported, timeout=2000):
            try:
                raise ValueError(f"bad frame {k}")
            except ValueError as exc:
                reporter.report(type(exc), exc, exc.__traceback__)
    dialog = reporter.dialog
    qtbot.addWidget(dialog)
    assert dialog.isVisible() and not dialog.isModal()
    assert "bad frame 2" in dialog.text() and "3 unexpected errors so far" in dialog.text()
    assert str(path) in dialog.text()
    assert path.read_text().count("ValueError: bad frame") == 3


def test_errors_from_threads_reach_the_gui_thread(qtbot, tmp_path, monkeypatch):
    reporter = errors.Reporter(errors.setup_logging(tmp_path))
    monkeypatch.setattr(sys, "excepthook", sys.excepthook)  # restored after the test
    monkeypatch.setattr(threading, "excepthook", threading.excepthook)
    errors.install(reporter)
    shown = []
    reporter.reported.connect(lambda title, message: shown.append((threading.current_thread(), title)))

    def fail():
        raise OSError("port vanished")
    with qtbot.waitSignal(reporter.reported, timeout=2000):
        worker = threading.Thread(target=fail, name="serial-reader")
        worker.start()
        worker.join()
    qtbot.addWidget(reporter.dialog)
    assert shown == [(threading.main_thread(), "OSError in serial-reader")]


def test_an_unwritable_data_folder_falls_back_to_the_terminal(tmp_path, caplog):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with caplog.at_level(logging.WARNING, logger="tactile_viewer"):
        assert errors.setup_logging(blocker / "logs") is None
    assert "cannot write the log" in caplog.text


def test_the_data_folder_can_be_chosen(monkeypatch, tmp_path):
    monkeypatch.setenv("TACTILE_VIEWER_DATA", str(tmp_path))
    assert errors.data_folder() == tmp_path
    monkeypatch.delenv("TACTILE_VIEWER_DATA")
    assert errors.data_folder().name == "tactile-viewer"


@pytest.fixture(autouse=True)
def _quiet_log():
    yield
    for handler in list(errors.log.handlers):  # do not leave file handlers behind
        errors.log.removeHandler(handler)
        handler.close()


def test_a_deleted_dialog_does_not_turn_the_reporter_into_a_loop(qtbot, tmp_path):
    # the dialog used to be parented to the active window, which can be a short-lived progress
    # dialog: once it was deleted, every report raised inside the reporter again, without end
    from PyQt6 import sip

    reporter = errors.Reporter(errors.setup_logging(tmp_path))
    for k in range(2):
        with qtbot.waitSignal(reporter.reported, timeout=2000):
            reporter.report(ValueError, ValueError(f"frame {k}"), None)
        sip.delete(reporter.dialog)  # gone under the reporter's feet
    assert reporter.count == 2
    assert "the error dialog itself failed" not in (tmp_path / errors.LOG_NAME).read_text()
