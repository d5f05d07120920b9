"""Work off the GUI thread, for the Qt layer: one-off tasks and results handed back to the GUI thread."""

from __future__ import annotations

from PyQt6 import QtCore

__all__ = ["Task", "Dispatcher"]


class Task(QtCore.QThread):
    """Runs ``fn(progress)`` in a worker thread; ``progress(done, total)`` returns False to cancel."""

    progressed = QtCore.pyqtSignal(int, int)
    succeeded = QtCore.pyqtSignal(object)
    failed = QtCore.pyqtSignal(object)

    def __init__(self, fn, parent=None):
        super().__init__(parent)
        self._fn = fn
        self._cancelled = False

    def cancel(self):
        self._cancelled = True

    def _progress(self, done, total):
        self.progressed.emit(int(done), int(total))
        return not self._cancelled

    def run(self):
        try:
            result = self._fn(self._progress)
        except Exception as exc:  # handed to the GUI thread, which shows it
            self.failed.emit(exc)
        else:
            self.succeeded.emit(result)


class Dispatcher(QtCore.QObject):
    """Runs callables on the thread that owns it (the GUI thread), posted from any thread.

    The model's ``dispatch``: its worker thread hands results back through it.
    """

    _posted = QtCore.pyqtSignal(object)

    def __init__(self, parent=None):
        super().__init__(parent)
        self._posted.connect(self._call, QtCore.Qt.ConnectionType.QueuedConnection)

    def post(self, fn):
        self._posted.emit(fn)

    @staticmethod
    def _call(fn):
        fn()
