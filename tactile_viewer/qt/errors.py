"""Errors the app did not expect: logged to a file, shown to the user, never fatal.

PyQt6 aborts the process when an exception leaves a slot and ``sys.excepthook``
is Python's default. :func:`install` replaces the hook (and the one for
threads): the error is logged with its traceback to ``tactile-viewer.log`` in
the user's data folder, a non-modal dialog names it, and the event loop goes
on with the window's state and data intact. Errors raised on other threads
(readers, workers) reach the dialog through a queued signal, because widgets
may only be touched on the GUI thread.
"""

from __future__ import annotations

import logging
import logging.handlers
import os
import sys
import threading
import traceback
from pathlib import Path

from PyQt6 import QtCore, QtWidgets, sip

__all__ = ["data_folder", "setup_logging", "install", "Reporter"]

log = logging.getLogger("tactile_viewer")

LOG_NAME = "tactile-viewer.log"


def data_folder() -> Path:
    """The user's data folder for the app (Qt's per-platform choice).

    ``TACTILE_VIEWER_DATA`` overrides it (tests, shared lab machines).
    """
    override = os.environ.get("TACTILE_VIEWER_DATA")
    if override:
        return Path(override)
    location = QtCore.QStandardPaths.writableLocation(
        QtCore.QStandardPaths.StandardLocation.GenericDataLocation)
    return Path(location or Path.home() / ".local" / "share") / "tactile-viewer"


def setup_logging(folder: Path | None = None, *, level=logging.INFO) -> Path | None:
    """Log the app to ``folder/tactile-viewer.log`` (rotated at 1 MB, 3 kept) and warnings to stderr.

    Returns the log file's path, or None when the folder cannot be written
    (the app then logs to stderr only, and says so there).
    """
    folder = data_folder() if folder is None else Path(folder)
    log.setLevel(level)
    for handler in list(log.handlers):  # a second window or test: one set of handlers
        log.removeHandler(handler)
        handler.close()
    console = logging.StreamHandler()
    console.setLevel(logging.WARNING)
    console.setFormatter(logging.Formatter("tactile-viewer: %(levelname)s: %(message)s"))
    log.addHandler(console)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / LOG_NAME
        handler = logging.handlers.RotatingFileHandler(path, maxBytes=1_000_000, backupCount=3,
                                                       encoding="utf-8")
    except OSError as exc:
        log.warning("cannot write the log in %s (%s); logging to the terminal only", folder, exc)
        return None
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(threadName)s %(name)s: %(message)s"))
    log.addHandler(handler)
    return path


class Reporter(QtCore.QObject):
    """Shows unexpected errors in a dialog on the GUI thread; repeated ones are counted, not stacked.

    Signals
    -------
    reported(str, str)
        Title and message of each error (emitted on the GUI thread).
    """

    reported = QtCore.pyqtSignal(str, str)
    _queued = QtCore.pyqtSignal(str, str)

    def __init__(self, log_path: Path | None, parent=None):
        super().__init__(parent)
        self.log_path = log_path
        self.count = 0
        self.dialog: QtWidgets.QMessageBox | None = None
        self._queued.connect(self._show, QtCore.Qt.ConnectionType.QueuedConnection)

    def report(self, exc_type, exc, tb, *, where: str = "") -> None:
        """Log one exception and queue its dialog (any thread)."""
        self.count += 1
        log.error("unexpected error%s", f" in {where}" if where else "", exc_info=(exc_type, exc, tb))
        title = f"{exc_type.__name__}" + (f" in {where}" if where else "")
        self._queued.emit(title, str(exc) or exc_type.__name__)

    def _show(self, title: str, message: str):
        # Never raise from here: an error in the reporter would come back to the reporter.
        try:
            text = f"{message}\n\nThe viewer goes on; what it showed and recorded is kept."
            if self.log_path is not None:
                text += f"\nDetails are in {self.log_path}."
            if self.dialog is not None and not sip.isdeleted(self.dialog) and self.dialog.isVisible():
                # a burst of errors (one per frame, say) updates one dialog instead of burying the window
                self.dialog.setText(f"{text}\n\n{self.count} unexpected errors so far.")
            else:
                # no parent: a short-lived parent (a progress dialog) would delete it under us
                self.dialog = QtWidgets.QMessageBox(QtWidgets.QMessageBox.Icon.Critical, "Unexpected error",
                                                    text, QtWidgets.QMessageBox.StandardButton.Ok)
                self.dialog.setInformativeText(title)
                self.dialog.setModal(False)
                self.dialog.show()
            self.reported.emit(title, message)
        except Exception:
            log.exception("the error dialog itself failed")


def install(reporter: Reporter) -> None:
    """Route uncaught exceptions of the GUI thread and of every other thread to ``reporter``."""

    def hook(exc_type, exc, tb):
        if issubclass(exc_type, KeyboardInterrupt):
            sys.__excepthook__(exc_type, exc, tb)
            return
        try:
            reporter.report(exc_type, exc, tb)
        except Exception:  # the hook itself must never raise: print both and go on
            traceback.print_exception(exc_type, exc, tb)
            traceback.print_exc()

    def thread_hook(args):
        if args.exc_type is SystemExit:
            return
        name = args.thread.name if args.thread is not None else "a thread"
        try:
            reporter.report(args.exc_type, args.exc_value, args.exc_traceback, where=name)
        except Exception:
            traceback.print_exception(args.exc_type, args.exc_value, args.exc_traceback)

    sys.excepthook = hook
    threading.excepthook = thread_hook
