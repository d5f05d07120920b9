"""The time plots: a dock of pyqtgraph plots of the whole recording, with a cursor at the frame drawn.

Stacked plots with one time axis: total normal force, size and direction of
the total tangential force, their ratio, and the contact centroid's x and y;
when the recording carries its true forces, the truth beside the estimate
and two rows of errors. A vertical cursor on every plot stands at the frame
drawn and follows playback; a click on a plot (or dragging the cursor) shows
the nearest frame. CSV (:meth:`tactile_viewer.model.series.Series.to_csv`) and PNG
exports.

Contacts followed over time: when the series holds more than one contact
identity (:attr:`tactile_viewer.model.series.Series.contacts`), every row also has a
thin curve per contact, named ``#1``, ``#2`` ... in the Fz legend as in the
contacts table, broken where the contact is absent (the
:data:`~tactile_viewer.model.time_plot_rows.MAX_CONTACT_CURVES` contacts
present on the most frames; a single contact's curves would repeat the
totals, so none are drawn for it).

The series is solved in the background (:func:`tactile_viewer.model.series_solving.compute_series`
in a task of the window's :class:`~tactile_viewer.qt.tasks.TaskRunner`, without
its modal dialog: the window stays free) and drawn as it fills in; a new
source, kernel, quality or parameters cancel it and start again (parameter
changes after a short pause, so a slider drag starts one series, not fifty).
A live source has no whole recording: the dock draws the frames solved so far,
the last ``live_span`` seconds of them. During playback only the cursor moves:
the curves are drawn when the series changes, never per frame.

The dock holds the bar, its Qt timers and the exports; what is solved when,
and what is cached, is :class:`~tactile_viewer.model.series_schedule.SeriesSchedule`
(no Qt); the plots are a :class:`~tactile_viewer.qt.time_plot_stack.TimePlotStack`.
"""

from __future__ import annotations

import math
from pathlib import Path

from PyQt6 import QtCore, QtGui, QtWidgets

from solver.arguments import MAX_STRESS
from solver.checks import real_number

from ..io.recording import written_whole
from ..io.sidecar import derived_name
from ..model.series import Series
from ..model.series_schedule import SeriesSchedule
from ..model.series_solving import MAX_FRAMES, SeriesBuilder, nearest_frame
from ..model.time_plot_rows import ERROR_ROWS, FIRST_ROWS, ROWS, TIPS
from ..model.viewer_model import ViewerModel
from .preferences import save_rows, saved_rows
from .tasks import TaskRunner
from .time_plot_stack import TimePlotStack

__all__ = ["TimePlotsDock"]

REFRESH_MS = 300  # partial series and live frames reach the curves this often
CURSOR_WAIT_MS = 100  # the cursor's lines wait this long for the frame's result before moving alone
SETTLE_MS = 250  # parameters must stay this long before their series is solved (a slider drag)
LIVE_SPAN_S = 60.0  # a live source's plots hold this much of its history


