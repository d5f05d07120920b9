"""Work off the GUI thread, for the Qt layer: one-off tasks, their runner, results back to the GUI thread."""

from __future__ import annotations

from PyQt6 import QtCore, QtWidgets

from ..model.worker import Cancelled

__all__ = ["Task", "Dispatcher", "TaskRunner"]


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


class TaskRunner(QtCore.QObject):
    """The window's one-off work: each task in its own thread, with or without a progress dialog.

    Results come back on the GUI thread; a task that fails shows its error
    through ``error(title, text)`` unless it was cancelled. After :meth:`close`
    (the window is going) results are dropped.

    Signals
    -------
    finished(object)
        A task with a progress dialog ended: its result or its exception.
    """

    finished = QtCore.pyqtSignal(object)

    def __init__(self, parent: QtWidgets.QWidget, error):
        super().__init__(parent)
        self._parent = parent
        self._error = error
        self.tasks: list[Task] = []
        self.closed = False

    def run(self, work, done, label: str, *, determinate: bool) -> Task:
        """``work(progress)`` behind a window-modal progress dialog (shown after 0.4 s); ``done(result)``."""
        task = Task(work, self)
        dialog = QtWidgets.QProgressDialog(label, "Cancel", 0, 0 if not determinate else 100, self._parent)
        dialog.setWindowModality(QtCore.Qt.WindowModality.WindowModal)
        dialog.setMinimumDuration(400)
        dialog.setAutoClose(False)
        dialog.setAutoReset(False)
        dialog.canceled.connect(task.cancel)
        if determinate:
            task.progressed.connect(lambda d, t: (dialog.setMaximum(t), dialog.setValue(d)))

        def finish(outcome, ok):
            dialog.close()
            dialog.deleteLater()
            if self.closed:
                return  # the window closed while it ran: nothing left to show it in
            if ok:
                done(outcome)
            elif not isinstance(outcome, Cancelled):
                self._error("Failed", f"{label.rstrip('.')}: {outcome}")
            self.finished.emit(outcome)

        return self._start(task, lambda result: finish(result, True), lambda exc: finish(exc, False))

    def background(self, work, done, failed) -> Task:
        """``work(progress)`` with no dialog; ``done(result)`` or ``failed(exception)`` on the GUI thread."""
        task = Task(work, self)
        return self._start(task, lambda result: None if self.closed else done(result),
                           lambda exc: None if self.closed else failed(exc))

    def _start(self, task: Task, succeeded, failed) -> Task:
        task.succeeded.connect(succeeded)
        task.failed.connect(failed)
        task.finished.connect(lambda: self.tasks.remove(task) if task in self.tasks else None)
        task.finished.connect(task.deleteLater)
        self.tasks.append(task)
        task.start()
        return task

    def close(self):
        """Cancel every task and wait for it; later results are dropped."""
        self.closed = True
        for task in list(self.tasks):
            task.cancel()
            task.wait()