class TimePlotsDock(QtWidgets.QDockWidget):
    """Plots of the whole recording over time, a cursor at the frame shown; click to seek.

    Parameters
    ----------
    model : ViewerModel
        The window's model: its source, solver and parameters are plotted,
        its frame is the cursor, and clicks set its frame.
    tasks : TaskRunner
        The window's runner: the series is solved in one of its background
        tasks (cancelled with the others when the window closes).
    parent : QWidget, optional
    error : callable, optional
        ``error(title, text)`` shows a failure to the user (an export that
        could not be written, a series that could not be solved); default a
        message box.
    notify : callable, optional
        ``notify(text)`` for passing news ("saved ..."); default none.
    live_span : float, optional
        Seconds of a live source's history drawn. Default 60.
    max_frames : int, optional
        Frames a series solves at most, evenly over the recording. Default
        :data:`tactile_viewer.model.series_solving.MAX_FRAMES`.

    Signals
    -------
    drawn()
        The curves were redrawn (a partial series, a complete one, live frames).
    computed()
        A complete series of the recording is drawn.

    Attributes
    ----------
    series : Series or None
        What the curves show.
    graphics : TimePlotStack
        The plots: by row, their curves (estimate, truth, errors, each contact's),
        cursors and lost-frame shading.
    schedule : SeriesSchedule
        What is solved in the background, when, and what is kept.
    """

    drawn = QtCore.pyqtSignal()
    computed = QtCore.pyqtSignal()

    def __init__(self, model: ViewerModel, tasks: TaskRunner, parent=None, *, error=None, notify=None,
                 live_span: float = LIVE_SPAN_S, max_frames: int = MAX_FRAMES):
        live_span = real_number("live_span", live_span, rule="finite seconds > 0",
                                valid=lambda v: math.isfinite(v) and v > 0)
        schedule = SeriesSchedule(model, tasks.background, finished=lambda series: self._finish(series),
                                  failed=lambda exc: self._failed(exc), max_frames=max_frames,
                                  every=REFRESH_MS / 1e3)  # checks max_frames and names it
        super().__init__("Time plots", parent)
        self.setObjectName("time_plots")  # saveState/restoreState find the dock by it
        self.model = model
        self.tasks = tasks
        self._error = error if error is not None else self._message_box
        self._notify = notify if notify is not None else (lambda text: None)
        self.live_span = live_span
        self.schedule = schedule  # what is solved in the background, when, and what is kept
        self.series: Series | None = None
        self._cursor_x = math.nan  # the time of the frame the model shows
        self._lines_x = math.nan  # where the cursor lines stand: the frame drawn
        # as the user left them last run, else the first three
        rows_shown = saved_rows({key for key, *_ in (*ROWS, *ERROR_ROWS)}) or set(FIRST_ROWS)

        body = QtWidgets.QWidget()
        column = QtWidgets.QVBoxLayout(body)
        column.setContentsMargins(2, 2, 2, 2)
        bar = QtWidgets.QHBoxLayout()
        self.status = QtWidgets.QLabel("no recording")
        self.csv_button = QtWidgets.QPushButton("CSV...")
        self.csv_button.setToolTip("Save the series as CSV: one row per frame, units in the header")
        self.csv_button.clicked.connect(
            lambda: self._save_dialog("Save the time series", "series.csv", "CSV (*.csv)", self.export_csv))
        self.png_button = QtWidgets.QPushButton("PNG...")
        self.png_button.setToolTip("Save the plots as a PNG image")
        self.png_button.clicked.connect(
            lambda: self._save_dialog("Save the time plots", "time_plots.png", "PNG image (*.png)",
                                      self.export_png))
        self.rows_button = QtWidgets.QToolButton()
        self.rows_button.setText("Rows")
        self.rows_button.setToolTip("Choose the plots shown (the CSV holds every series)")
        self.rows_button.setPopupMode(QtWidgets.QToolButton.ToolButtonPopupMode.InstantPopup)
        rows_menu = QtWidgets.QMenu(self.rows_button)
        self.row_actions: dict[str, QtGui.QAction] = {}
        for key, label, _unit, _ in (*ROWS, *ERROR_ROWS):
            action = rows_menu.addAction(f"{label}: {TIPS[key].split(',')[0].split(':')[0]}")
            action.setCheckable(True)
            action.setChecked(key in rows_shown)
            action.toggled.connect(lambda on, key=key: self.show_rows(**{key: on}))
            self.row_actions[key] = action
        self.rows_button.setMenu(rows_menu)
        bar.addWidget(self.status, 1)
        bar.addWidget(self.rows_button)
        bar.addWidget(self.csv_button)
        bar.addWidget(self.png_button)
        column.addLayout(bar)

        self.graphics = TimePlotStack(rows_shown)
        self.graphics.seek_requested.connect(self.seek_time)
        scroll = QtWidgets.QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setFrameShape(QtWidgets.QFrame.Shape.NoFrame)
        scroll.setWidget(self.graphics)
        column.addWidget(scroll, 1)
        # before anything is open: a sentence, not empty axes from 0 to 1 and a legend of nothing
        self.placeholder = QtWidgets.QLabel("The forces over time show here once a recording is open "
                                            "(File > Open) or a board connected (Live > Connect)")
        self.placeholder.setAlignment(QtCore.Qt.AlignmentFlag.AlignCenter)
        self.placeholder.setWordWrap(True)
        column.addWidget(self.placeholder, 1)
        self._plots_area = scroll
        scroll.hide()
        self.setWidget(body)
        self._set_exports()

        self._refresh_timer = QtCore.QTimer(self, interval=REFRESH_MS)
        self._refresh_timer.timeout.connect(self._refresh)
        self._settle_timer = QtCore.QTimer(self, interval=SETTLE_MS, singleShot=True)
        self._settle_timer.timeout.connect(self._start)
        self._cursor_timer = QtCore.QTimer(self, interval=CURSOR_WAIT_MS, singleShot=True)
        self._cursor_timer.timeout.connect(lambda: self._move_lines(self._cursor_x))
        self.visibilityChanged.connect(self._visibility)
        self._connections = ((model.recording_changed, self._on_source),
                             (model.parameters_changed, self._on_parameters),
                             (model.frame_changed, self._on_frame),
                             (model.solved, self._on_solved))
        for signal, slot in self._connections:
            signal.connect(slot)
        if model.is_open:
            self._on_source()

    # -- building ---------------------------------------------------------------------------

    def show_rows(self, **shown: bool):
        """Show (True) or hide (False) rows by key (``ROWS``, ``ERROR_ROWS``); one stays."""
        unknown = set(shown) - set(self.graphics.plots)
        if unknown:
            raise ValueError(f"rows must be among {sorted(self.graphics.plots)}, got {sorted(unknown)}")
        rows = {key for key in self.rows_shown if shown.get(key, True)} | {k for k, on in shown.items() if on}
        if not rows & {key for key, *_ in ROWS}:
            rows.add("fz")  # a plot with no row has no time axis to stand on
        save_rows(rows)
        for key, action in self.row_actions.items():
            action.blockSignals(True)
            action.setChecked(key in rows)
            action.blockSignals(False)
        self.graphics.show_rows(rows)

    @property
    def rows_shown(self) -> set:
        """The row keys shown (:data:`~tactile_viewer.model.time_plot_rows.ROWS`, ``ERROR_ROWS``)."""
        return self.graphics.rows_shown

    # -- following the model -----------------------------------------------------------------

    def detach(self):
        """Stop following the model and cancel the series being solved (the dock is being removed)."""
        for signal, slot in self._connections:
            try:
                signal.disconnect(slot)
            except ValueError:
                pass  # detached before
        self.schedule.cancel()
        self._settle_timer.stop()
        self._refresh_timer.stop()
        self._cursor_timer.stop()

    def _on_source(self):
        # a new source, or the same one with another solver (kernel, quality): all of it again
        self.schedule.new_source()
        self._set_exports()
        model = self.model
        self.placeholder.hide()
        self._plots_area.show()
        self.graphics.mark_lost(() if model.live or model.recording is None else model.recording.lost_spans)
        if model.live:
            self._draw(self.schedule.follow_live(model.grid, kernel=model.kernel, source=model.source.label,
                                                 span=self.live_span))
            self.status.setText(f"live: the last {self.live_span:g} s of frames solved")
            self._refresh_timer.start()
            return
        if model.recording is not None:
            self._cursor_x = float(model.recording.t[model.frame])
            self._cursor_timer.start()
        if self.series is not None and not self.schedule.asked_for(model.recording):
            # another recording: its curves replace these as they are solved, none of these stay meanwhile
            self._draw(SeriesBuilder(model.grid).series())
        self._start()

    def _on_parameters(self):
        # stop solving the old parameters at once (the window's own solves need the processor during a
        # drag); solve the new ones when they have settled
        if not self.schedule.parameters_changed():
            return
        self._set_exports()
        self.status.setText("parameters changed: the series follows when they settle...")
        self._settle_timer.start()

    def _on_frame(self, index: int):
        # The cursor is at this frame now; its lines move when the frame's result is drawn (solved), in
        # the window's repaint of that frame. Moved here, they cost the window a repaint of its own on
        # every frame (measured under Xvfb: the frame slider's latency 100 ms instead of 63). A result
        # that does not come (a failed or very slow solve): they move after CURSOR_WAIT_MS anyway.
        recording = self.model.recording
        if recording is not None:
            self._cursor_x = float(recording.t[index])
            self._cursor_timer.start()

    def _on_solved(self, solved):
        again = self.schedule.solved(solved)
        if self.schedule.live is not None:
            self._cursor_x = solved.time
            self._move_lines(solved.time)
            return
        if solved.frame == self.model.frame:
            self._cursor_timer.stop()  # the frame shown is drawn: the lines come with it
        self._move_lines(solved.time)
        if again:  # the recording was re-tared: same file, other stresses
            self._start()

    def _visibility(self, visible: bool):
        if visible:
            self._move_lines(self._lines_x)
            if self.schedule.stale:
                self._start()

    # -- the series --------------------------------------------------------------------------------

    def _start(self):
        # the series the model wants now, solved in the background (or from the cache, or when shown)
        self._settle_timer.stop()
        frames = self.schedule.start(visible=self.isVisible())
        if frames is not None:
            self.status.setText(f"solving {frames} frames...")
            task = self.schedule.task
            if task.isRunning():
                # a background job: where the platform lets threads have priorities, the window's come first
                task.setPriority(QtCore.QThread.Priority.LowPriority)
            self._refresh_timer.start()
        self._set_exports()

    def _finish(self, series: Series):
        self._draw(series)
        mode = "Auto" if series.mode == "auto" else (
            f"shear ratio {series.shear_ratio:.2f}, direction {math.degrees(series.shear_direction):.0f} deg")
        sampled = "" if len(series) == len(self.model.recording) else f" (of {len(self.model.recording)})"
        refused = (f"; {len(series.refused)} refused by the solver (values beyond {MAX_STRESS:g} Pa), "
                   f"first frame {series.refused[0]}" if series.refused else "")
        self.status.setText(f"{len(series)} frames{sampled}, {series.kernel} kernel, {mode}{refused}")
        self._set_exports()
        self.computed.emit()

    def _failed(self, exc: BaseException):
        self._set_exports()
        self.status.setText("the series could not be solved")
        self._error("Time plots", f"solving the series failed: {exc}")

    def _refresh(self):
        # the timer: a partial series, or the live frames that came since the last look
        if self.schedule.live is not None:
            live = self.schedule.new_live_series()
            if live is not None:
                self._draw(live)
            return
        if not self.schedule.solving:
            self._refresh_timer.stop()
            return
        partial = self.schedule.new_partial()
        if partial is not None:
            self._draw(partial)
            self.status.setText(f"solving: {len(partial)} of {partial.total} frames...")

    # -- drawing ---------------------------------------------------------------------------------

    def _draw(self, series: Series):
        self.series = series
        self.graphics.draw(series)
        self._move_lines(self._lines_x)
        self._set_exports()
        self.drawn.emit()

    def _move_lines(self, x: float):
        # the one thing that moves during playback: a few line items, never the curves
        self._lines_x = x
        if self.isVisible():
            self.graphics.move_cursors(x)

    @property
    def cursor_time(self) -> float:
        """Seconds of the frame the model shows: where the cursor goes (nan: no frame yet).

        Its lines get there with the frame's result (:attr:`lines_time`).
        """
        return self._cursor_x

    @property
    def lines_time(self) -> float:
        """Seconds at which the cursor's lines stand: the frame drawn (nan: none yet)."""
        return self._lines_x

    # -- seeking ------------------------------------------------------------------------------

    def seek_time(self, x: float) -> bool:
        """Show the recording's frame nearest to ``x`` seconds; False for a live source or nothing."""
        recording = self.model.recording
        if recording is None or self.model.live or not math.isfinite(x):
            return False
        self.model.set_frame(nearest_frame(recording.t, x))
        return True

    # -- exports -------------------------------------------------------------------------------

    def _set_exports(self):
        # a complete series only: a partial one is not what the plots will show
        series = self.series
        ready = not self.schedule.solving and series is not None and len(series) > 0 and series.complete
        self.csv_button.setEnabled(ready)
        self.png_button.setEnabled(ready)

    def export_csv(self, path) -> Path | None:
        """Write the series drawn as CSV (:meth:`Series.to_csv`); None (the error shown) when it cannot."""
        series = self.series
        if series is None or not len(series):
            self._error("Nothing to export", "no series has been solved yet")
            return None
        if self.schedule.solving or not series.complete:
            self._error("Series not complete", f"the series is still being solved ({len(series)} of "
                        f"{series.total} frames): export it when it is complete")
            return None
        try:
            written = series.to_csv(path)
        except OSError as exc:
            self._error("Cannot save the series", f"{path}: {exc.strerror or exc}")
            return None
        self._notify(f"saved {written}")
        return written

    def export_png(self, path) -> Path | None:
        """Write the plots as a PNG image; None (and the error shown) when it cannot."""
        path = Path(path)
        image = self.graphics.grab()
        try:
            with written_whole(path) as temporary:
                if image.isNull() or not image.save(str(temporary), "PNG"):
                    raise OSError("the image could not be written")
        except OSError:
            self._error("Cannot save the plots", f"{path}: the image could not be written (check the folder "
                        "exists and may be written to)")
            return None
        self._notify(f"saved {path}")
        return path

    def _save_dialog(self, title: str, default: str, file_filter: str, export):
        # the name picked, given the default's ending (a name so made must be free), to ``export``
        path, _ = QtWidgets.QFileDialog.getSaveFileName(self, title, default, file_filter)
        if path:
            try:
                export(derived_name(path, Path(default).suffix, what=Path(default).stem.replace("_", " ")))
            except FileExistsError as exc:
                self._error(f"Cannot {title[0].lower()}{title[1:]}", str(exc.strerror))

    def _message_box(self, title, text):
        QtWidgets.QMessageBox.critical(self, title, text)
